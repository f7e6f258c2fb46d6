"""A change that grows over a finite time and then stays (issue 26 point 3): two ramps of one parameter, ``+r``
from t0 and ``−r`` from t1, make the window ``r · clip(t − t0, 0, t1 − t0)`` — a loss that grows from t0 to t1 and
holds after it; as t1 − t0 → 0 it is a step.

The dictionary's time gates are a step at an onset and a ramp that never ends. A stiffness lost linearly from 2.5 s
to 7.5 s of a 10 s sweep, then holding, was kept as a ramp from 2.04 s at 3.42 %/s (20 σ left): the next round
screened every term again around that compromise, and the dictionary's other ramp of the same parameter, probed at
the residual's onset with the first ramp's onset fixed, never ended it. So when a round has kept a time-gated term
that leaves more than the noise, the change is tried with an end (:func:`window_refit`): windows of that parameter
from the kept term (a step: centred on its instant, over a few durations; a ramp: ending at shares of the time
left), probed on the full model, the best zoomed on the whole record and refitted with both rates and both onsets
free. It runs only after a time-gated term was kept; nothing is added to the screen. The pair is said as one change
(:func:`finite_changes`). Measured (10 s sweeps, 2 µm, seed 1, one record each): k1 −20 % over 5 s 20.2 σ → 1.03 σ;
c3 ×3 over 2 s 2.31 σ → 1.01 σ; k2 −25 % over 0.5 s with a smooth (cubic) edge 28.8 σ → 1.54 σ (the straight
window's corners).

Pure logic on the fit engine's objects: the rounds (:mod:`workbench.discover._rounds`) keep the result.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any, TypeVar

import numpy as np

from board_config.parameter import Parameter, freed
from plant import PlantModel
from workbench.discover._dictionary import Term
from workbench.discover._dictionary_code import since_name, since_placed, term_default_width, width_name
from workbench.discover._effect_writer import describe_term
from workbench.discover._event_check import static_twin
from workbench.discover._gate_words import describe_finite_change, describe_recovery
from workbench.discover._gates import WIDTH_GATES, onset_floor
from workbench.discover._onset import ONSET_RESOLUTION_S, whole_record_rms, whole_scores
from workbench.discover._results import FoundTerm
from workbench.discover._search import SearchState, refine
from workbench.fit import FitOutcome, Objective, Target

T = TypeVar("T")

#: durations (s) of the windows around a kept step's instant (a loss over a short time: its refit widens them), and
#: as shares of the record (a loss over a long time: a straight 30 % loss of k2 from 6 s to 9 s of a 15 s sweep was
#: kept as a step at 6.12 s, the change's first visible instant; the windows centred on it, 2.5 s at most, zoomed to
#: 6.13–8.69 s: 6.35 σ held out)
STEP_DURATIONS_S = (0.05, 0.15, 0.4, 1.0, 2.5)
STEP_DURATION_SHARES = (0.1, 0.2, 0.35)
#: where a step's instant lies in its window: the middle, the start (the change's first visible instant: a loss that
#: grows slowly is noticed early), the end
STEP_INSTANT_AT = (0.5, 0.0, 1.0)
#: where a window from a kept ramp may start (shares of the time left after the ramp's onset) and end (shares of
#: the time left after the window's start); the total change over the window as multiples of the ramp's rate × its
#: duration (a ramp that never ends fits the window's rate low: 3.42 %/s for a 4 %/s loss over 5 s)
RAMP_STARTS = (0.0, 0.1, 0.2)
RAMP_ENDS = (0.2, 0.35, 0.5, 0.65, 0.8)
RAMP_RATE_MULTIPLIERS = (1.0, 1.4)
#: the window's zoom: its total change moved by these factors at each step (its start and end by ± the step)
ZOOM_TOTAL = (0.95, 1.0, 1.05)
#: how far (s) the refit on the training blocks may move the zoomed onsets
ONSET_FREE_S = 0.05
#: how far (s) a refit of the emitted file may move a pair's onsets: the whole record placed them, a refit on the
#: training blocks alone is blind where they lie in a held-out block (the k2 loss over 0.5 s at 5.5 s, its file
#: refitted within ±1.25 s: 14.9 σ held-out; within ±50 ms: 2.98 σ; the discovery's own 1.54 σ)
EMITTED_ONSET_S = 0.01
#: two ramps of one key are said as one change that then holds when the rate left after the end (the sum of their
#: rates) is below this share of the rise's rate
HOLDS_SHARE = 0.15


@dataclass(frozen=True)
class Window:
    """A change of ``total`` (relative) growing linearly from ``start`` to ``end`` (s)."""

    start: float
    end: float
    total: float

    @property
    def rate(self) -> float:
        return self.total / max(self.end - self.start, 1e-6)


@dataclass(frozen=True)
class WindowFit:
    """The refit of a finite-time change: its two ramps (dictionary indices: the rise from t0 and the end at t1),
    the time-gated term it replaces (its index; the rise's own index when that was a ramp), the refit, every
    dictionary value with it (the replaced term off) and the simulations run; ``kind``: "window" (two ramps),
    "stages" (two steps) or "smooth" (one step with a fitted edge: ``rise`` and ``end`` the same slot)."""

    rise: int
    end: int
    replaced: int
    outcome: FitOutcome
    values: dict[str, float]
    n_sims: int
    kind: str = "window"
    #: further kept slots of the change (a third step: :func:`workbench.discover._staged_change.third_stage`)
    extra: tuple[int, ...] = ()

    @property
    def slots(self) -> tuple[int, ...]:
        """Every dictionary index the change keeps, in order (the rise, the end, the extra ones)."""
        return tuple(dict.fromkeys((self.rise, self.end, *self.extra)))


def gate_slots(terms: Sequence[Term], term: Term, form: str) -> list[int]:
    """The dictionary indices of the ``form`` terms (``on_ramp``, ``on_step``) of ``term``'s parameter (same core
    parameter and section/mass), the ``term``'s own first when it is one."""
    out = [k for k, t in enumerate(terms) if t.placement == "damage" and t.form == form
           and (t.param, t.index) == (term.param, term.index)]
    return sorted(out, key=lambda k: terms[k] != term)


