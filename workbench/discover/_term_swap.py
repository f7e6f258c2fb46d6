"""One kept term replaced by another dictionary term, refitted with the rest of the set: the shared end of the steps
that try a kept term in another form after the rounds — another gate shape (:mod:`workbench.discover._form_swap`),
a step on one side from its instant (:mod:`workbench.discover._event_side`), every patch's change in one patch
(:mod:`workbench.discover._patch_place`).

:func:`best_replacement` refits each try (the replacing term, its start, any extra free parameter) with every kept
coefficient and the new term's shape free and returns the best by the held-out error; :func:`take_replacement`
takes it when it lowers the held-out error beyond the twins' tolerance, and logs the try either way;
:func:`for_each_kept` is the loop each step runs over the kept set.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from board_config.parameter import Parameter
from workbench.discover._rounds import SearchProgress, SearchSettings, SearchSetup
from workbench.discover._search import free_for, refine
from workbench.discover._twins import twin_tolerance
from workbench.fit import FitOutcome, Objective, explained

#: the steps after the rounds try a kept term in another's place only while the set leaves more than this (σ held
#: out): each costs a batch of probes and a few refits of the whole set, and a set near the noise has its terms
ABOVE_SIGMA = 3.0


def for_each_kept(setup: SearchSetup, progress: SearchProgress, applies: Callable[[int], bool],
                  one: Callable[[int], None], min_kept: int = 1, above: float | None = None) -> None:
    """``one(k)`` for each kept term ``k`` that ``applies``, while the set (of at least ``min_kept`` terms) leaves
    more than :data:`ABOVE_SIGMA` and is not explained — or, given ``above`` (σ), more than that whatever share of
    the excess it removed; the time counted as refits."""
    limit = ABOVE_SIGMA if above is None else above
    if (len(progress.state.kept) < min_kept or progress.current_held <= limit
            or (above is None and explained(progress.current_held, setup.held_before, setup.n_held))):
        return
    t0 = time.perf_counter()
    for k in list(progress.state.kept):
        if progress.current_held > limit and k in progress.state.kept and applies(k):
            one(k)
    progress.timings["refit_s"] += time.perf_counter() - t0


@dataclass(frozen=True)
class Replacement:
    """Dictionary term ``index`` in kept term ``replaced``'s place: the refit's start values and its outcome."""

    replaced: int
    index: int
    start: dict[str, float]
    outcome: FitOutcome


def best_replacement(setup: SearchSetup, progress: SearchProgress, settings: SearchSettings, k: int,
                     tries: Sequence[tuple[int, dict[str, float], Sequence[Parameter]]]) -> Replacement | None:
    """Each try (term j, start values, extra free parameters) in kept term ``k``'s place, refitted with every kept
    coefficient and j's shape; the best by the held-out error (None when none integrates)."""
    best: Replacement | None = None
    for j, start, extra in tries:
        kept = [j if i == k else i for i in progress.state.kept]
        free = [*free_for(setup.terms, setup.names, kept, start, j), *extra]
        robj = Objective(setup.targets, setup.models, free, base_values=start, threads=settings.threads)
        out = refine(robj, start, settings.max_nfev)
        progress.n_sims += robj.n_sims
        if out.ok and (best is None or out.held_rms_sigma < best.outcome.held_rms_sigma):
            best = Replacement(k, j, start, out)
    return best


def take_replacement(setup: SearchSetup, progress: SearchProgress, settings: SearchSettings,
                     found: Replacement | None, log_key: str, words: str,
                     extra: dict[str, float] | None = None) -> bool:
    """Take ``found`` when it lowers the held-out error beyond the twins' tolerance; say and log the try (``words``:
    what was tried, e.g. "in another shape beside the set") under ``log_key`` (with ``extra`` fields). Returns
    whether it was taken."""
    if found is None:
        return False
    k, j, out = found.replaced, found.index, found.outcome
    old, new = setup.terms[k].key, setup.terms[j].key
    taken = out.held_rms_sigma * twin_tolerance(setup.n_held) < progress.current_held
    settings.say(f"  {old} {words}: {new} {out.held_rms_sigma:.4g} σ held-out (the set {progress.current_held:.4g} "
                 "σ): " + ("taken" if taken else "not taken"))
    progress.rounds.append({log_key: {"term": old, "as": new, "held_rms_sigma": out.held_rms_sigma,
                                      "set_held_rms_sigma": progress.current_held, "taken": taken, **(extra or {})}})
    if not taken:
        return False
    state = progress.state
    state.kept = [j if i == k else i for i in state.kept]
    state.values = found.start | out.values
    progress.twins.pop(k, None)
    progress.adopt(out)
    return True
