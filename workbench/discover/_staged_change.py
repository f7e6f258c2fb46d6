"""Damage in stages (issue 26 point 3): two steps of one parameter — a crack that runs, arrests at a ply interface
and runs again; a bolt that slips twice. A kept step or ramp that leaves more than the noise is also tried as two
steps of its parameter (:func:`staged_refit`), beside the change that grows over a finite time
(:mod:`workbench.discover._finite_change`), and the better of the two replaces it (:func:`change_refit`).

Why it is needed: section 2 losing 10 % of its stiffness at 4.5 s and 10 % more at 12 s of a 15 s sweep was kept as
a ramp from 2.78 s (67 σ held out): the ramp smears both steps, and the step of k2 refitted alone at 4.49 s (73.6 σ)
sized itself to absorb part of the second loss, so it missed the record between the two instants too (68 σ RMS);
no later round could then place the second step. Probing pairs of steps on the full model — the first at an onset
the round found, the second on a grid after it, the loss split between them — then zooming and refitting both
places them.

A third step (:func:`third_stage`): a crack that advances by pop-in — it arrests at each tougher ply and jumps on —
loses a section's stiffness in a staircase. Section 3 losing 2 % of its stiffness at 3.75 s, 6.75 s and 9.75 s of a
15 s sweep was kept as "lost 6 % between t = 0.00 s and 10.34 s, faster and faster" (1.55 σ held out): the step
found the first jump (3.758 s, 8.3 σ), two steps reached 2.62 σ, and no shape of one or two pieces follows three
jumps — the first sentence gave the damage's start as the record's. Two steps that still leave more than the noise
are given a third step of their parameter, probed on the full model at instants evenly over the record (equal thirds
of the total, or a share split off its nearest step), its instant placed on the whole record, the sizes refitted and
every onset placed; :func:`change_refit` keeps it when it leaves the whole record lowest.

Pure logic on the fit engine's objects; the rounds (:mod:`workbench.discover._rounds`) keep the result.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

from board_config.parameter import Parameter, freed
from plant import PlantModel
from workbench.discover._dictionary import Term
from workbench.discover._event_check import damage_kinds, damage_like, static_twin
from workbench.discover._finite_change import (
    ONSET_FREE_S,
    Window,
    WindowFit,
    WindowProbe,
    gate_slots,
    lowest,
    others_free,
    whole_rms,
    whole_scores,
    window_refit,
    zoom_window,
)
from workbench.discover._gates import onset_floor
from workbench.discover._onset import MAX_LOSS
from workbench.discover._onset_profile import HELD_ONSET_S, placed_on_whole
from workbench.discover._search import SearchState, refine
from workbench.discover._simplex_place import placed_together
from workbench.discover._smooth_change import VARIANTS, smooth_refit
from workbench.discover._twins import twin_tolerance
from workbench.fit import Objective, Target

#: second instants probed after each first one (evenly over the time left) — and first instants before it (evenly
#: over the time before: the kept step may sit at the later, larger change) — and the share of the total change the
#: first step takes: below 1 both steps go one way (a crack that runs twice), above 1 the second step gives part of
#: the first back (a partial recovery: the root losing 25 % at 6 s of a 20 s MBIT.a, 15 % of it back at 13 s, was
#: kept as one step and then as a window of 30.8 % from 6.0 s to 6.1 s, 35.6 σ held out; two steps one way: 74.9 σ)
STAGE_SECONDS = 10
STAGE_SHARES = (0.3, 0.5, 0.7, 1.5, 2.5)
#: rounds of the two steps' onsets placed on the whole record and their sizes refitted (:func:`stages_placed`)
PLACE_CYCLES = 3
#: a kept change moving its parameter the way damage does not is also refitted as this many of its kinds
MAX_KINDS = 1


def step_slots(terms: Sequence[Term], term: Term) -> list[int]:
    """The dictionary indices of the steps of ``term``'s parameter (same core parameter and section/mass), the
    ``term``'s own first when it is one."""
    return gate_slots(terms, term, "on_step")


def stage_setting(window: Window, share: float, first: tuple[str, str | None],
                  second: tuple[str, str | None]) -> dict[str, float]:
    """Two steps: ``share`` of ``window.total`` at ``window.start``, the rest at ``window.end`` (the steps'
    (coefficient, onset) names)."""
    return {first[0]: share * window.total, str(first[1]): window.start,
            second[0]: (1.0 - share) * window.total, str(second[1]): window.end}


