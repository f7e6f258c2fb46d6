"""Rytter's four levels in words — detected? where? how much? how long? — written from health.json itself.

:func:`levels` reads the document :mod:`.assess` builds (docs/health.md: its last visit, trends, forecast and the
``location`` and ``followed`` sections), so the sentences say what the file holds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from reporting.uncertainty_text import format_percent_change
from studies.health.cause import effect_of
from studies.health.forecast import Forecast
from studies.health.locate import SECTIONS, location_sentence
from studies.health.trend import Trend

#: what an added effect is, in words (the Where? level)
EFFECT_WORDS = {"dielectric_leakage": "their dielectric leaks (dielectric_leakage: a conductance G_leak in parallel "
                                      "with each patch couple)"}
#: where a health parameter lives on the laminate (the lumped model's own map; docs/model.md)
LOCATION = {
    "k3": "a bending stiffness (fitted as k3, the tip section's, which stands for any section here)",
    "alpha_h": "the MFC patches' hysteresis (Bouc-Wen linearity factor α_h)",
    "beta_h": "the MFC patches' hysteresis (Bouc-Wen shape factor β_h)",
}
#: a section stiffness named by shm diagnose and followed (§3 of docs/health.md)
SECTION_WORDS = {"k1": "the bending stiffness of section 1 (root)", "k2": "the bending stiffness of section 2",
                 "k3": "the bending stiffness of section 3 (tip)"}


@dataclass(frozen=True, slots=True)
class FourLevels:
    """Rytter's four levels in words (:func:`levels`): detected? where? how much? how long?"""
    detected: str
    where: str
    how_much: str
    how_long: str

    def to_json(self) -> dict[str, str]:  # health.json's levels (docs/health.md)
        return {"detected": self.detected, "where": self.where, "how_much": self.how_much, "how_long": self.how_long}


# The four levels are written from health.json itself (``doc``, and its ``location`` and ``followed`` sections,
# ``loc`` and ``fol`` below: the JSON document at the edge, docs/health.md), so the words say what the file holds.
def levels(doc: dict[str, Any], trends: dict[str, Trend], fc: Forecast) -> FourLevels:
    last = doc["visits"][-1]
    bv = last["board_verdict"]
    board = f"; the board's monitor said {bv} at this visit" if bv else ""
    detected, where = _detected_where(doc, trends, board)
    parts = [_estimate_words(e, trends, last["operating_hours"]) for e in last["estimates"]]
    how_much = f"at {last['operating_hours']:g} h: " + "; ".join(parts)
    fol = doc.get("followed") or {}
    loc = doc.get("location") or {}
    if fol.get("switched"):
        how_much = (f"at {last['operating_hours']:g} h: " + _followed_how_much(doc, trends)
                    + f" (the default set's estimates moved too — {'; '.join(parts)} — with "
                    f"{last['held_rms_sigma']:.2f} σ held-out residual left: not the cause)")
        if any(trends[n].significant for n in fol["free"] if n in trends):
            detected = (f"yes — {', '.join(fol['free'])} changed since entry into service (significant trend; "
                        f"shm diagnose named {', '.join(fol['named'])} at {fol['diagnosed_visit_hours']:g} h)"
                        + board)
        where = _cause_place(fol) + ("; " + location_sentence(loc) + _section_agreement(fol, loc)
                                     if loc.get("run") and loc.get("distinguishable") is not None else "")
    if loc.get("run") and loc.get("distinguishable") is not None:
        how_much += _stiffness_loss_words(loc)
    return FourLevels(detected, where, how_much, _how_long(doc, fc))


