"""The pair step of ``shm discover`` (:func:`pair_step`): after the rounds, when what they kept still leaves more
than the noise, the best *pairs* of the first round's linear screen (:mod:`workbench.discover._pair_screen`) are
refitted together on the full model from the nominal one, and the best replaces the kept set when it fits clearly
better — beyond the twins' tolerance.

Forward selection keeps one term per round; two changes in two places whose averages look like one third thing (two
patches weak in opposite polarities: a lower gain) send it to the third thing first and leave no single term that
removes a clear share of the rest. The pair screen sees them together; the refit on the full model says whether the
records hold them.
"""

from __future__ import annotations

import time

import numpy as np

from workbench.discover._event_check import is_timed
from workbench.discover._pair_screen import PairRow, pair_screen, screen_matrices, single_held
from workbench.discover._rounds import SearchProgress, SearchSettings, SearchSetup
from workbench.discover._search import free_for, refine
from workbench.discover._twins import twin_tolerance
from workbench.fit import FitOutcome, Objective, explained

#: at most this many pairs are refitted (the best of the screen)
N_PAIRS = 3
#: a pair is refitted only when its linearised held-out excess over the noise is at most this share of the best
#: single term's: the pair must explain what no single term does, not add a little to it
PAIR_GAIN = 0.5
#: pairs are tried only for a kept set that leaves more than this (σ held out; the verdicts' own reach of the noise
#: floor, issue 26 point 1): near it, a second place would fit the last of the noise as much as the physics
ABOVE_SIGMA = 1.5


def pair_rows(setup: SearchSetup, progress: SearchProgress) -> list[tuple[int, int, PairRow]]:
    """The first round's best pairs (dictionary indices of both terms, and the screen's row) that explain clearly
    more than any single term (:data:`PAIR_GAIN`); none without a first round."""
    batch = progress.first_batch
    if batch is None:
        return []
    cand = batch.cand
    terms = [setup.terms[k] for k in cand]
    m = screen_matrices(setup.targets, batch.ys, setup.eps[cand])
    usable = np.asarray(batch.ok[1:], bool) & np.array([not is_timed(t) for t in terms])
    places = [(t.placement, t.param, t.index) for t in terms]
    cap = np.array([1.0 if t.placement == "damage" and t.unit == "1" else np.inf for t in terms])
    best_single = float(np.min(single_held(m, usable), initial=np.inf))
    rows = pair_screen(m, places, usable, cap, N_PAIRS)
    return [(cand[r.i], cand[r.j], r) for r in rows if r.held_rms_sigma - 1.0 <= PAIR_GAIN * (best_single - 1.0)]


def refit_pair(setup: SearchSetup, progress: SearchProgress, settings: SearchSettings, ki: int, kj: int,
               row: PairRow) -> tuple[dict[str, float], FitOutcome] | None:
    """The pair refitted together on the full model from the nominal one (the kept terms off), both coefficients and
    shapes free: the start values and the outcome, None when the refit fails."""
    names, terms = setup.names, setup.terms
    start = dict(progress.state.values) | {names[k][0]: 0.0 for k in progress.state.kept}
    start |= {names[ki][0]: row.coef_i, names[kj][0]: row.coef_j}
    free = free_for(terms, names, [ki], start, ki) + free_for(terms, names, [kj], start, kj)
    robj = Objective(setup.targets, setup.models, free, base_values=start, threads=settings.threads)
    out = refine(robj, start, settings.max_nfev)
    progress.n_sims += robj.n_sims
    return (start, out) if out.ok else None


def pair_step(setup: SearchSetup, progress: SearchProgress, settings: SearchSettings) -> None:
    """When the kept set leaves more than the noise, the screen's best pairs (:func:`pair_rows`) refitted; the best
    replaces the kept set when it leaves clearly less held-out error (beyond :func:`twin_tolerance`)."""
    if progress.current_held <= ABOVE_SIGMA or explained(progress.current_held, setup.held_before, setup.n_held):
        return
    t0 = time.perf_counter()
    best: tuple[int, int, dict[str, float], FitOutcome] | None = None
    for ki, kj, row in pair_rows(setup, progress):
        got = refit_pair(setup, progress, settings, ki, kj, row)
        key = f"{setup.terms[ki].key} + {setup.terms[kj].key}"
        if got is None:
            continue
        settings.say(f"pair step: {key} (screened {row.held_rms_sigma:.3g} σ) refitted together: held-out "
                     f"{got[1].held_rms_sigma:.4g} σ")
        if best is None or got[1].held_rms_sigma < best[3].held_rms_sigma:
            best = (ki, kj, *got)
    progress.timings["refit_s"] += time.perf_counter() - t0
    if best is None or best[3].held_rms_sigma * twin_tolerance(setup.n_held) >= progress.current_held:
        return
    ki, kj, start, out = best
    settings.say(f"pair step: {setup.terms[ki].key} and {setup.terms[kj].key} together leave "
                 f"{out.held_rms_sigma:.4g} σ held-out, the kept set {progress.current_held:.4g} σ: they replace it")
    progress.rounds.append({"pair": {"terms": [setup.terms[ki].key, setup.terms[kj].key],
                                     "held_rms_sigma": out.held_rms_sigma,
                                     "set_held_rms_sigma": progress.current_held}})
    state = progress.state
    state.kept = [ki, kj]
    state.values = start | out.values
    progress.twins = {}
    progress.adopt(out)