@dataclass(frozen=True)
class StageProbe(WindowProbe):
    """A :class:`~workbench.discover._finite_change.WindowProbe` whose window is two steps (``share`` first)."""

    share: float = 0.5

    def setting(self, window: Window) -> dict[str, float]:
        return stage_setting(window, self.share, self.rise, self.end)


def candidate_stages(firsts: Sequence[float], total: float, t_end: float, kept_at: float | None = None
                     ) -> list[Window]:
    """Pairs of instants: each of ``firsts`` (s) with :data:`STAGE_SECONDS` second instants evenly after it, and
    (``kept_at``: the kept change's instant, s) :data:`STAGE_SECONDS` first instants evenly before that one."""
    after = [Window(a, a + (t_end - a) * i / (STAGE_SECONDS + 1), total) for a in firsts if a < t_end
             for i in range(1, STAGE_SECONDS + 1)]
    if kept_at is None or kept_at <= 0.0:
        return after
    return after + [Window(kept_at * i / (STAGE_SECONDS + 1), kept_at, total) for i in range(1, STAGE_SECONDS + 1)]


def stage_free(terms: Sequence[Term], names: Sequence[tuple[str, str | None]], state: SearchState,
               start: dict[str, float], pair: Sequence[int], replaced: int, t_end: float,
               onset_half: float = ONSET_FREE_S) -> list[Parameter]:
    """Free parameters of the steps' refit (two, or three: :func:`third_stage`): the other kept
    terms' coefficients (±1.5 × their size), every step's size (within ±2 × the largest, a loss never past
    :data:`~workbench.discover._onset.MAX_LOSS`) and onset (± ``onset_half``, s)."""
    out = others_free(terms, names, state, start, pair, replaced)
    size = max(abs(start[names[k][0]]) for k in pair)
    for k in pair:
        cname, gname = names[k]
        c, g = start[cname], start[str(gname)]
        out.append(freed(cname, terms[k].unit, max(c - 2.0 * size, MAX_LOSS), c + 2.0 * size, False, "discover"))
        out.append(freed(str(gname), "s", onset_floor(g, onset_half), min(g + onset_half, t_end), False,
                         "discover"))
    return out


def staged_refit(targets: Sequence[Target], models: Sequence[PlantModel], terms: Sequence[Term],
                 names: Sequence[tuple[str, str | None]], state: SearchState, kept: int, firsts: Sequence[float],
                 t_end: float, threads: int | None, max_nfev: int, like: int | None = None) -> WindowFit | None:
    """The kept time-gated term ``kept`` as two steps of its parameter: pairs of instants (the first at the kept
    term's onset or one of ``firsts``, s) probed at :data:`STAGE_SHARES` of its total change, the best zoomed and
    refitted (None when its parameter has fewer than two steps or nothing integrates). ``like``: two steps of that
    term's parameter instead (the kept change's kind), from the kept total's static twin."""
    term = terms[kept if like is None else like]
    slots = [k for k in step_slots(terms, term) if k == kept or k not in state.kept]
    if len(slots) < 2:
        return None
    pair = (slots[0], slots[1])
    cname, gname = names[kept]
    coef, t0 = float(state.values[cname]), float(state.values[str(gname)])
    total = coef * (t_end - t0) if terms[kept].form == "on_ramp" else coef
    total = total if like is None else static_twin(total)
    windows = candidate_stages(sorted({t0, *firsts}), total, t_end, t0)
    base = dict(state.values) | {cname: 0.0}
    best: tuple[StageProbe, float, Window] | None = None
    n = 0
    for share in STAGE_SHARES:
        probe = StageProbe(targets, models, base, names[pair[0]], names[pair[1]], t_end, threads, share)
        scores = probe.scores(windows)
        n += len(windows)
        k = min(range(len(windows)), key=lambda i: scores[i], default=None)
        if k is not None and math.isfinite(scores[k]) and (best is None or scores[k] < best[1]):
            best = (probe, scores[k], windows[k])
    if best is None:
        return None
    zoomed = zoom_window(best[0], [best[2]])
    if zoomed is None:
        return None
    window, _, nz = zoomed
    start = base | stage_setting(window, best[0].share, best[0].rise, best[0].end)
    obj = Objective(targets, models, stage_free(terms, names, state, start, pair, kept, t_end), base_values=start,
                    threads=threads)
    out = refine(obj, start, max_nfev)
    n_sims = (n + nz) * len(targets) + obj.n_sims
    if not out.ok:
        return None
    fit = WindowFit(pair[0], pair[1], kept, out, start | out.values, n_sims, kind="stages")
    return stages_placed(targets, models, terms, names, state, fit, t_end, threads, max_nfev)


