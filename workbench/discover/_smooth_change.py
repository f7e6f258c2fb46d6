"""A damage event whose change took time and arrested (issue 26 point 3): a step with a fitted edge,
``½(1 + tanh((t − t0)/w))`` — half the change at t0, 10–90 % of it over 2.2 w.

A kept step or ramp that leaves more than the noise is tried as a window (two ramps, straight corners) and as two
steps (:mod:`workbench.discover._staged_change`); a loss that runs and arrests along an S-curve is neither, and at a
sweep's signal-to-noise the window's corners alone leave several σ: section 1 losing 30 % along
½(1 + tanh((t − 8.25 s)/0.6 s)) of a 15 s sweep was kept as a window from 7.27 to 9.18 s, 4.54 σ held out (585 σ
before). The dictionary's steps carry their edge width as a parameter (``h_NN``, default the sharp
:data:`~workbench.discover._gates.STEP_WIDTH_S`), so the same step slot with a wide edge *is* the S-curve:
:func:`smooth_refit` probes edge widths (and, from a kept ramp, centres after its onset) on the full model, zooms
the best over the whole record and refits size, centre and width on the training blocks.

Pure logic on the fit engine's objects; :func:`~workbench.discover._staged_change.change_refit` keeps the better.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from board_config.parameter import Parameter, freed
from plant import PlantModel
from workbench.discover._dictionary import Term
from workbench.discover._dictionary_code import width_name
from workbench.discover._event_check import static_twin
from workbench.discover._finite_change import (
    ZOOM_TOTAL,
    WindowFit,
    gate_slots,
    lowest,
    others_free,
    whole_rms,
    whole_scores,
)
from workbench.discover._gates import onset_floor
from workbench.discover._onset import MAX_LOSS, ONSET_RESOLUTION_S
from workbench.discover._search import SearchState, refine
from workbench.discover._simplex_place import simplex_search
from workbench.fit import Objective, Target

#: edge widths w probed for an S-curve (fractions of the record: from a change over a few tenths of a percent of
#: it to one over a fifth of it, 10–90 %)
WIDTHS = (0.002, 0.006, 0.015, 0.035, 0.08)
#: from a kept ramp: the S-curve's centre at these shares of the time left after the ramp's onset, its total the
#: ramp's rate × that time left × these multipliers
RAMP_CENTRES = (0.1, 0.25, 0.4, 0.55, 0.7)
RAMP_TOTALS = (0.5, 1.0)
#: time constants probed for a ramp that settles (fractions of the record), its total change (rate × time constant)
#: as multiples of a kept ramp's change over the time left, or as shares of a kept step's size with the step
#: resized to end at the kept level (a recovery: the opposite sign, from a larger drop — a step of k2 refitted
#: alone on a 35 % loss that recovers half sized itself −17.9 %; a further loss that settles: the same sign)
SETTLE_TAUS = (0.03, 0.08, 0.2, 0.5)
SETTLE_TOTALS = (0.5, 0.8, 1.2)
RECOVER_SHARES = (-1.0, -0.5, -0.25, 0.25, 0.5)
#: the zoom moves the width by these factors and the centre (an onset) by ± a step — a quarter of the width for an
#: S-curve, :data:`RAMP_ONSET_STEP_S` for a ramp — halved each of :data:`ZOOM_ROUNDS` rounds
ZOOM_WIDTH = (0.8, 1.0, 1.25)
ZOOM_ROUNDS = 4
RAMP_ONSET_STEP_S = 0.02
#: how far (s) the refit may move a settling ramp's onset
RAMP_ONSET_FREE_S = 0.1
#: after the refit the onset is placed on the whole record, moved by these offsets (s) either way, and the refit is
#: run again with it held
POLISH_OFFSETS_S = (0.0001, 0.0002, 0.0005, 0.001, 0.002, 0.004, 0.008, 0.016)
#: an accelerating change (a ramp of negative width −T: quadratic in time for T, then held) probed from a kept
#: step with T at these fractions of the record, its start 0.7 T before the step (where a quadratic growth reaches
#: half its total) and its total the step's × ``ACCEL_TOTALS``; from a kept ramp with its start these fractions of
#: the record before the ramp's onset, its end at these shares of the time left and its total the ramp's change
#: over the time left × ``RAMP_TOTALS`` (a 18 % loss of k2 growing as ((t − 4.5 s)/9 s)² over a 15 s sweep was kept
#: as a window from 6.5 to 13.5 s, 4.29 σ)
ACCEL_SPANS = (0.1, 0.25, 0.45, 0.65)
ACCEL_HALF_WAY = 0.7
ACCEL_TOTALS = (0.8, 1.0, 1.25)
ACCEL_EARLIER = (0.0, 0.05, 0.15, 0.3)
ACCEL_ENDS = (0.5, 0.75, 1.0)
#: the accelerating change's zoom: a simplex search (Nelder–Mead) of its start, its end and its total on the whole
#: record's error, from each of the best :data:`ACCEL_STARTS` first edges, at most :data:`ACCEL_EVALS` probes each.
#: The error is narrow and has side valleys (the 18 % loss of k2 over 4.5–13.5 s of a 15 s sweep fits to 0.977 σ,
#: with 16 % to 34 σ, started 0.5 s later to 9.9 σ): the S-curve's grid zoom stopped at 3.85 σ, a pattern search of
#: 26 neighbours at 2.58 σ, the simplex from the best first edge at 2.15 σ and from the second and third at
#: 0.977 σ (140–207 probes of 15 ms)
ACCEL_STARTS = 4
ACCEL_EVALS = 250
#: an accelerating change grows over at least this share of the record: a quicker one is a step (the S-curve's
#: business), and said as one accelerating "between t = 11 s and t = 11 s" it misleads (a 15 % loss of k2 at 11.0 s
#: of MBIT.a)
ACCEL_MIN_SHARE = 0.01
#: the variants: a step with a fitted edge, a kept ramp that settles, a kept step that then partly recovers (or
#: goes on, settling), a change that accelerates and holds — the dictionary form each is written in, and the kept
#: forms it starts from
VARIANTS = {"smooth": ("on_step", ("on_step", "on_ramp")), "settle": ("on_ramp", ("on_ramp",)),
            "recover": ("on_ramp", ("on_step",)), "accelerate": ("on_ramp", ("on_step", "on_ramp"))}


@dataclass(frozen=True)
class Edge:
    """A change of ``total`` (relative) at ``centre`` (s: an S-curve's half-way instant, a ramp's onset) with time
    scale ``width`` (s: the S-curve's edge, the ramp's time constant; negative, −T: an accelerating ramp's growth
    time T)."""

    centre: float
    width: float
    total: float


@dataclass(frozen=True)
class EdgeProbe:
    """What probing edges needs: the records, their models, the values (the replaced term off), the slot's
    (coefficient, onset, width) names, its form (a ramp's coefficient is its rate, total ÷ width) and the
    integrator's threads."""

    targets: Sequence[Target]
    models: Sequence[PlantModel]
    values: dict[str, float]
    names: tuple[str, str, str]
    threads: int | None
    form: str = "on_step"
    #: a recovery's kept step (its coefficient's name, its size, its onset's name): the step set to size − total,
    #: so that the record ends at the kept step's level (a step refitted alone sizes itself to most of the
    #: record), at the recovery's onset (a step refitted alone is placed late, 4.529 s for a drop at 4.5 s)
    level: tuple[str, float, str] | None = None
    #: where the centre may lie (a switching point's range; None: within the record)
    bounds: tuple[float, float] | None = None

    def setting(self, e: Edge) -> dict[str, float]:
        c, g, h = self.names
        out = {c: e.total / abs(e.width) if self.form == "on_ramp" else e.total, g: e.centre, h: e.width}
        if self.level is not None:
            out[self.level[0]] = self.level[1] - e.total
            out[self.level[2]] = e.centre
        return out

    def scores(self, edges: Sequence[Edge]) -> list[float]:
        """The whole record's RMS (σ) with each edge (inf where it does not integrate)."""
        return whole_scores(self.targets, self.models, self.values, [self.setting(e) for e in edges], self.threads)


def candidate_edges(form: str, coef: float, onset: float, t_end: float, variant: str = "smooth") -> list[Edge]:
    """Edges to probe from a kept ``form`` (``on_step`` of size ``coef`` at ``onset``, or ``on_ramp`` of rate
    ``coef`` from it) in a record ending at ``t_end`` (s): an S-curve centred on the step or after the ramp's onset
    (``variant`` "smooth"), the ramp settling ("settle"), a settling ramp from the step's instant ("recover"), a
    change accelerating to the step's size or the ramp's change ("accelerate", :data:`ACCEL_SPANS`)."""
    left = max(t_end - onset, 0.0)
    if variant == "accelerate":
        return accelerating_edges(form, coef, onset, t_end)
    if variant == "settle":
        return [Edge(onset, w * t_end, coef * left * m) for w in SETTLE_TAUS for m in SETTLE_TOTALS]
    if variant == "recover":
        return [Edge(onset, w * t_end, coef * m) for w in SETTLE_TAUS for m in RECOVER_SHARES]
    widths = [w * t_end for w in WIDTHS]
    if form == "on_step":
        return [Edge(onset, w, coef) for w in widths]
    return [Edge(onset + c * left, w, coef * left * m) for c in RAMP_CENTRES for w in widths for m in RAMP_TOTALS]


def accelerating_edges(form: str, coef: float, onset: float, t_end: float) -> list[Edge]:
    """:func:`candidate_edges`' accelerating changes (width −T) from a kept step of size ``coef`` or a ramp of
    rate ``coef`` from ``onset`` (s) in a record ending at ``t_end`` (s)."""
    if form == "on_step":
        return [Edge(max(onset - ACCEL_HALF_WAY * f * t_end, 0.0), -f * t_end, coef * m)
                for f in ACCEL_SPANS for m in ACCEL_TOTALS]
    out = []
    for back in ACCEL_EARLIER:
        start = max(onset - back * t_end, 0.0)
        out += [Edge(start, -e * (t_end - start), coef * max(t_end - onset, 0.0) * m)
                for e in ACCEL_ENDS for m in RAMP_TOTALS]
    return [e for e in out if e.width < -ACCEL_MIN_SHARE * t_end]


def zoom_edge(probe: EdgeProbe, first: Sequence[Edge], t_end: float) -> tuple[Edge, float, int] | None:
    """The best of ``first`` by the whole record's RMS, zoomed for :data:`ZOOM_ROUNDS` rounds: centre ± a step
    (halved each round, not below the onsets' resolution), width × :data:`ZOOM_WIDTH`, total × ``ZOOM_TOTAL``.
    Returns the edge, its RMS and the probes run per record (None when nothing integrates)."""
    found = lowest(first, probe.scores(first))
    if found is None:
        return None
    (best, score), n = found, len(first)
    step = RAMP_ONSET_STEP_S if probe.form == "on_ramp" else 0.25 * best.width
    lo, hi = probe.bounds or (0.0, t_end)
    for _ in range(ZOOM_ROUNDS):
        if probe.bounds is None and step < ONSET_RESOLUTION_S:
            break
        grid = [Edge(best.centre + i * step, best.width * f, best.total * m) for i in (-1, 0, 1)
                for f in ZOOM_WIDTH for m in ZOOM_TOTAL if (i, f, m) != (0, 1.0, 1.0)]
        grid = [e for e in grid if lo <= e.centre <= hi]
        best, score = lowest([best, *grid], [score, *probe.scores(grid)]) or (best, score)
        n += len(grid)
        step *= 0.5
    return best, score, n


def simplex_edge(probe: EdgeProbe, first: Sequence[Edge], t_end: float) -> tuple[Edge, float, int] | None:
    """The best accelerating edge (width −T) by the whole record's RMS: a simplex search of (start, end, total)
    from each of the :data:`ACCEL_STARTS` best of ``first`` (an end up to twice the record: a loss still growing
    when the record ends). Returns the edge, its RMS and the probes run per record (None when nothing
    integrates)."""
    scores = probe.scores(first)
    found = lowest(first, scores)
    if found is None:
        return None
    (best, score), n = found, len(first)
    order = sorted(range(len(first)), key=lambda i: scores[i])[:ACCEL_STARTS]

    def rms(v: list[float]) -> float:
        nonlocal n
        start, end, total = v
        if start < 0.0 or end - start < ACCEL_MIN_SHARE * t_end or end > 2.0 * t_end:
            return math.inf
        n += 1
        return float(probe.scores([Edge(start, start - end, total)])[0])

    for i in order:
        if not math.isfinite(scores[i]):
            continue
        e = first[i]
        (start, end, total), fun = simplex_search(rms, [e.centre, e.centre - e.width, e.total], ACCEL_EVALS)
        if math.isfinite(fun) and fun < score:
            best, score = Edge(start, start - end, total), fun
    return best, score, n


def edge_free(terms: Sequence[Term], names: Sequence[tuple[str, str | None]], state: SearchState,
              start: dict[str, float], slot: int, replaced: int, t_end: float, onsets: bool = True
              ) -> list[Parameter]:
    """Free parameters of the edge's refit: the other kept terms' coefficients (±1.5 × their size; a step that
    recovers too), the slot's coefficient (±2 × it, a loss never past ``MAX_LOSS``), its onset (an S-curve's
    centre ± its width, at least ± 50 ms; a ramp's ± :data:`RAMP_ONSET_FREE_S`; within the record) and its width
    (a factor of three either way, in log; an accelerating ramp's growth time linearly, and its onset ± a quarter
    of it). ``onsets`` False: the onset held where the zoom placed it."""
    out = others_free(terms, names, state, start, (slot, slot), replaced)
    cname, gname = names[slot]
    c, g, w = start[cname], start[str(gname)], start[width_name(slot)]
    lo = max(c - 2.0 * abs(c), MAX_LOSS) if terms[slot].unit == "1" else c - 2.0 * abs(c)
    out.append(freed(cname, terms[slot].unit, lo, c + 2.0 * abs(c), False, "discover"))
    half = max(w, 0.05) if terms[slot].form == "on_step" else max(-0.25 * w, RAMP_ONSET_FREE_S)
    if onsets:
        out.append(freed(str(gname), "s", onset_floor(g, half), min(g + half, t_end), False, "discover"))
    shortest = min(w / 3.0, -ACCEL_MIN_SHARE * t_end)  # −T of the shortest growth allowed
    out.append(freed(width_name(slot), "s", w / 3.0, w * 3.0, True, "discover") if w > 0.0 else
               freed(width_name(slot), "s", min(3.0 * w, 3.0 * shortest), shortest, False, "discover"))
    return out


def smooth_refit(targets: Sequence[Target], models: Sequence[PlantModel], terms: Sequence[Term],
                 names: Sequence[tuple[str, str | None]], state: SearchState, kept: int, t_end: float,
                 threads: int | None, max_nfev: int, variant: str = "smooth", like: int | None = None
                 ) -> WindowFit | None:
    """The kept time-gated term ``kept`` (dictionary index) as a change with a fitted time scale (``variant``: one
    of :data:`VARIANTS`): the edges of :func:`candidate_edges` probed on the full model, the best zoomed
    (:func:`zoom_edge`; an accelerating change's :func:`simplex_edge`) and refitted (:func:`edge_free`). "smooth",
    "settle" and "accelerate" replace the kept term; "recover" adds a settling ramp of its parameter from the kept
    step's instant (the step stays, its size refitted). ``like``: the change is of that term's parameter instead,
    in place of the kept term, started from the kept change's static twin (a stiffness lost where a patch's
    authority rose; not for "recover"). None when the kept form does not start the variant, the parameter has no
    free slot or nothing integrates."""
    term = terms[kept]
    form, starts = VARIANTS[variant]
    if term.form not in starts or (like is not None and variant == "recover"):
        return None
    slots = [k for k in gate_slots(terms, terms[kept if like is None else like], form)
             if (k == kept and variant != "recover") or k not in state.kept]
    if not slots:
        return None
    slot = slots[0]
    replaced = slot if variant == "recover" else kept
    cname, gname = names[kept]
    sc, sg = names[slot]
    base = dict(state.values) | ({} if variant == "recover" else {cname: 0.0})
    level = (cname, float(state.values[cname]), str(gname)) if variant == "recover" else None
    probe = EdgeProbe(targets, models, base, (sc, str(sg), width_name(slot)), threads, form, level)
    coef = float(state.values[cname]) if like is None else static_twin(float(state.values[cname]))
    first = candidate_edges(term.form, coef, float(state.values[str(gname)]), t_end, variant)
    zoomed = (simplex_edge if variant == "accelerate" else zoom_edge)(probe, first, t_end)
    if zoomed is None:
        return None
    edge, _, n = zoomed
    start = probe.values | probe.setting(edge)
    onset_names = [str(sg)] + ([level[2]] if level is not None else [])
    best, n_sims = None, n * len(targets)
    for onsets in (True, False):  # the onsets refitted on the training blocks, then held where the whole record
        free = edge_free(terms, names, state, start, slot, replaced, t_end, onsets)  # puts them
        if level is not None and onsets:  # the step's instant moves with the recovery's onset
            g0 = start[level[2]]
            free.append(freed(level[2], "s", onset_floor(g0, RAMP_ONSET_FREE_S), min(g0 + RAMP_ONSET_FREE_S, t_end),
                              False, "discover"))
        obj = Objective(targets, models, free, base_values=start, threads=threads)
        out = refine(obj, start, max_nfev)
        n_sims += obj.n_sims
        if out.ok and (best is None or whole_rms(targets, out) < whole_rms(targets, best)):
            best = out
        if out.ok and onsets:
            start, k = placed_onsets(probe, start | out.values, onset_names)
            n_sims += k * len(targets)
    if best is None:
        return None
    return WindowFit(slot, slot, replaced, best, start | best.values, n_sims, kind=variant)


def placed_onsets(probe: EdgeProbe, values: dict[str, float], onsets: Sequence[str]) -> tuple[dict[str, float], int]:
    """``values`` with the ``onsets`` (names: one, or a recovery's ramp and its step, set to one instant — the
    recovery starts with the drop) shifted together by the offset of :data:`POLISH_OFFSETS_S` that leaves the
    whole record lowest, and the probes run per record. A refit on the training blocks is blind to an onset inside
    a held-out block: a 35 % loss of k2 at 4.5 s recovering half, onsets refitted to 4.495 s: training 1.01 σ,
    held-out 14.4 σ; each placed in turn: the ramp's drifted to 4.528 s, 2.0 σ."""
    shifts = [0.0, *POLISH_OFFSETS_S, *(-d for d in POLISH_OFFSETS_S)]
    at = values[onsets[0]]
    settings = [{name: at + d for name in onsets} for d in shifts]
    rms = whole_scores(probe.targets, probe.models, values, settings, probe.threads)
    return values | settings[min(range(len(shifts)), key=lambda i: rms[i])], len(shifts)