def ramp_slots(terms: Sequence[Term], term: Term) -> list[int]:
    """The ramps of ``term``'s parameter (:func:`gate_slots`)."""
    return gate_slots(terms, term, "on_ramp")


def candidate_windows(form: str, coef: float, onset: float, t_end: float) -> list[Window]:
    """Windows to probe from a kept time-gated term (``form`` ``on_step`` of size ``coef`` at ``onset``: windows
    centred on it, starting at it and ending at it; or ``on_ramp`` of rate ``coef`` from it), within a record ending
    at ``t_end`` (s)."""
    out: list[Window] = []
    if form == "on_step":
        for at in STEP_INSTANT_AT:
            for d in (*STEP_DURATIONS_S, *(share * t_end for share in STEP_DURATION_SHARES)):
                a, b = max(onset - at * d, 0.0), min(onset + (1.0 - at) * d, t_end)
                if b > a and Window(a, b, coef) not in out:
                    out.append(Window(a, b, coef))
        return out
    for s in RAMP_STARTS:
        a = onset + s * (t_end - onset)
        for e in RAMP_ENDS:
            b = a + e * (t_end - a)
            out += [Window(a, b, coef * m * (b - a)) for m in RAMP_RATE_MULTIPLIERS]
    return out


def window_setting(window: Window, rise: tuple[str, str | None], end: tuple[str, str | None]) -> dict[str, float]:
    """The dictionary parameters of ``window`` as the two ramps ``rise`` (+rate from its start) and ``end`` (−rate
    from its end): (coefficient name, onset name) each."""
    return {rise[0]: window.rate, str(rise[1]): window.start, end[0]: -window.rate, str(end[1]): window.end}


