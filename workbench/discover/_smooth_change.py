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

from collections.abc import Sequence
from dataclasses import dataclass

from board_config.parameter import Parameter, freed
from plant import PlantModel
from workbench.discover._dictionary import Term
from workbench.discover._dictionary_code import width_name
from workbench.discover._finite_change import (
    ZOOM_TOTAL,
    WindowFit,
    gate_slots,
    lowest,
    others_free,
    whole_rms,
    whole_scores,
)
from workbench.discover._onset import MAX_LOSS, ONSET_RESOLUTION_S
from workbench.discover._search import SearchState, refine
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
#: the variants: a step with a fitted edge, a kept ramp that settles, a kept step that then partly recovers (or
#: goes on, settling) — the dictionary form each is written in, and the kept form it starts from
VARIANTS = {"smooth": ("on_step", ("on_step", "on_ramp")), "settle": ("on_ramp", ("on_ramp",)),
            "recover": ("on_ramp", ("on_step",))}


@dataclass(frozen=True)
class Edge:
    """A change of ``total`` (relative) at ``centre`` (s: an S-curve's half-way instant, a ramp's onset) with time
    scale ``width`` (s: the S-curve's edge, the ramp's time constant)."""

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
        out = {c: e.total / e.width if self.form == "on_ramp" else e.total, g: e.centre, h: e.width}
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
    (``variant`` "smooth"), the ramp settling ("settle"), a settling ramp from the step's instant ("recover")."""
    left = max(t_end - onset, 0.0)
    if variant == "settle":
        return [Edge(onset, w * t_end, coef * left * m) for w in SETTLE_TAUS for m in SETTLE_TOTALS]
    if variant == "recover":
        return [Edge(onset, w * t_end, coef * m) for w in SETTLE_TAUS for m in RECOVER_SHARES]
    widths = [w * t_end for w in WIDTHS]
    if form == "on_step":
        return [Edge(onset, w, coef) for w in widths]
    return [Edge(onset + c * left, w, coef * left * m) for c in RAMP_CENTRES for w in widths for m in RAMP_TOTALS]


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


def edge_free(terms: Sequence[Term], names: Sequence[tuple[str, str | None]], state: SearchState,
              start: dict[str, float], slot: int, replaced: int, t_end: float, onsets: bool = True
              ) -> list[Parameter]:
    """Free parameters of the edge's refit: the other kept terms' coefficients (±1.5 × their size; a step that
    recovers too), the slot's coefficient (±2 × it, a loss never past ``MAX_LOSS``), its onset (an S-curve's
    centre ± its width, at least ± 50 ms; a ramp's ± :data:`RAMP_ONSET_FREE_S`; within the record) and its width
    (a factor of three either way, in log). ``onsets`` False: the onset held where the zoom placed it."""
    out = others_free(terms, names, state, start, (slot, slot), replaced)
    cname, gname = names[slot]
    c, g, w = start[cname], start[str(gname)], start[width_name(slot)]
    lo = max(c - 2.0 * abs(c), MAX_LOSS) if terms[slot].unit == "1" else c - 2.0 * abs(c)
    out.append(freed(cname, terms[slot].unit, lo, c + 2.0 * abs(c), False, "discover"))
    half = max(w, 0.05) if terms[slot].form == "on_step" else RAMP_ONSET_FREE_S
    if onsets:
        out.append(freed(str(gname), "s", max(g - half, 0.0), min(g + half, t_end), False, "discover"))
    out.append(freed(width_name(slot), "s", w / 3.0, w * 3.0, True, "discover"))
    return out


def smooth_refit(targets: Sequence[Target], models: Sequence[PlantModel], terms: Sequence[Term],
                 names: Sequence[tuple[str, str | None]], state: SearchState, kept: int, t_end: float,
                 threads: int | None, max_nfev: int, variant: str = "smooth") -> WindowFit | None:
    """The kept time-gated term ``kept`` (dictionary index) as a change with a fitted time scale (``variant``: one
    of :data:`VARIANTS`): the edges of :func:`candidate_edges` probed on the full model, the best zoomed
    (:func:`zoom_edge`) and refitted (:func:`edge_free`). "smooth" and "settle" replace the kept term; "recover"
    adds a settling ramp of its parameter from the kept step's instant (the step stays, its size refitted). None
    when the kept form does not start the variant, its parameter has no free slot or nothing integrates."""
    term = terms[kept]
    form, starts = VARIANTS[variant]
    if term.form not in starts:
        return None
    slots = [k for k in gate_slots(terms, term, form) if (k == kept and variant != "recover") or k not in state.kept]
    if not slots:
        return None
    slot = slots[0]
    replaced = slot if variant == "recover" else kept
    cname, gname = names[kept]
    sc, sg = names[slot]
    base = dict(state.values) | ({} if variant == "recover" else {cname: 0.0})
    level = (cname, float(state.values[cname]), str(gname)) if variant == "recover" else None
    probe = EdgeProbe(targets, models, base, (sc, str(sg), width_name(slot)), threads, form, level)
    first = candidate_edges(term.form, float(state.values[cname]), float(state.values[str(gname)]), t_end, variant)
    zoomed = zoom_edge(probe, first, t_end)
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
            free.append(freed(level[2], "s", max(g0 - RAMP_ONSET_FREE_S, 0.0), min(g0 + RAMP_ONSET_FREE_S, t_end),
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
