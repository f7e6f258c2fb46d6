"""The same damage with another gate shape (issue 26 point 3): a change of one parameter in one place on one side of
its signal can switch sharply at a point off zero, open over a smooth edge, or grow with the signal up to a
saturation. The screen linearises each member at the shape it was built with (a sign gate at zero, an edge or a
saturation at a fixed share of the signal's scale), so a form whose shape sits far from there ranks below a
neighbour of the wrong shape, and the refit, started from the neighbour, stays in its basin:

- a crack in section 2 held shut until δ2 < −0.4 mm (a bilinear spring with its corner off zero, 30 % lost) was said
  "a crack … its lost stiffness growing with the opening … once δ2 reaches −1.4 mm" (26.4 σ; blind set 4, sweep) —
  the hinge at −0.4 mm is a member, screened at 0;
- patch 1 losing coupling in proportion to its positive voltage up to 250 V was kept as a smooth switch of the drive
  at 0 V over ±179 V (7.0 σ; MBIT.a).

:func:`shape_rows`: when a round's best refit is such a switched change and leaves more than the noise, the same
parameter, place and side with each other gate shape is probed on the full model over a grid of shapes (switching
points across the signal's range, edge widths over 1.5 decades, saturations over a factor of eight) and sizes
around the best's, each candidate's best zoomed, and the best probe of each comes back as a row placed at its shape,
for a refit. The rounds keep it only when it fits clearly better (:func:`workbench.discover._rounds.family_best`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from workbench.discover._dictionary import Term
from workbench.discover._finite_change import whole_rms
from workbench.discover._gates import SAT_GATES, SIDED_GATES, SIGN_GATES, SOFT_GATES
from workbench.discover._onset import whole_scores
from workbench.discover._results import ScreenRow

#: switching points probed (fractions of the signal's scale; within the term's own range)
POINTS = (-0.75, -0.6, -0.45, -0.3, -0.15, 0.0, 0.15, 0.3, 0.45, 0.6, 0.75)
#: edge widths (a smooth gate) and saturations (a growing one) probed, fractions of the signal's scale
WIDTHS = (0.03, 0.1, 0.3, 1.0)
#: edge widths probed for a smooth gate on a section's rate (fractions of the rate's scale): a direction-dependent
#: stiffness switches near the turning points and its error is not monotone in the edge (see
#: :data:`~workbench.discover._gates.SOFT_RATE_AT`) — a tip crack switched by δ̇3 < 0 over 0.2 mm/s was kept at
#: ±5.34 mm/s, the screen's 4.4 mm/s (0.5 % of δ̇3's 0.88 m/s scale) refitted into a basin a factor of 25 from the
#: truth (22.4 σ; sweep, blind set 5) — so over 2.5 decades from near the sharp switch, the zoom reaching a factor
#: of two below the smallest
RATE_WIDTHS = (0.0003, 0.001, 0.003, 0.01, 0.03, 0.1)
SATURATIONS = (0.25, 0.5, 1.0, 2.0)
#: saturations probed for a smoothly saturating gate (on a patch's charging current, whose scale is set by the drive's
#: fastest edges: see :data:`~workbench.discover._gates.SAT_CHARGE_AT`)
SMOOTH_SATURATIONS = (0.0125, 0.025, 0.05, 0.1, 0.2)
#: ... and on a patch's own voltage (its scale is the voltage's 99th percentile)
VOLT_SATURATIONS = (0.05, 0.1, 0.2, 0.4, 0.8)
#: sizes probed, multiples of the best refit's coefficient (a sharp switch gives the whole change where a smooth or
#: growing one gives part of it)
SIZES = (0.7, 1.0, 1.4)
#: shapes are tried only for a best that leaves more than this (σ held out): at the noise there is nothing to tell
ABOVE_SIGMA = 1.5
#: a probe comes back when its whole-record error is at most this share of the best refit's (a grid point off
#: the truth by a tenth of the scale still leaves a part; the refit places it)
NEAR_SHARE = 0.9
#: at most this many shapes are refitted (the best by their probes)
MAX_SHAPES = 2
#: the grid's best is zoomed this many rounds: a switching point ± half the grid's spacing (fraction of the scale
#: below, halved each round), a width or saturation × / ÷ (1 + SHAPE_STEP) (halved each round), the size × / ÷
#: ZOOM_SIZE — a crack's corner 0.1 mm off its truth (−0.4 mm, on a 2 mm scale) still left more than the kept
#: neighbour (sweep, blind set 4: the grid's −0.31 mm and −0.61 mm both above 52 σ)
ZOOM_ROUNDS = 3
POINT_STEP = 0.15
SHAPE_STEP = 0.5
ZOOM_SIZE = 1.15

#: a probe: (dictionary index, coefficient, shape)
Trial = tuple[int, float, float]


def gate_side(form: str) -> str:
    """"pos" or "neg" for a gate that acts on one side of its signal, "" for any other (a gap, a time gate)."""
    if form in SIDED_GATES:
        return "pos" if form.startswith("on_pos") else "neg"
    return ""


def same_kind(signal: str, other: str) -> bool:
    """Whether two gate signals are the same kind of quantity for a shape: a voltage (the drive's or the patch's
    own: their volts are alike, the patch's lagging), or a position — a section's deflection or a mass's
    displacement (a crack opened by the tip's swing or by its own section's bending: on a sweep the tip crack
    closing partly, δ3 > 0, was kept as switched by z3 over ±6 mm, 21.8 σ)."""
    volts = ("va", "vc")

    def position(s: str) -> bool:
        return s.startswith("delta") or (s.startswith("z") and not s.startswith("zd"))

    return signal == other or (signal in volts and other in volts) or (position(signal) and position(other))


def shape_grid(term: Term, scale: float) -> list[float]:
    """Shapes (SI) probed for ``term``: switching points within its range, edge widths, saturations."""
    if term.form in SIGN_GATES:
        lo, hi = term.shape_range or (-scale, scale)
        return sorted({min(max(f * scale, lo), hi) for f in POINTS})
    if term.form in SOFT_GATES:
        return [f * scale for f in (RATE_WIDTHS if term.signal.startswith("ddelta") else WIDTHS)]
    if term.form in SAT_GATES:
        return [f * scale for f in (SMOOTH_SATURATIONS if term.signal == "ic" else VOLT_SATURATIONS)]
    return [f * scale for f in SATURATIONS]


def shape_candidates(terms: list[Term], best: Term) -> list[int]:
    """Dictionary indices of ``best``'s parameter and place on the same side of the same kind of signal with another
    gate shape — refitted in the round already or not: the round's refit started from the screen's shape (a switch
    at 0), the grid starts it elsewhere (patch 3 weak below −100 V of drive, MBIT.a: the sharp switch refitted from
    0 V stayed in its basin, 8.0 σ). A sharp switch is its own candidate too: its refit moved its switching point
    from 0 only as far as the nearest basin (a root crack open at rest, cornered at δ1 = −0.25 mm, refitted to
    −0.17 mm with a wide edge: 14.7 σ, sweep). So is a smooth switch, its edge probed over the grid (its refit moves
    the edge a factor of four from the screen's; one candidate per form and signal, whatever the screen's widths)."""
    side = gate_side(best.form)
    if best.placement != "damage" or not side:
        return []
    out: dict[tuple[str, str], int] = {}
    for k, t in enumerate(terms):
        if (t.placement == "damage" and (t.param, t.index) == (best.param, best.index) and gate_side(t.form) == side
                and same_kind(best.signal, t.signal) and (t.form in (*SIGN_GATES, *SOFT_GATES)
                                                          or (t.form, t.signal) != (best.form, best.signal))):
            out.setdefault((t.form, t.signal), k)  # one per shape: the screen's several widths share one grid
    return list(out.values())


def _zoomed(trial: Trial, step: float, sign: bool) -> list[Trial]:
    """The neighbours of ``trial`` one zoom step away: its shape ± ``step`` (a switching point, SI) or × / ÷
    (1 + ``step``) (a width or a saturation), its size × / ÷ :data:`ZOOM_SIZE`."""
    k, c, g = trial
    shapes = (g - step, g, g + step) if sign else (g / (1.0 + step), g, g * (1.0 + step))
    return [(k, c * m, h) for h in shapes for m in (1.0 / ZOOM_SIZE, 1.0, ZOOM_SIZE) if (h, m) != (g, 1.0)]


def _probe(setup: Any, progress: Any, settings: Any, trials: list[Trial],
           base: Mapping[str, float] | None = None) -> np.ndarray:
    """The whole record's RMS (σ) with each trial on top of ``base`` (the kept set's values when None; inf where it
    does not integrate)."""
    settings_ = [{setup.names[k][0]: c} | ({str(setup.names[k][1]): g} if setup.names[k][1] else {})
                 for k, c, g in trials]
    values = progress.state.values if base is None else base
    progress.n_sims += len(trials) * len(setup.targets)
    return np.asarray(whole_scores(setup.targets, setup.models, values, settings_, settings.threads))


def best_shapes(setup: Any, progress: Any, settings: Any, cands: list[int], coef: float,
                base: Mapping[str, float] | None = None) -> dict[int, tuple[float, Trial]]:
    """Each candidate's best (whole-record RMS, trial) over :func:`shape_grid` × :data:`SIZES` × ``coef``, zoomed
    for :data:`ZOOM_ROUNDS` rounds (the step halved each round), on top of ``base`` (the kept set's when None)."""
    trials = [(k, coef * m, g) for k in cands
              for g in shape_grid(setup.terms[k], setup.scales.get(setup.terms[k].signal, 1.0)) for m in SIZES]
    found: dict[int, tuple[float, Trial]] = {}
    for tr, e in zip(trials, _probe(setup, progress, settings, trials, base)):
        if math.isfinite(e) and e < found.get(tr[0], (math.inf, tr))[0]:
            found[tr[0]] = (float(e), tr)
    for r in range(ZOOM_ROUNDS):
        steps = {k: (0.5 ** (r + 1) * POINT_STEP * setup.scales.get(setup.terms[k].signal, 1.0)
                     if setup.terms[k].form in SIGN_GATES else 0.5 ** r * SHAPE_STEP) for k in found}
        near = [n for k, (_, tr) in found.items() for n in _zoomed(tr, steps[k], setup.terms[k].form in SIGN_GATES)]
        near = [n for n in near if _within(setup.terms[n[0]], n[2])]
        for tr, e in zip(near, _probe(setup, progress, settings, near, base) if near else []):
            if math.isfinite(e) and e < found[tr[0]][0]:
                found[tr[0]] = (float(e), tr)
    return found


def _within(term: Term, shape: float) -> bool:
    """Whether ``shape`` is one the term may take: a switching point within its range, a positive width."""
    if term.form in SIGN_GATES and term.shape_range is not None:
        return term.shape_range[0] <= shape <= term.shape_range[1]
    return term.form in SIGN_GATES or shape > 0.0


def shape_rows(setup: Any, progress: Any, settings: Any, best: Any) -> list[ScreenRow]:
    """Rows of the round's ``best`` refit (a ``BestRefit``) with another gate shape, each placed at its best probe
    (:func:`best_shapes`), when that comes within :data:`NEAR_SHARE` of the best's whole-record error; at most
    :data:`MAX_SHAPES`. ``setup``, ``progress``, ``settings``: the rounds' objects."""
    if best.held_rms_sigma <= ABOVE_SIGMA:
        return []
    term = setup.terms[best.index]
    coef = float(best.outcome.values.get(setup.names[best.index][0], 0.0))
    cands = shape_candidates(setup.terms, term)
    if not cands or coef == 0.0:
        return []
    limit = NEAR_SHARE * whole_rms(setup.targets, best.outcome)
    found = best_shapes(setup, progress, settings, cands, coef)
    out = [ScreenRow(setup.terms[k], c, e, math.inf, shape=g, placed=True)
           for e, (k, c, g) in sorted(found.values(), key=lambda et: et[0]) if e <= limit]
    if out:
        settings.say(f"  {term.key} with another gate shape: {len(out)} within {limit:.3g} σ whole-record ("
                     + ", ".join(f"{r.term.key} at {r.shape:.3g} {r.term.shape_unit} {r.held_rms_sigma:.3g} σ"
                                 for r in out) + ")")
    return out[:MAX_SHAPES]