def others_free(terms: Sequence[Term], names: Sequence[tuple[str, str | None]], state: SearchState,
                start: dict[str, float], pair: Sequence[int], replaced: int) -> list[Parameter]:
    """The coefficients of the kept terms other than ``pair`` and the ``replaced`` one, free within ±1.5 × their
    size (the refit of a change that replaces a kept term)."""
    out = []
    for k in state.kept:
        if k in pair or k == replaced:
            continue
        c = start[names[k][0]]
        span = max(abs(c), 1e-300)
        out.append(freed(names[k][0], terms[k].unit, c - 1.5 * span, c + 1.5 * span, False, "discover"))
    return out


def window_free(terms: Sequence[Term], names: Sequence[tuple[str, str | None]], state: SearchState,
                start: dict[str, float], pair: tuple[int, int], replaced: int, t_end: float,
                onset_half: float | None) -> list[Parameter]:
    """Free parameters of the window's refit: the other kept terms' coefficients (±1.5 × their size; not the
    ``replaced`` term's, off), both rates (±2 × the window's rate) and, unless ``onset_half`` is None, both onsets
    (within the record, ``onset_half`` s either way)."""
    out = others_free(terms, names, state, start, pair, replaced)
    rise, end = (names[k] for k in pair)
    rate = start[rise[0]]
    for cname, gname in (rise, end):
        c, g = start[cname], start[str(gname)]
        out.append(freed(cname, "1/s", c - 2.0 * abs(rate), c + 2.0 * abs(rate), False, "discover"))
        if onset_half is not None:
            out.append(freed(str(gname), "s", onset_floor(g, onset_half), min(g + onset_half, t_end), False,
                             "discover"))
    return out


@dataclass(frozen=True)
class WindowProbe:
    """What probing windows needs: the records, their models, the current values with the replaced term off, the
    two ramps' (coefficient, onset) names, the record's end (s) and the integrator's threads."""

    targets: Sequence[Target]
    models: Sequence[PlantModel]
    values: dict[str, float]
    rise: tuple[str, str | None]
    end: tuple[str, str | None]
    t_end: float
    threads: int | None

    def setting(self, window: Window) -> dict[str, float]:
        """The dictionary parameters of ``window`` (its two ramps)."""
        return window_setting(window, self.rise, self.end)

    def scores(self, windows: Sequence[Window]) -> list[float]:
        """The whole record's RMS (σ) with each window (inf where it does not integrate)."""
        return whole_scores(self.targets, self.models, self.values, [self.setting(w) for w in windows], self.threads)


def lowest(items: Sequence[T], scores: Sequence[float]) -> tuple[T, float] | None:
    """The first item of the lowest finite score, with its score (None when no score is finite)."""
    k = min(range(len(items)), key=lambda i: scores[i], default=None)
    return None if k is None or not math.isfinite(scores[k]) else (items[k], scores[k])


def zoom_window(probe: WindowProbe, first: Sequence[Window]) -> tuple[Window, float, int] | None:
    """The best of ``first`` by the whole record's RMS, then zoomed: its start and end moved by ± a step (a quarter
    of its duration, halved each time down to :data:`ONSET_RESOLUTION_S`) and its total by :data:`ZOOM_TOTAL`.
    Scored over the whole record, as :func:`~workbench.discover._onset.onset_scan` places an onset: a short change
    inside a held-out block is invisible to the training error (a k2 loss over 0.5 s at 5.5 s of a 10 s sweep,
    refitted on training only: start 5.04 s, training 1.2 σ, held-out 12.8 σ). Returns the window, its RMS and
    the probes run per record (None when nothing integrates)."""
    found = lowest(first, probe.scores(first))
    if found is None:
        return None
    (best, score), n = found, len(first)
    step = 0.25 * (best.end - best.start)
    while step > ONSET_RESOLUTION_S:
        grid = [Window(best.start + i * step, best.end + j * step, best.total * m) for i in (-1, 0, 1)
                for j in (-1, 0, 1) for m in ZOOM_TOTAL if (i, j, m) != (0, 0, 1.0)]
        # within the record, or from before it for a change already under way when the record began
        grid = [w for w in grid if min(best.start, 0.0) <= w.start < w.end <= probe.t_end]
        best, score = lowest([best, *grid], [score, *probe.scores(grid)]) or (best, score)
        n += len(grid)
        step *= 0.5
    return best, score, n