#: two steps whose onsets were placed in turn and still leave more than this whole-record RMS (σ) are moved
#: together (:func:`_stages_together`); steps that the move brings closer than STAGES_APART_S (s) are one step
#: split in two, not kept (a 15 % loss of k2 at 11.0 s of MBIT.a was said "section 2 lost 4.66 % … at t = 11.000 s;
#: and section 2 lost 10.3 % … at t = 11.000 s")
TOGETHER_ABOVE_SIGMA = 1.5
STAGES_APART_S = 0.01


def stages_placed(targets: Sequence[Target], models: Sequence[PlantModel], terms: Sequence[Term],
                  names: Sequence[tuple[str, str | None]], state: SearchState, fit: WindowFit, t_end: float,
                  threads: int | None, max_nfev: int) -> WindowFit:
    """The two steps' refit ``fit`` with each onset placed on the whole record in turn
    (:func:`~workbench.discover._onset_profile.placed_on_whole`) and refitted with them held (±
    :data:`~workbench.discover._onset_profile.HELD_ONSET_S`), up to :data:`PLACE_CYCLES` times while the whole
    record prefers that. The refit on the training blocks is blind to an onset inside a held-out block: the root
    losing 25 % at 6 s of a 20 s MBIT.a, 15 % of it back at 13.0 s, had its second step refitted to 12.941 s —
    12.6 σ held out; placed, 1.03 σ. Sizes and onsets trade on a sweep (a step placed late is sized larger): on the
    15 s sweep (25 % at 4.5 s, 15 % back at 9.75 s) one placement left 22.3 % at 4.440 s and 12.2 % at 9.893 s —
    so what still leaves more than the noise is then moved all at once (:func:`_stages_together`)."""
    pair = fit.slots
    onsets = [str(names[k][1]) for k in pair]
    n = 0
    for _ in range(PLACE_CYCLES):
        values, score = dict(fit.values), whole_rms(targets, fit.outcome)
        for gname in onsets:
            values[gname], score, m = placed_on_whole(targets, models, values, gname, score, threads)
            n += m
        if all(values[g] == fit.values[g] for g in onsets):
            break
        obj = Objective(targets, models, stage_free(terms, names, state, values, pair, fit.replaced, t_end,
                                                    HELD_ONSET_S), base_values=values, threads=threads)
        again = refine(obj, values, max_nfev)
        n += obj.n_sims
        if not (again.ok and whole_rms(targets, again) < whole_rms(targets, fit.outcome)):
            break
        fit = replace(fit, outcome=again, values=values | again.values)
    fit, m = _stages_together(targets, models, terms, names, state, fit, t_end, threads, max_nfev)
    return replace(fit, n_sims=fit.n_sims + n + m)


def _stages_together(targets: Sequence[Target], models: Sequence[PlantModel], terms: Sequence[Term],
                     names: Sequence[tuple[str, str | None]], state: SearchState, fit: WindowFit, t_end: float,
                     threads: int | None, max_nfev: int) -> tuple[WindowFit, int]:
    """The two steps' onsets and sizes moved together on the whole record
    (:func:`~workbench.discover._simplex_place.placed_together`) when it still leaves more than
    :data:`TOGETHER_ABOVE_SIGMA`, then the sizes refitted with the onsets held; kept when the whole record prefers
    it and the steps stay :data:`STAGES_APART_S` apart. Returns the fit and the simulations run."""
    score = whole_rms(targets, fit.outcome)
    if score <= TOGETHER_ABOVE_SIGMA:
        return fit, 0
    pair = fit.slots
    onsets, sizes = [str(names[k][1]) for k in pair], [names[k][0] for k in pair]
    values, moved, n = placed_together(targets, models, dict(fit.values), onsets, sizes, (0.0, t_end), threads)
    if moved >= score or min_gap([values[g] for g in onsets]) < STAGES_APART_S:
        return fit, n
    obj = Objective(targets, models, stage_free(terms, names, state, values, pair, fit.replaced, t_end,
                                                HELD_ONSET_S), base_values=values, threads=threads)
    again = refine(obj, values, max_nfev)
    if again.ok and whole_rms(targets, again) < score:
        fit = replace(fit, outcome=again, values=values | again.values)
    return fit, n + obj.n_sims


