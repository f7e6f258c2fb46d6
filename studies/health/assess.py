"""The whole assessment behind ``shm health``: visits → estimates → trends → forecast → the four levels.

Returns one JSON-ready document (see docs/health.md for every key) plus the objects the report plots.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from board_config.errors import InputError
from reporting.uncertainty_text import format_percent_change
from studies.health.cause import effect_of
from studies.health.estimate import DEFAULT_FREE, Visit, VisitEstimates, VisitParameter, estimate_visits
from studies.health.evaluate import (
    ALPHA,
    LAMBDAS,
    MIN_VISITS,
    SweepPrediction,
    evaluate_sweep,
    sweep_predictions,
)
from studies.health.follow import Followed, effect_limits, find_and_follow, series, trends_upto
from studies.health.forecast import Forecast, forecast_trip, visit_of
from studies.health.locate import (
    SECTIONS,
    LocationRun,
    diagnose_first_name,
    locate_stiffness,
    location_sentence,
)
from studies.health.sources import load_visits
from studies.health.trend import Trend
from studies.health.trip import HEALTH_PARAMS, TripBoundary, trip_boundary
from studies.health.truth import TrueFirstFault, true_first_fault, truth_document

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


@dataclass
class Assessment:
    #: the health.json document (docs/health.md): JSON at the edge, written as is
    doc: dict[str, Any]
    visits: list[Visit]
    estimates: list[VisitEstimates]
    trends: dict[str, Trend]
    forecast: Forecast
    boundary: TripBoundary
    #: the forecast rebuilt as of each visit (:func:`.evaluate.sweep_predictions`; with trip samples)
    sweep: list[SweepPrediction] = field(default_factory=list)
    #: each visit's estimates of the set diagnose named (None: the default set was followed)
    followed_estimates: list[VisitEstimates] | None = None
    #: the monitor's trip limit of each followed effect parameter (SI)
    effect_limits: dict[str, float] = field(default_factory=dict)


def assess_health(sources: Sequence[str], *, params: str = "table2", as_of: float | None = None,
                  free: Sequence[str] | None = None, workers: int | None = None, seed: int = 1,
                  progress: Callable[[str], None] | None = None, dask_scheduler: str | None = None,
                  locate: str = "auto", locate_diagnose: bool = False, locate_visits: int = 1,
                  evaluate: bool = False, alpha: float = ALPHA, lambdas: Sequence[float] = LAMBDAS,
                  follow: str = "auto") -> Assessment:
    """``follow``: "auto" (when a visit's default fit leaves more than the noise or runs to a bound, ask shm
    diagnose on the latest such visit what changed and re-estimate and trend that set on every visit,
    :mod:`.follow`) or "never"; ``locate``: "auto" (place a stiffness loss in its section when the latest visit
    shows one — a stiffness changed or trending, or a health fit leaving 1.5 × the first visit's held-out
    residual), "always" or "never";
    ``locate_diagnose`` adds what ``shm diagnose`` names first on the latest visit to the candidates;
    ``locate_visits`` > 1 also places the loss on that many visits before the latest (``location_history``);
    ``evaluate`` scores the prognosis against the truth's first FAULT over every visit before it, whatever
    ``as_of`` (:mod:`.evaluate`; the sources must carry the truth: the board's verdicts or true parameters)."""
    say = progress or (lambda s: None)
    if follow not in ("auto", "never"):
        raise InputError(f"--follow must be auto or never, got {follow!r}")
    if locate not in ("auto", "always", "never"):
        raise InputError(f"--locate must be auto, always or never, got {locate!r}")
    free = tuple(free) if free else DEFAULT_FREE
    unknown = [f for f in free if f not in HEALTH_PARAMS]
    if unknown:
        raise InputError(f"--free {unknown[0]!r}: shm health re-estimates the monitor's health parameters "
                         f"({', '.join(HEALTH_PARAMS)})")
    if locate_visits < 1:
        raise InputError(f"--locate-visits must be >= 1, got {locate_visits}")
    all_visits = load_visits(sources)
    visits = [v for v in all_visits if as_of is None or v.operating_hours <= as_of + 1e-9]
    if len(visits) < 2:
        raise InputError(f"{len(visits)} visit(s) up to --as-of {as_of:g} h: a trend needs at least two visits "
                         f"(the sources hold {len(all_visits)} visits at "
                         + ", ".join(f"{v.operating_hours:g}" for v in all_visits[:12]) + " h)"
                         if as_of is not None else "the sources hold fewer than two visits: a trend needs two")
    say(f"shm health: {len(visits)} visits ({visits[0].operating_hours:g} … {visits[-1].operating_hours:g} h"
        + (f", as of {as_of:g} h; {len(all_visits) - len(visits)} later visits not used" if as_of is not None else "")
        + f"), re-estimating {', '.join(free)} with params {params}")
    if evaluate and not any(v.verdict for v in all_visits) and any(v.truth is None for v in all_visits):
        _evaluation_truth(None, all_visits)  # the one-line error, before any long computation
    say("trip boundary of the board's monitor (campaign machinery; computed once per parameter set, then cached)")
    boundary = trip_boundary(params)
    truth_ff = true_first_fault(all_visits, params, boundary)
    extra: list[Visit] = []
    if evaluate:
        t_eol = _evaluation_truth(truth_ff, all_visits)
        extra = [v for v in all_visits if v.operating_hours > visits[-1].operating_hours and v.operating_hours < t_eol]
        if extra:
            say(f"--evaluate: also re-estimating the {len(extra)} visits after the as-of time up to the true first "
                f"FAULT at {t_eol:g} h")
    ests_all = estimate_visits([*visits, *extra], params, free, workers=workers, progress=say,
                               dask_scheduler=dask_scheduler)
    followed = Followed()
    if follow == "auto":
        followed = find_and_follow(ests_all[: len(visits)], lambda i: visits[i].records, params,
                                   lambda eff, fr, base: estimate_visits(
                                       [*visits, *extra], params, fr, workers=workers, progress=say,
                                       dask_scheduler=dask_scheduler, add=eff, base=base), say)
    return assess_estimates(visits, all_visits, extra, ests_all, params=params, free=free, boundary=boundary,
                            truth_ff=truth_ff, as_of=as_of, seed=seed, say=say, locate=locate,
                            locate_diagnose=locate_diagnose, locate_visits=locate_visits, evaluate=evaluate,
                            alpha=alpha, lambdas=lambdas, followed=followed)


def assess_estimates(visits: list[Visit], all_visits: list[Visit], extra: list[Visit],
                     ests_all: list[VisitEstimates], *, params: str, free: Sequence[str], boundary: TripBoundary,
                     truth_ff: TrueFirstFault | None, as_of: float | None, seed: int, say: Callable[[str], None],
                     locate: str = "never", locate_diagnose: bool = False, locate_visits: int = 1,
                     evaluate: bool = False, alpha: float = ALPHA, lambdas: Sequence[float] = LAMBDAS,
                     followed: Followed | None = None) -> Assessment:
    """The assessment from the visits' estimates (``ests_all``: ``visits`` then ``extra``, the visits after the
    as-of time that only --evaluate uses): trends, forecast, the forecast as of every visit, location, truth.
    ``followed``: the set diagnose named and its estimates (:mod:`.follow`): then that set is trended."""
    followed = followed or Followed()
    ests = ests_all[: len(visits)]
    hours = [v.operating_hours for v in visits]
    t_ests = followed.estimates if followed.estimates is not None else ests_all
    t_free = followed.free if followed.switched else tuple(free)
    limits = effect_limits(params, t_free)
    y_all, s_all = series(t_ests, t_free)
    trends = trends_upto(hours, y_all, s_all, len(hours))
    interval = float(np.median(np.diff(hours))) if len(hours) > 1 else 100.0
    current = {n: trends[n].best.predict(np.array([hours[-1]]))[0] for n in t_free if n in HEALTH_PARAMS}
    fc = forecast_trip(trends, boundary, hours[-1], interval, current=current, seed=seed, effect_limits=limits)
    swept = [*visits, *extra]
    say(f"remaining life against time: the forecast rebuilt as of each visit from the {MIN_VISITS}th on "
        f"({max(len(swept) - MIN_VISITS + 1, 0)} forecasts)")
    sweep = sweep_predictions([v.operating_hours for v in swept], {n: list(v) for n, v in y_all.items()},
                              {n: list(v) for n, v in s_all.items()}, boundary, interval, seed=seed,
                              effect_limits=limits)
    location = _locate(visits, ests, trends, params, locate, locate_diagnose, say)
    if location.found is not None and locate_visits > 1:
        history = []
        for v in visits[-locate_visits:-1]:
            say(f"where? the visit at {v.operating_hours:g} h (--locate-visits)")
            history.append(locate_stiffness(v.records, params, operating_hours=v.operating_hours))
        location = replace(location, history=history)
    doc = _document(visits, all_visits, ests, trends, fc, hours, interval, as_of, params, free, location)
    doc["followed"] = followed.as_dict(hours) | {"effect_trip_limits": limits}
    if followed.estimates is not None:
        for vd, fe in zip(doc["visits"], followed.estimates):
            vd["followed_estimates"] = [x.to_json() for x in fe.estimates]
            vd["followed_held_rms_sigma"] = fe.held_rms_sigma
    doc["levels"] = levels(doc, trends, fc).to_json()
    doc["remaining_life"] = [p.to_json() for p in sweep]
    doc["truth"] = truth_document(visits, params, free, truth_ff)
    t_eol = truth_ff.operating_hours if truth_ff is not None else None  # h; assess_health checks it is known
    doc["evaluation"] = (evaluate_sweep(sweep, t_eol, alpha=alpha, lambdas=lambdas).to_json()
                         | {"truth_source": truth_ff.source, "true_first_fault_visit": truth_ff.visit}
                         if evaluate and truth_ff is not None and t_eol is not None else None)
    return Assessment(doc, visits, ests, trends, fc, boundary, sweep, followed.estimates, limits)


def _evaluation_truth(truth_ff: TrueFirstFault | None, all_visits: Sequence[Visit]) -> float:
    """The true first FAULT's hours for --evaluate, or a one-line InputError saying what is missing."""
    if truth_ff is None:
        raise InputError("--evaluate needs a life whose truth is known: these sources carry neither the board's "
                         "verdicts (a run directory of shm run or its usage.db) nor true parameters (the "
                         "provenance.truth_values of a shm synth record)")
    if truth_ff.operating_hours is None:
        raise InputError(f"--evaluate: no FAULT in the {len(all_visits)} visits (up to "
                         f"{all_visits[-1].operating_hours:g} h; truth from {truth_ff.source}): a prognosis is "
                         "scored against the first FAULT")
    t_eol = float(truth_ff.operating_hours)
    if sum(v.operating_hours < t_eol for v in all_visits) < MIN_VISITS:
        raise InputError(f"--evaluate: the first FAULT is at {t_eol:g} h, after only "
                         f"{sum(v.operating_hours < t_eol for v in all_visits)} visits; a prediction needs "
                         f"{MIN_VISITS} visits before it")
    return t_eol


def _locate_trigger(ests: list[VisitEstimates], trends: dict[str, Trend]) -> str | None:
    """Why the latest visit calls for placing a stiffness loss (None: no reason)."""
    last = ests[-1]
    for x in last.estimates:
        if x.name in SECTIONS and _est_verdict(x) == "changed":
            return f"{x.name} changed at the latest visit"
    for n, t in trends.items():
        if n in SECTIONS and t.significant:
            return f"significant {n} trend"
    first = ests[0].held_rms_sigma
    if math.isfinite(first) and last.held_rms_sigma > 1.5 * first:
        return (f"the health fit leaves {last.held_rms_sigma:.2f} σ held-out residual at the latest visit "
                f"({first:.2f} σ at the first)")
    return None


def _locate(visits: list[Visit], ests: list[VisitEstimates], trends: dict[str, Trend], params: str, mode: str,
            with_diagnose: bool, say: Callable[[str], None]) -> LocationRun:
    """Place the stiffness loss on the latest visit when ``mode`` asks for it (auto: when a trigger says so)."""
    why = _locate_trigger(ests, trends) if mode == "auto" else ("asked (--locate always)" if mode == "always"
                                                                  else None)
    if why is None:
        return LocationRun("not asked (--locate never)" if mode == "never" else
                           "no stiffness change, trend or excess residual at the latest visit (--locate always "
                           "forces it)")
    v = visits[-1]
    extra: list[str] = []
    if with_diagnose:
        say(f"where? shm diagnose on the visit at {v.operating_hours:g} h ...")
        name = diagnose_first_name(v.records, params)
        say(f"  shm diagnose names first: {name}")
        if name:
            extra.append(name)
    say(f"where? ({why}) freeing k1, k2, k3{''.join(', ' + e for e in extra if e not in SECTIONS)} one at a time "
        "with alpha_h, beta_h "
        f"on the visit at {v.operating_hours:g} h")
    found = locate_stiffness(v.records, params, operating_hours=v.operating_hours, extra=extra)
    for c in found.candidates:
        if c.error is not None:
            say(f"  {c.name}: could not be fitted ({c.error})")
        else:
            rel = f"{100 * c.relative:+.2f} %" if c.relative is not None else "effect"
            bound = " AT ITS FIT BOUND (a limit, not an estimate)" if c.at_bound else ""
            say(f"  {c.name} alone: {rel}{bound}, held-out rss {c.held_rss_sigma2:.0f} σ² ({c.fit_wall_s:.1f} s)")
    return LocationRun(found=found, trigger=why, diagnose_named=extra[0] if extra else None)


def _document(visits: list[Visit], all_visits: list[Visit], ests: list[VisitEstimates], trends: dict[str, Trend],
              fc: Forecast, hours: list[float], interval: float, as_of: float | None, params: str,
              free: Sequence[str], location: LocationRun | None = None) -> dict[str, Any]:
    """health.json (docs/health.md) from the typed results: the JSON document at the edge."""
    vis = []
    for v, e in zip(visits, ests):
        vis.append({
            "visit": v.visit, "operating_hours": v.operating_hours, "board_verdict": v.verdict,
            "mbit_verdicts": v.mbit_verdicts, "records": [str(r.path) for r in v.records],
            "held_rms_sigma": e.held_rms_sigma,
            "estimates": [{"name": x.name, "value": x.value, "stderr": x.stderr, "unit": x.unit,
                           "nominal": x.nominal, "relative": x.relative, "at_bound": x.at_bound,
                           "verdict": _est_verdict(x)} for x in e.estimates],
        })
    trend_doc = {}
    for n, t in trends.items():
        trend_doc[n] = {"model": t.model, "best_fit_model": t.best.name, "significant": t.significant,
                        "p_value": t.p_value, "rate": t.rate_per_100h(hours[-1]) / 100.0,
                        "rate_unit": "relative deviation per hour" if effect_of(n) is None else
                        f"{_unit_of(n)} per hour", "rate_per_100h_pct": 100 * t.rate_per_100h(
                            hours[-1]), "information_criterion": {k: (f.ic if math.isfinite(f.ic) else None)
                                                 for k, f in t.fits.items()},
                        "model_weights": t.weights,
                        "change_point_hours": t.best.tau if t.best.name == "change_point" and t.significant
                        else None, "change_point_note": t.change_point_note,
                        "current_relative": float(t.best.predict(np.array([hours[-1]]))[0]),
                        "latest_visit_check": t.check}
    f = fc.as_dict()
    start = hours[0]
    f["visit_interval_hours"] = interval
    if fc.trip_interval_90 is not None:
        lo, hi = fc.trip_interval_90
        f["trip_visits_90"] = [_visit_number(visits, lo, start, interval), _visit_number(visits, hi, start, interval)]
        f["trip_visit"] = _visit_number(visits, fc.trip_operating_hours, start, interval)
    later = [v for v in all_visits if v.operating_hours > hours[-1]]
    first_fault = next((v for v in all_visits if v.verdict == "FAULT"), None)
    doc = {
        "params": params, "free": list(free), "as_of_hours": as_of, "visits_used": len(visits),
        "visits_later_not_used": len(later), "visits": vis, "trend": trend_doc, "forecast": f,
        "location": None if location is None else location.to_json(),
        "board_first_fault": None if first_fault is None else {"visit": first_fault.visit,
                                                               "operating_hours": first_fault.operating_hours},
    }
    doc["levels"] = levels(doc, trends, fc).to_json()
    return doc


def _visit_number(visits: list[Visit], hours: float | None, start: float, interval: float) -> int | None:
    k = visit_of(hours, start, interval)
    if k is None:
        return None
    first_no = visits[0].visit if visits[0].visit is not None else 1
    return first_no + k


def _est_verdict(x: VisitParameter) -> str:
    rel = x.relative
    se = (x.stderr or 0.0) / abs(x.nominal)
    if abs(rel) > max(3 * se, 0.02):
        return "changed"
    return "as nominal"


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


def _unit_of(name: str) -> str:
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
        rate = (f", {t.rate_per_100h(last['operating_hours']) / 100.0:+.3g} {_unit_of(n)} per h ({t.best.name})"
                if t.significant else ", no significant trend")
        if effect_of(n) is not None:
            se = f" ± {est['stderr']:.2g}" if est["stderr"] is not None else ""
            lim = (fol.get("effect_trip_limits") or {}).get(n)
            lim_s = f"; the monitor trips at {n} ≈ {lim:.3g} {_unit_of(n)}" if lim and math.isfinite(lim) else ""
            out.append(f"{n} {est['value']:.3g}{se} {_unit_of(n)}{rate}{lim_s}")
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