def window_refit(targets: Sequence[Target], models: Sequence[PlantModel], terms: Sequence[Term],
                 names: Sequence[tuple[str, str | None]], state: SearchState, kept: int, t_end: float,
                 threads: int | None, max_nfev: int, like: int | None = None) -> WindowFit | None:
    """The kept time-gated term ``kept`` (dictionary index) given an end: the windows of :func:`candidate_windows`
    probed on the full model (the kept term off) and the best zoomed (:func:`zoom_window`), then refitted with
    both rates free and both onsets within half the window's duration (at least 5 % of the record) of the zoom's —
    the zoom's steps move start, end and size one grid at a time, and stopped a 5 s loss from 2.5 s at 2.03–7.88 s
    while the refit reaches 2.49–7.51 s. When that refit (on the training blocks) leaves the whole record worse
    than the zoom did, the onsets are refitted within :data:`ONSET_FREE_S` of the zoom's, then held at them; the
    refit that leaves the whole record lowest is kept (None when its parameter has fewer than two ramps or nothing
    integrates). ``like``: the window is of that term's parameter instead, in place of the kept term (its kind:
    a stiffness lost where a patch's authority rose), started from the kept change's static twin."""
    term = terms[kept if like is None else like]
    slots = ramp_slots(terms, term)
    if len(slots) < 2:
        return None
    pair = (slots[0], slots[1])
    cname, gname = names[kept]
    coef = float(state.values[cname]) if like is None else static_twin(float(state.values[cname]))
    probe = WindowProbe(targets, models, dict(state.values) | {cname: 0.0}, names[pair[0]], names[pair[1]], t_end,
                        threads)
    zoomed = zoom_window(probe, candidate_windows(terms[kept].form, coef, state.values[str(gname)], t_end))
    if zoomed is None:
        return None
    window, score, n = zoomed
    start = probe.values | window_setting(window, probe.rise, probe.end)
    n_sims = n * len(targets)
    best: FitOutcome | None = None
    for half in (max(0.5 * (window.end - window.start), 0.05 * t_end), ONSET_FREE_S, None):
        obj = Objective(targets, models, window_free(terms, names, state, start, pair, kept, t_end, half),
                        base_values=start, threads=threads)
        out = refine(obj, start, max_nfev)
        n_sims += obj.n_sims
        if out.ok and (best is None or whole_rms(targets, out) < whole_rms(targets, best)):
            best = out
        if best is not None and whole_rms(targets, best) <= score * (1.0 + 1e-3):
            break
    return None if best is None else WindowFit(pair[0], pair[1], kept, best, start | best.values, n_sims)


def whole_rms(targets: Sequence[Target], out: FitOutcome) -> float:
    return float(whole_record_rms(targets, np.array([out.held_rms_sigma]), np.array([out.train_rms_sigma]))[0])


def keep_window(state: SearchState, stderr: dict[str, float], twins: dict[int, list[dict[str, Any]]],
                fit: WindowFit) -> None:
    """Keep the window's two ramps in place of the term it replaces: the kept list, the values, the standard
    errors (the twins of a ramp that never ends are no twins of the window: dropped)."""
    state.kept = [k for k in state.kept if k not in (fit.replaced, *fit.slots)] + list(fit.slots)
    state.values.update(fit.values)
    stderr.update({e.name: e.stderr for e in fit.outcome.estimates})
    for k in (fit.replaced, *fit.slots):
        twins.pop(k, None)