def min_gap(instants: Sequence[float]) -> float:
    """The shortest time (s) between two of ``instants``."""
    ordered = sorted(instants)
    return min((b - a for a, b in itertools.pairwise(ordered)), default=math.inf)


#: instants probed for the third step, evenly over the record (15 on a 15 s record: one a second)
THIRD_INSTANTS = 15
#: three steps two of which end up closer than this share of the record are one step split in two, not three
#: steps: MBIT.b's root losing 6 % at 0.75 s and the tip 6 % at 1.8 s (3 s) was kept as section 1 losing 6.01 % at
#: 0.750 s, 2.69 % at 1.794 s and 2.67 % at 1.811 s (1.155 σ) — the pair at 1.8 s copying the tip's loss with the
#: root's stiffness — where two steps (1.728 σ) have their second moved to section 3 (:mod:`._change_place`)
THIRD_APART_SHARE = 0.02
#: shares of its nearest step the third one takes (the nearest keeps the rest), beside equal thirds of the total
THIRD_SHARES = (0.3, 0.5)


def third_settings(steps: Sequence[tuple[float, float, tuple[str, str | None]]], third: tuple[str, str | None],
                   t_end: float) -> list[dict[str, float]]:
    """The settings probed for a third step (``third``: its (coefficient, onset) names) beside ``steps`` — each
    (onset s, size, its names): at :data:`THIRD_INSTANTS` instants evenly inside the record (none within
    :data:`STAGES_APART_S` of a step), the total split in equal thirds, and
    :data:`THIRD_SHARES` of the nearest step moved to the new instant."""
    total = sum(size for _, size, _ in steps)
    out: list[dict[str, float]] = []
    for i in range(1, THIRD_INSTANTS + 1):
        at = t_end * i / (THIRD_INSTANTS + 1)
        if min(abs(at - onset) for onset, _, _ in steps) < STAGES_APART_S:
            continue
        equal = {names[0]: total / 3.0 for _, _, names in steps}
        out.append(equal | {third[0]: total / 3.0, str(third[1]): at})
        _, size, names = min(steps, key=lambda s: abs(at - s[0]))
        out += [{names[0]: (1.0 - share) * size, third[0]: share * size, str(third[1]): at} for share in THIRD_SHARES]
    return out


def third_stage(targets: Sequence[Target], models: Sequence[PlantModel], terms: Sequence[Term],
                names: Sequence[tuple[str, str | None]], state: SearchState, fit: WindowFit, t_end: float,
                threads: int | None, max_nfev: int) -> WindowFit | None:
    """The two steps ``fit`` given a third step of their parameter when they leave more than
    :data:`TOGETHER_ABOVE_SIGMA` over the whole record: the settings of
    :func:`third_settings` probed on the full model, the best one's instant placed on the whole record, the sizes
    refitted and every onset placed. None when the two steps explain the records, their parameter has no third
    step free, nothing integrates or two of the three end up closer than :data:`THIRD_APART_SHARE` of the
    record."""
    if fit.kind != "stages" or fit.extra or whole_rms(targets, fit.outcome) <= TOGETHER_ABOVE_SIGMA:
        return None
    free = [k for k in step_slots(terms, terms[fit.rise]) if k not in fit.slots and k not in state.kept]
    if not free:
        return None
    third = free[0]
    values = dict(fit.values)
    steps = [(float(values[str(names[k][1])]), float(values[names[k][0]]), names[k]) for k in fit.slots]
    settings = third_settings(steps, names[third], t_end)
    found = lowest(settings, whole_scores(targets, models, values, settings, threads))
    if found is None:
        return None
    start = values | found[0]
    gname = str(names[third][1])
    start[gname], _, m = placed_on_whole(targets, models, start, gname, found[1], threads)
    slots = (*fit.slots, third)
    obj = Objective(targets, models, stage_free(terms, names, state, start, slots, fit.replaced, t_end),
                    base_values=start, threads=threads)
    out = refine(obj, start, max_nfev)
    if not out.ok:
        return None
    n_sims = len(settings) * len(targets) + m + obj.n_sims
    three = WindowFit(fit.rise, fit.end, fit.replaced, out, start | out.values, n_sims, kind="stages3",
                      extra=(third,))
    three = stages_placed(targets, models, terms, names, state, three, t_end, threads, max_nfev)
    if min_gap([three.values[str(names[k][1])] for k in three.slots]) < THIRD_APART_SHARE * t_end:
        return None
    first, second, last = sorted(three.slots, key=lambda k: three.values[str(names[k][1])])
    return replace(three, rise=first, end=second, extra=(last,))  # in time order: said so


