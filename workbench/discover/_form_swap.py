"""A kept switch in another gate shape, beside the rest of the set (issue 26 point 3).

Each round of ``shm discover`` chooses its new term's gate shape before the later terms are in. A tip crack open
for δ3 > 0 that also rubs while open (its damping more than doubled while open; blind set 7, 15 s sweep) was kept in
round 1 as a loss growing with the opening (190 σ: the sharp switch also left the rubbing's part), round 2 added the
damping switched at δ3 > 0 (73.7 σ held out) and the verdict fell back to re-estimated parameters (63.7 σ). With the
damping in, the sharp switch is the shape that fits.

:func:`swap_step`: after the joint polish, when two or more terms are kept and the set still leaves more than
3 σ, each kept switched term's other gate shapes
(:func:`~workbench.discover._gate_shape.shape_candidates`) are probed over their grids with that term off and the
rest of the set on, and the best :data:`MAX_SWAPS` are refitted with the whole set (every coefficient, the new
term's shape); a swap is taken when it lowers the held-out error beyond the twins' tolerance.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

from workbench.discover._dictionary_code import since_name, since_placed
from workbench.discover._gate_shape import Trial, best_shapes, shape_candidates
from workbench.discover._rounds import SearchProgress, SearchSettings, SearchSetup
from workbench.discover._since_onset import place_instant
from workbench.discover._term_swap import Replacement, best_replacement, for_each_kept, take_replacement

#: at most this many other shapes of one kept term are refitted (the best by their probes)
MAX_SWAPS = 2


def swap_step(setup: SearchSetup, progress: SearchProgress, settings: SearchSettings,
              above: float | None = None) -> bool:
    """Each kept switched term tried in its other gate shapes beside the rest of the set (see the module
    docstring), while the set leaves more than ``above`` σ (:func:`for_each_kept`'s rule when None); the set changes
    only when a swap fits clearly better. Returns whether it changed."""
    before = list(progress.state.kept)
    for_each_kept(setup, progress, lambda k: True, lambda k: _swap_one(setup, progress, settings, k), min_kept=2,
                  above=above)
    return progress.state.kept != before


def placed_swap_step(setup: SearchSetup, progress: SearchProgress, settings: SearchSettings) -> None:
    """The swap again for each kept switch given an instant after it (:mod:`workbench.discover._since_onset`), its
    other shapes begun at that instant, one term kept or more: the round chose its shape over the whole record (own
    check: section 2 cracked at 6.75 s of a sweep and then breathing, kept as a crack opening gradually over ±815 µm,
    placed at 6.69 s, 34 σ; the sharp hinge is the crack)."""
    for_each_kept(setup, progress, lambda k: since_placed(progress.state.values, k),
                  lambda k: _swap_one(setup, progress, settings, k))


def _swap_one(setup: SearchSetup, progress: SearchProgress, settings: SearchSettings, k: int) -> None:
    """Kept term ``k`` replaced by its best other shape when that fits clearly better with the rest of the set."""
    cands = [j for j in shape_candidates(setup.terms, setup.terms[k]) if j not in progress.state.kept]
    replace_by_best(setup, progress, settings, k, cands, "shape_swap", "in another shape beside the set")


def replace_by_best(setup: SearchSetup, progress: SearchProgress, settings: SearchSettings, k: int,
                    cands: list[int], log_key: str, words: str, max_tries: int = MAX_SWAPS,
                    sizes: Callable[[int], Sequence[float]] = lambda _j: (1.0,)) -> tuple[Replacement | None, bool]:
    """Kept term ``k`` replaced by the best of ``cands`` (dictionary indices) when that fits clearly better with the
    rest of the set: each probed over its shapes' grid at ``k``'s size times each of ``sizes(j)`` (:func:`best_shapes`,
    ``k`` off, begun at ``k``'s instant if it has one), the best ``max_tries`` refitted with every kept coefficient;
    the try said and logged as ``words`` under ``log_key``. Returns the best try (None when none integrates) and
    whether ``k`` was replaced by it."""
    state, names = progress.state, setup.names
    cname = names[k][0]
    coef = float(state.values.get(cname, 0.0))
    if not cands or coef == 0.0:
        return None, False
    base = dict(state.values) | {cname: 0.0}
    since = ({since_name(j): state.values[since_name(k)] for j in cands if since_name(j) in state.values}
             if since_placed(state.values, k) else {})  # the other terms begun at the kept switch's instant
    groups: dict[float, list[int]] = {}
    for j in cands:
        for m in sizes(j):
            groups.setdefault(m, []).append(j)
    found: dict[int, tuple[float, Trial]] = {}
    for m, group in groups.items():
        for j, et in best_shapes(setup, progress, settings, group, coef * m, base | since).items():
            if et[0] < found.get(j, (math.inf,))[0]:
                found[j] = et
    tries = [(j, base | {names[j][0]: c} | ({str(names[j][1]): g} if names[j][1] else {})
              | {s: v for s, v in since.items() if s == since_name(j)}, ())
             for _, (j, c, g) in sorted(found.values(), key=lambda et: et[0])[:max_tries]]
    swap = best_replacement(setup, progress, settings, k, tries)
    taken = take_replacement(setup, progress, settings, swap, log_key, words)
    if taken and since and swap is not None:
        place_instant(setup, progress, settings, swap.index)  # the new term's own instant
    return swap, taken