def found_term(terms: Sequence[Term], names: Sequence[tuple[str, str | None]], scales: Mapping[str, float],
               values: Mapping[str, float], stderr: Mapping[str, float], twins: list[dict[str, Any]],
               k: int) -> FoundTerm:
    """Dictionary term ``k`` at ``values`` as found: its coefficient, its shape (an onset with its standard error
    from ``stderr``), a fitted edge or settling time said and written so, in words, with its ``twins``."""
    cname, gname = names[k]
    term = terms[k]
    coef = values[cname]
    shape = values[gname] if gname else 0.0
    scale = scales.get(term.signal, 1.0)
    se = stderr.get(gname) if gname else None
    if term.form in WIDTH_GATES:  # a step whose edge, a ramp whose saturation was fitted: said and written so
        width, default = values.get(width_name(k), 0.0), term_default_width(term)
        if width != 0.0 and abs(width - default) > 1e-3 * default:
            term = replace(term, width=float(width))
    if since_placed(values, k):  # a switched change begun during the record: said and written so
        term = replace(term, since=float(values[since_name(k)]))
    words = describe_term(term, coef, shape, scale, se, stderr.get(since_name(k)))
    return FoundTerm(term.with_shape(shape), coef, shape, scale, words, twins, se)


def finite_changes(found: Sequence[FoundTerm]) -> list[FoundTerm]:
    """``found`` with each pair of ramps of one parameter (a rise and its end) said as one change — the rise's words
    name the window ("section 1 lost 20 % of its stiffness between t = 2.5 and 7.5 s"), the end's words say it
    held (or kept changing at the rate left) — and each onset's refit range narrowed so that the emitted file's
    ``FitRange`` (a quarter of it either way) is ± :data:`EMITTED_ONSET_S`; so is each onset of two steps of one
    parameter (damage in stages, :mod:`workbench.discover._staged_change`: with the range a quarter of each step's
    slot, 0.94 s, its file refitted to 3.0 σ against the discovery's 1.47 σ); the later of two steps that gives part
    of the earlier one's change back is said as a recovery ("then section 1 regained 15 % of its stiffness at …")."""
    out = list(found)
    for i, a in enumerate(out):
        j = next((j for j in range(i + 1, len(out)) if _pair(a, out[j])), None)
        if j is None:
            continue
        rise, end = (a, out[j]) if a.shape <= out[j].shape else (out[j], a)
        rise_words, end_words = describe_finite_change(
            rise.term.param, rise.term.index, rise.coef, rise.shape, rise.shape_se, end.coef, end.shape,
            end.shape_se, HOLDS_SHARE)
        out[out.index(rise)] = _placed(rise, rise_words)
        out[out.index(end)] = _placed(end, end_words, said_with=rise.term.key)
    for i, a in enumerate(out):  # two steps of one parameter (damage in stages): each onset placed as a pair's
        first = next((b for b in out[:i] + out[i + 1:] if _staged(a, b)), None)
        if first is None:
            continue
        words = a.words
        if a.shape > first.shape and a.coef * first.coef < 0:  # the later step gives part of the change back
            words = describe_recovery(a.term.param, a.term.index, first.coef, a.coef, a.shape, a.shape_se)
        out[i] = _placed(a, words, said_with=a.said_with)
    return out


def _pair(a: FoundTerm, b: FoundTerm) -> bool:
    return (a.term.placement == b.term.placement == "damage" and a.term.form == b.term.form == "on_ramp"
            and (a.term.param, a.term.index) == (b.term.param, b.term.index) and a.coef * b.coef < 0)


def _staged(a: FoundTerm, b: FoundTerm) -> bool:
    return (a.term.placement == b.term.placement == "damage" and a.term.form == b.term.form == "on_step"
            and (a.term.param, a.term.index) == (b.term.param, b.term.index))


def _placed(ft: FoundTerm, words: str, said_with: str = "") -> FoundTerm:
    near = (onset_floor(ft.shape, 2.0 * EMITTED_ONSET_S), ft.shape + 2.0 * EMITTED_ONSET_S)
    return FoundTerm(replace(ft.term, shape_range=near), ft.coef, ft.shape, ft.scale, words, ft.twins, ft.shape_se,
                     said_with)