def _detected_where(doc: dict[str, Any], trends: dict[str, Trend], board: str) -> tuple[str, str]:
    """Levels 1 and 2 from the last visit's estimates and the trends (``board``: the monitor's words, or "")."""
    changed = [e for e in doc["visits"][-1]["estimates"] if e["verdict"] == "changed"]
    sig = [n for n, t in trends.items() if t.significant]
    if not (changed or sig):
        return ("no — every health parameter is within 3 standard errors (or 2 %) of nominal, no trend" + board,
                "nothing to place")
    names = sorted({e["name"] for e in changed} | set(sig))
    detected = (f"yes — {', '.join(names)} changed since entry into service"
                + (f" (significant trend: {', '.join(sig)})" if sig else "") + board)
    loc = doc.get("location") or {}
    where = "; ".join(f"{n}: {LOCATION.get(n, n)}" for n in names if not (loc.get("run") and n in SECTIONS))
    if loc.get("run"):
        where = (where + "; " if where else "") + location_sentence(loc)
    elif any(n in SECTIONS for n in names):
        where += (" (from which model parameter moved: the section stiffnesses were not compared; "
                  "--locate always does)")
    return detected, where


def _estimate_words(e: dict[str, Any], trends: dict[str, Trend], hours: float) -> str:
    """One estimate's change since nominal, with its trend's rate at ``hours`` (h) when the trend is significant."""
    t = trends.get(e["name"])
    rse = e["stderr"] / abs(e["nominal"]) if e["stderr"] is not None else None
    rate = ""
    if t is not None and t.significant:
        acc = {"exponential": ", accelerating", "power": _power_word(t),
               "change_point": f", after a sudden change at about {t.best.tau or 0:g} h"}.get(t.best.name, "")
        rate = f", {100 * t.rate_per_100h(hours):+.2f} % per 100 h ({t.best.name}{acc})"
    bound = " — at its fit bound: a limit, not an estimate" if e.get("at_bound") else ""
    return f"{e['name']} {format_percent_change(e['relative'], rse)}{bound}{rate}"


def _stiffness_loss_words(loc: dict[str, Any]) -> str:
    """How much stiffness the located section lost (or each possible section, when they cannot be told apart)."""
    alts = sorted((c for c in loc["candidates"] if c.get("section") in (loc.get("possible_sections") or [])
                   and "relative" in c), key=lambda c: c["held_rss_sigma2"])
    words = ("; the stiffness loss itself: " + (" or ".join(
        f"{c['name']} {100 * c['relative']:+.1f} % if in section {c['section']}" for c in alts))
        if len(alts) > 1 or loc.get("section") is None else "")
    if loc.get("section") is not None and len(alts) <= 1:
        words += (f"; the stiffness loss itself: {loc['parameter']} {100 * loc['relative']:+.1f} % "
                  f"(section {loc['section']})")
    return words


def _how_long(doc: dict[str, Any], fc: Forecast) -> str:
    """Level 4: the board's own FAULT if it said so, else the forecast trip time, or a lower bound without trend."""
    last = doc["visits"][-1]
    f = doc["forecast"]
    if (board_said := _board_said_fault(doc)) is not None:
        return board_said
    if fc.already_faulty:
        return ("now: the estimated parameters are already beyond the monitor's trip limit (the built-in test "
                "flags this laminate)")
    if fc.significant and fc.trip_operating_hours is not None:
        # forecast_trip sets the remaining life and P(FAULT at the next visit) together with the trip time
        assert fc.rul_hours is not None and fc.p_fault_next_visit is not None
        lo, hi = f["trip_interval_90"]
        hi_s = f"{hi:.0f}" if hi is not None else "beyond the horizon"
        vis = f.get("trip_visits_90") or [None, None]
        in_visits = ""
        if vis[0] is not None and "visits_used" in doc:
            last_no = last["visit"] or doc["visits_used"]
            a = vis[0] - last_no
            b = (vis[1] - last_no) if vis[1] is not None else None
            in_visits = f", i.e. in {a} to {b if b is not None else '?'} visits (visit {vis[0]}–{vis[1]})"
        return (f"the built-in test will flag this laminate at about {fc.trip_operating_hours:.0f} h "
                f"(90 %: {lo:.0f}–{hi_s} h){in_visits}; remaining useful life {fc.rul_hours:.0f} h from the "
                f"last visit; P(FAULT at the next visit, {fc.next_visit_hours:g} h) = "
                f"{100 * fc.p_fault_next_visit:.0f} %")
    if fc.significant:
        return (f"a trend, but no FAULT of the monitor expected before {fc.horizon_hours:.0f} h (the forecast "
                "horizon)")
    lb = fc.lower_bound_hours
    assert lb is not None  # forecast_trip sets it whenever no trend is significant
    return (f"no significant trend: no date. No FAULT of the monitor expected before {lb:.0f} h "
            f"(lower bound: remaining life ≥ {lb - fc.last_hours:.0f} h)")


