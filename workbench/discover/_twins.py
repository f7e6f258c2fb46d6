"""The terms the records cannot tell apart from the one a round of ``shm discover`` keeps (:func:`twins_of`), within
the noise (:func:`twin_tolerance`)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

from workbench.discover._dictionary import DELAY_FORMS, SIGNALS, Term
from workbench.discover._effect_writer import describe_term
from workbench.discover._gates import TIME_GATES
from workbench.discover._results import ScreenRow
from workbench.discover._search import HARD_FORMS

#: at most this many twins are named per kept term
MAX_TWINS = 2
#: a twin's held-out RMS may exceed the chosen term's by this share (model tolerance) plus three standard
#: deviations of the RMS of white noise over the held-out samples
TWIN_MODEL_SHARE = 0.02


#: forms that switch on their signal: the hard forms (a force's sign, side, dead zone, clip or saturation; a
#: parameter's sign gate, soft edge or gap)
SWITCHING_FORMS = frozenset(HARD_FORMS)
#: terms of the chosen term's switching family refitted beside it (the best few by the screen): on its own signal,
#: and on the signals :func:`alike` it
MAX_SWITCH_FAMILY = 4
MAX_ALIKE_FAMILY = 2
#: a damage term constant in time is refitted in at most this many other places, each only when its screen comes
#: within this factor of the chosen term's own
MAX_PLACE_FAMILY = 2
PLACE_SCREEN_NEAR = 1.5
#: ... and only for a chosen term whose refit leaves at most this (held-out σ)
PLACE_BELOW_SIGMA = 3.0


def alike(a: str, b: str) -> bool:
    """Whether two signals measure the same kind of thing at the same place — the same unit and the same mass or
    section number (z2 and δ2, ż2 and δ̇2; the drive and the patch voltage): on a record that moves one way a switch on
    either reads alike (a force on mass 2 acting once z2 passes 0.9 mm, a section 2 stiffer beyond δ2 = 0.3 mm)."""
    if a == b:
        return True
    if a == "one" or b == "one" or SIGNALS[a].unit != SIGNALS[b].unit:
        return False
    return a.lstrip("abcdefghijklmnopqrstuvwxyz") == b.lstrip("abcdefghijklmnopqrstuvwxyz")


def switch_family(chosen: Term, rows: Sequence[ScreenRow], done: set[str], n: int = MAX_SWITCH_FAMILY,
                  n_alike: int = MAX_ALIKE_FAMILY) -> list[ScreenRow]:
    """The best ``n`` rows (in the screen's order) of the other terms that switch on the chosen term's own signal,
    then the best ``n_alike`` that switch on a signal :func:`alike` it, not refitted yet (``done``: keys). A record
    that moves that signal one way only, or never past some level, cannot tell these readings apart — a section
    softer for δ > 0 (a breathing crack) from one softer within ±g of δ (a clearance) on a step that bends the section
    one way: each gets its own refit, so the verdict names the ones the record cannot rule out (:func:`twins_of`) and
    keeps the one that fits clearly best."""
    if chosen.form not in SWITCHING_FORMS or chosen.signal == "one":
        return []
    own: list[ScreenRow] = []
    other: list[ScreenRow] = []
    seen = {chosen.key, *done}
    for r in rows:  # one row per key (a form's shapes are rows of their own)
        if r.term.form in SWITCHING_FORMS and r.term.key not in seen and alike(r.term.signal, chosen.signal):
            seen.add(r.term.key)
            (own if r.term.signal == chosen.signal else other).append(r)
    return _diverse(own, n) + _diverse(other, n_alike)


def _diverse(rows: Sequence[ScreenRow], n: int) -> list[ScreenRow]:
    """The best ``n`` of ``rows`` (in their order), the best of each physics first — a force of its placement and
    form, a core parameter's own change by its switch (sharp or smooth edge alike; growing with the opening apart) —
    then the next best: a root crack open for δ1 > 0 on an MBIT.b step, behind patch 1's coupling switched by δ1
    (sharp and smooth), a clearance and a crack growing with the opening, was never refitted and the first sentence
    named only the clearance."""
    firsts: dict[tuple[str, str, str], ScreenRow] = {}
    for r in rows:
        firsts.setdefault((r.term.placement, r.term.param, r.term.form.replace("_soft", "")), r)
    lead = list(firsts.values())[:n]
    return lead + [r for r in rows if r not in lead][: n - len(lead)]


def place_switch_family(chosen: Term, rows: Sequence[ScreenRow], done: set[str], held: float = 0.0,
                        n: int = MAX_PLACE_FAMILY, near: float = PLACE_SCREEN_NEAR) -> list[ScreenRow]:
    """The same switching physics in the other sections (masses, patches): rows of the chosen term's placement,
    form and parameter at another index on the same kind of signal there (δ2 for δ3, z1 for z3), not refitted yet
    (``done``: keys), whose screen comes within ``near`` × the chosen term's own — the best ``n`` by the screen. A
    record that excites one mode (an MBIT) moves a clearance in section 1 and one in section 3 alike: free play in
    the root clamp on MBIT.a was named "section 3 is softer … within ±108 µm of δ3" (the screen: s1, s2 and s3's
    clearances 2.71, 2.71, 2.69 σ), section 1 never said.

    Only for a term whose refit nearly explains the records (``held``, σ, at most :data:`PLACE_BELOW_SIGMA`): twins
    matter to the verdict's words, and far from the noise a better place is the next round's business — a strong
    tip stop on a sweep, kept as c3 × [δ̇3 > 0] at 95 σ, was replaced by its place in section 2 (79.6 σ) and the
    search went on to delays (74 σ) instead of the stop (0.98 σ)."""
    if chosen.index < 0 or chosen.form in TIME_GATES or held > PLACE_BELOW_SIGMA \
            or (chosen.placement != "damage" and chosen.form not in SWITCHING_FORMS):
        return []
    mine = min((r.held_rms_sigma for r in rows if r.term.key == chosen.key), default=math.inf)
    kind = chosen.signal.rstrip("0123456789")
    out: list[ScreenRow] = []
    seen = {chosen.key, *done}
    for r in rows:  # best first: the screen's order
        t = r.term
        if (t.placement, t.param, t.form) == (chosen.placement, chosen.param, chosen.form) \
                and t.index != chosen.index and t.signal.rstrip("0123456789") == kind and t.key not in seen \
                and r.held_rms_sigma <= near * max(mine, 1.0):
            seen.add(t.key)
            out.append(r)
    return out[:n]


def twin_tolerance(n_held: int) -> float:
    """Factor on the chosen term's held-out RMS within which another term explains the records as well."""
    return 1.0 + TWIN_MODEL_SHARE + 3.0 / math.sqrt(2.0 * max(n_held, 1))


def twins_of(chosen: Term, held: float, rows: Sequence[ScreenRow], tried: Sequence[dict[str, Any]], n_held: int,
             scales: Mapping[str, float], linearised: bool) -> list[dict[str, Any]]:
    """Other terms that explain the records as well as ``chosen`` (held-out RMS ``held``) within the noise
    (:func:`twin_tolerance`): refitted ones by their refit; when the chosen term came from the linearised screen
    (``linearised``: the fast path), the rest by that screen against the chosen term's own screen value. Same-key
    terms (another shape of the same form) and the other Padé order of the same delay are not twins."""
    tol = twin_tolerance(n_held)
    refitted = {t["term"]: t["held_rms_sigma"] for t in tried}
    mine = next((r.held_rms_sigma for r in rows if r.term.key == chosen.key), held)
    out: list[dict[str, Any]] = []
    seen = {chosen.key}
    for r in rows:
        key = r.term.key
        same_delay = ((r.term.placement, r.term.signal) == (chosen.placement, chosen.signal)
                      and {r.term.form, chosen.form} <= set(DELAY_FORMS))  # the same delay, another Padé order
        if key in seen or same_delay:
            continue
        seen.add(key)
        if key in refitted:
            h, how = refitted[key], "refitted"
            ok = h <= max(held, 1.0) * tol
        elif not linearised:  # screened on the full model at a linearised coefficient: not comparable to a refit
            continue
        else:
            h, how = r.held_rms_sigma, "screen"
            ok = h <= max(mine, 1.0) * tol  # the screen against the chosen term's own screen value
        if ok:
            scale = scales.get(r.term.signal, 1.0)
            out.append({"key": key, "placement": r.term.placement, "param": r.term.param, "index": r.term.index,
                        "signal": r.term.signal,
                        "form": r.term.form, "held_rms_sigma": h, "judged_by": how,
                        "words": describe_term(r.term, r.coef, r.term.shape, scale)})
    return place_first(chosen, out)


def place_first(chosen: Term, twins: Sequence[dict[str, Any]], n: int = MAX_TWINS) -> list[dict[str, Any]]:
    """The first ``n`` of ``twins`` (in their order), the first one in another place among them (another
    section, or the mass or patch at its end: the dictionary's index): where the damage is matters most to the one
    who repairs it. A crack in section 2 on MBIT.a (one mode, 10 µm) was named "a crack in section 1 …", its two
    twins both in section 1 (a patch switched by δ1, a crack open for δ1 > 0). And one more, the first of another
    kind (placement: a section's own damage beside a force on a mass), when none of those is: a tip crack stiffer
    past a wedge on MBIT.a was said as a stop on mass 3, its twins stops on masses 1 and 2, the crack unsaid. The
    one in another place is the same parameter's when there is one: sections 1 and 2 each losing 7 % at once on
    MBIT.a were said "section 1 lost 13.1 % … — these records cannot tell it from authority d_ep of patch 2 rose …;
    or from authority d_ep of patch 1 rose …", section 2 unsaid."""
    out = list(twins[:n])
    if chosen.index >= 0:  # the same damage elsewhere first (section 2 lost where section 1 lost), else any
        others = [t for t in twins if t.get("index", -1) >= 0 and t["index"] != chosen.index]
        elsewhere = next((t for t in others if t.get("param") == chosen.param), next(iter(others), None))
        if elsewhere is not None and elsewhere not in out:
            out = [*twins[: n - 1], elsewhere]
    if out and all(t.get("placement") == chosen.placement for t in out):
        other = next((t for t in twins if t.get("placement", chosen.placement) != chosen.placement), None)
        out += [other] if other is not None else []
    return out