def change_refit(setup: Any, progress: Any, settings: Any, kept: int, done: Sequence[WindowFit] = ()
                 ) -> WindowFit | None:
    """The kept time-gated term ``kept`` given an end (a window), as two steps and as a change with a fitted time
    scale (:mod:`workbench.discover._smooth_change`: an S-curve, a ramp that settles, a step that partly recovers);
    the refit that leaves the whole record lower (None when none is possible; ``done``: the shapes the event's
    judgement refitted already, not refitted again). The first step's candidate instants: the kept term's onset and
    the onsets of this round's refitted steps of the same parameter. ``setup``, ``progress``, ``settings``: the
    rounds' objects."""
    own = _change_refits(setup, progress, settings, kept, None, done)
    term = setup.terms[kept]
    if own is None or damage_like(term, float(progress.state.values[setup.names[kept][0]])):
        return own
    kinds = damage_kinds(setup, progress, kept)[:MAX_KINDS]
    for like in kinds:  # the change said as the damage it may be: a stiffness lost, not an authority gained
        alt = _change_refits(setup, progress, settings, kept, like)
        if alt is not None and whole_rms(setup.targets, alt.outcome) <= whole_rms(setup.targets, own.outcome) \
                * twin_tolerance(setup.n_held):
            settings.say(f"  {term.key} moves its parameter the way damage does not; as a change of "
                         f"{setup.terms[like].key}'s parameter it explains the records alike or better: said so")
            return alt
    return own


def _change_refits(setup: Any, progress: Any, settings: Any, kept: int, like: int | None,
                   done: Sequence[WindowFit] = ()) -> WindowFit | None:
    """:func:`change_refit`'s window, two steps and fitted time scales of the kept term's parameter (``like``: the
    window, two steps, S-curve, settling and accelerating change of that term's)."""
    term = setup.terms[kept if like is None else like]
    firsts = [float(b.outcome.values[setup.names[b.index][1]]) for b in progress.refits
              if setup.terms[b.index].form == "on_step" and (setup.terms[b.index].param, setup.terms[b.index].index)
              == (term.param, term.index) and setup.names[b.index][1] in b.outcome.values]
    args = (setup.targets, setup.models, setup.terms, setup.names, progress.state, kept)
    t_end, threads, nfev = setup.scales["t"], settings.threads, settings.max_nfev
    fits: list[WindowFit | None] = list(done) if like is None else []
    done_kinds = {f.kind for f in fits if f is not None}
    if "window" not in done_kinds:
        fits.append(window_refit(*args, t_end, threads, nfev, like))
    if "stages" not in done_kinds:
        fits.append(staged_refit(*args, firsts, t_end, threads, nfev, like))
    fits += [smooth_refit(*args, t_end, threads, nfev, variant, like) for variant in VARIANTS
             if variant not in done_kinds and (like is None or variant != "recover")]
    two = [f for f in fits if f is not None and f.kind == "stages"]
    fits += [third_stage(setup.targets, setup.models, setup.terms, setup.names, progress.state, f, t_end, threads,
                         nfev) for f in two[:1]]
    made = [f for f in fits if f is not None]
    progress.n_sims += sum(f.n_sims for f in made if all(f is not g for g in done))
    for f in made:
        settings.say(f"  {setup.terms[kept].key} as {KIND_WORDS[f.kind]}: {f.outcome.held_rms_sigma:.4g} σ held-out")
    return min(made, key=lambda f: whole_rms(setup.targets, f.outcome), default=None)


KIND_WORDS = {"window": "a change over a finite time (two ramps)", "stages": "two steps", "stages3": "three steps",
               "smooth": "a step with a fitted edge (an S-curve)", "settle": "a ramp that settles",
               "recover": "a step, then a settling change (a partial recovery)",
               "accelerate": "a change that accelerates, then holds"}