def _board_said_fault(doc: dict[str, Any]) -> str | None:
    """How long? when the board's own built-in test already said FAULT at a visit used: that is the answer, whatever
    the trend (issue 33); marks the forecast ``already_faulty`` with the hours."""
    said = next((v for v in doc["visits"] if v.get("board_verdict") == "FAULT"), None)
    if said is None:
        return None
    last = doc["visits"][-1]
    doc["forecast"]["already_faulty"] = True
    doc["forecast"]["board_said_fault_hours"] = said["operating_hours"]
    return (f"already faulty: the board's own built-in test said FAULT at visit {said['visit']} "
            f"({said['operating_hours']:g} h)"
            + ("" if said is last else f", before the last visit used ({last['operating_hours']:g} h)"))


def _power_word(t: Trend) -> str:
    if t.best.name != "power":
        return ""
    m = float(t.best.theta[2])
    return f", accelerating (exponent {m:.2f})" if m > 1.05 else (f", decelerating (exponent {m:.2f})" if m < 0.95
                                                                  else "")


def unit_of(name: str) -> str:
    """The SI unit of a followed parameter: an added effect's own (plant.effect), "1" for a relative one."""
    eff = effect_of(name)
    if eff is None:
        return "1"
    from plant.effect import resolve_effect

    return next((p.unit for p in resolve_effect(eff).parameters if p.name == name), "1")


def _cause_place(fol: dict[str, Any]) -> str:
    """Where the followed cause lives, in words."""
    parts = [f"the patches: {EFFECT_WORDS.get(e, e)}" for e in fol.get("effects") or []]
    parts += [f"{n}: {SECTION_WORDS.get(n) if fol.get('switched') and n in SECTION_WORDS else LOCATION.get(n, n)}"
              for n in fol["free"] if effect_of(n) is None]
    return "; ".join(parts)


def _followed_how_much(doc: dict[str, Any], trends: dict[str, Trend]) -> str:
    """The followed parameters at the last visit, their rate and, for an effect, the monitor's trip limit."""
    last = doc["visits"][-1]
    fol = doc["followed"]
    out = []
    for n in fol["free"]:
        est = next((x for x in last.get("followed_estimates") or [] if x["name"] == n), None)
        t = trends.get(n)
        if est is None or t is None:
            continue
        rate = (f", {t.rate_per_100h(last['operating_hours']) / 100.0:+.3g} {unit_of(n)} per h ({t.best.name})"
                if t.significant else ", no significant trend")
        if effect_of(n) is not None:
            se = f" ± {est['stderr']:.2g}" if est["stderr"] is not None else ""
            lim = (fol.get("effect_trip_limits") or {}).get(n)
            lim_s = f"; the monitor trips at {n} ≈ {lim:.3g} {unit_of(n)}" if lim and math.isfinite(lim) else ""
            out.append(f"{n} {est['value']:.3g}{se} {unit_of(n)}{rate}{lim_s}")
        else:
            out.append(f"{n} {format_percent_change(est['value'] / est['nominal'] - 1.0, None)}{rate}")
    return "; ".join(out)


def _section_agreement(fol: dict[str, Any], loc: dict[str, Any]) -> str:
    """Whether the followed section stiffness is among the sections the localisation leaves possible."""
    followed = [SECTIONS[n] for n in fol["free"] if n in SECTIONS]
    possible = loc.get("possible_sections") or ([loc["section"]] if loc.get("section") else [])
    if not followed or not possible:
        return ""
    if all(sec in possible for sec in followed):
        return f" — the trended section ({', '.join(str(x) for x in followed)}) is among them: they agree"
    return (f" — but the trended section ({', '.join(str(x) for x in followed)}) is not among them: the "
            "localisation and shm diagnose disagree; read both")
