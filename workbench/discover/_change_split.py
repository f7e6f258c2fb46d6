"""One change in two places at once (issue 26 point 3): an impact at the junction of two sections cracks both at the
same instant; a dropped tool dents two patches. The round keeps the change in one place (the one that explains the
most alone) sized to soak up the other's share: k1 and k2 each losing 7 % at 6.75 s of a 15 s sweep was kept as
"section 2 lost 9.59 % at t = 6.750 s" (24 σ held out), and the next round, probing k1's step with k2's held at
−9.59 %, found nothing near — only "patch 1's authority rose by 4.66 % at the same instant" (3.87 σ), a twin of the
missing loss.

So when the kept change (a step, two steps, a window, an S-curve: every slot of its parameter and place) still leaves
more than the noise, the same change is probed *also* in each other place — the kept place at
:data:`SPLIT_KEEP` of its size, the other at :data:`SPLIT_ADD` of it, same instants and shape — over the whole
record; the best is refitted (both places' sizes free, onsets within
:data:`~workbench.discover._finite_change.ONSET_FREE_S`) and kept when it removes the round's share of the excess
(:func:`split_change`). On a record that cannot tell the places apart (one mode excited) the split explains no more
than the one place and is not kept.

Pure logic on the fit engine's objects; :func:`~workbench.discover._kept_change.refine_kept` calls it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from workbench.discover._change_place import N_PLACES, change_slots, counterpart, placed_free, transplant
from workbench.discover._event_check import is_timed
from workbench.discover._finite_change import lowest, whole_scores
from workbench.discover._results import excess_share_removed
from workbench.discover._search import SearchState, refine
from workbench.fit import FitOutcome, Objective, noise_tolerance

#: the kept change's share left in its place, and the share of its size added in another place
SPLIT_KEEP = (0.5, 0.75, 1.0)
SPLIT_ADD = (0.25, 0.5, 0.75, 1.0)


def split_setting(values: Mapping[str, float], names: Sequence[tuple[str, str | None]], mapping: Mapping[int, int],
                  keep: float, add: float) -> dict[str, float]:
    """The dictionary parameters of the change in two places: each slot's coefficient × ``keep``, its counterpart
    (``mapping``) at ``add`` × it with the slot's onset and fitted width."""
    return transplant(values, names, mapping, add, keep)


@dataclass(frozen=True)
class SplitChange:
    """The change refitted in two places: the added slots, the refit, every dictionary value with it and the
    simulations run."""

    added: tuple[int, ...]
    outcome: FitOutcome
    values: dict[str, float]
    n_sims: int


def split_refit(setup: Any, state: SearchState, slots: Sequence[int], threads: int | None, max_nfev: int
                ) -> SplitChange | None:
    """The change held by ``slots`` also in the other place whose probes (:data:`SPLIT_KEEP` × :data:`SPLIT_ADD`)
    leave the whole record lowest, refitted; None when no other place has free counterparts or nothing
    integrates. ``setup``: the rounds' objects."""
    index = setup.terms[slots[0]].index
    tries: list[tuple[dict[int, int], dict[str, float]]] = []
    for i in range(N_PLACES):
        mapping = {k: counterpart(setup.terms, k, i) for k in slots}
        if i == index or any(k2 is None or k2 in state.kept for k2 in mapping.values()):
            continue
        moves = {k: int(k2) for k, k2 in mapping.items() if k2 is not None}
        tries += [(moves, split_setting(state.values, setup.names, moves, a, b)) for a in SPLIT_KEEP
                  for b in SPLIT_ADD]
    if not tries:
        return None
    found = lowest(tries, whole_scores(setup.targets, setup.models, state.values, [s for _, s in tries], threads))
    n_sims = len(tries) * len(setup.targets)
    if found is None:
        return None
    (moves, setting), _ = found
    start = dict(state.values) | setting
    added = tuple(moves[k] for k in slots)
    others = [k for k in state.kept if k not in slots]
    obj = Objective(setup.targets, setup.models, placed_free(setup.terms, setup.names, others, start,
                                                             [*slots, *added], setup.scales["t"]),
                    base_values=start, threads=threads)
    out = refine(obj, start, max_nfev)
    if not out.ok:
        return None
    return SplitChange(added, out, start | out.values, n_sims + obj.n_sims)


def split_change(setup: Any, progress: Any, settings: Any, min_share: float) -> None:
    """The change the round kept last (``progress.state.kept[-1]``: time-gated, per place) also in another place
    (:func:`split_refit`) when it still leaves more than the noise; kept when the split removes ``min_share`` of
    the excess left. ``setup``, ``progress``, ``settings``: the rounds' objects."""
    state = progress.state
    term = setup.terms[state.kept[-1]]
    tol = noise_tolerance(setup.n_held)
    if term.placement != "damage" or not is_timed(term) or term.index < 0 or progress.current_held <= 1.0 + tol:
        return
    slots = change_slots(setup.terms, state.kept, term)
    split = split_refit(setup, state, slots, settings.threads, settings.max_nfev)
    if split is None:
        return
    progress.n_sims += split.n_sims
    h = split.outcome.held_rms_sigma
    gain = excess_share_removed(progress.current_held, h, tol)
    keep = gain is not None and gain >= min_share and h < progress.current_held
    settings.say(f"  {term.key}'s change also in {setup.terms[split.added[0]].key}'s place ({h:.4g} σ held-out, "
                 f"here {progress.current_held:.4g} σ): " + ("both kept, one change in two places" if keep
                                                             else "not kept"))
    progress.rounds.append({"split_change": {"term": term.key, "also": setup.terms[split.added[0]].key,
                                             "held_rms_sigma": h, "kept": keep}})
    if not keep:
        return
    state.kept.extend(split.added)
    state.values.update(split.values)
    progress.adopt(split.outcome)
