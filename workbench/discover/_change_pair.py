"""Two losses in two places at two instants (issue 26 point 3): an overload cracks the root; the load it sheds
cracks the tip seconds later. A step the round kept far from the noise is probed as *two* steps — the kept one moved
to any place at its instant, a second one in another place at its own instant (:func:`pair_refit`) — and kept when
that removes the round's share of the excess (:func:`pair_change`).

Why it is needed: the root losing 6 % at 3.75 s and the tip 6 % at 9 s of a 15 s sweep. The round's event was the
tip's step at the first instant (46.7 σ: the tip's loss dominates the record, and a tip step from 3.75 s covers it
after 9 s); the root's step alone at that instant leaves more than 140 σ, so the place moves (the same change in
another place, instant held) never try it, and the split (the same change in two places at once) added section 2 at
the same instant (14.8 σ). Probing the place pairs over a grid of second instants finds the pair the records hold.

Pure logic on the fit engine's objects; :func:`~workbench.discover._kept_change.refine_kept` calls it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

from workbench.discover._change_place import N_PLACES, counterpart, placed_free
from workbench.discover._dictionary import Term
from workbench.discover._finite_change import whole_scores
from workbench.discover._onset_profile import placed_on_whole
from workbench.discover._results import excess_share_removed
from workbench.discover._search import SearchState, refine
from workbench.discover._staged_change import STAGES_APART_S
from workbench.fit import FitOutcome, Objective, noise_tolerance

#: second instants probed, evenly over the record, and the second step's size as shares of the kept one's
PAIR_INSTANTS = 10
PAIR_ADD = (0.5, 1.0)
#: the best probes (distinct pairs of places, either order) whose second instant is placed on the whole record, each
#: scored again with its places swapped: the grid's instants miss the record's (9 s of a 15 s sweep lies between two),
#: so the grid's best may hold the places the wrong way round — section 3 at 3.75 s and section 1 at 9 s refitted to
#: 3.81 σ where the records hold section 1 first
PAIR_PLACED = 3
#: the placed pairs (either order) refitted, lowest whole-record RMS first; the one the held-out blocks prefer kept —
#: before the refit the sizes are the grid's (the second a half or the whole of the first), and the pair the records
#: hold scored 53.9 σ where the swapped one scored 31.8 σ and refitted to 3.81 σ
PAIR_REFITS = 3
#: a kept step is probed as a pair only while the round leaves more than this (σ held out): near the noise the place
#: moves and the split already decide
PAIR_ABOVE_SIGMA = 3.0


def free_step(terms: Sequence[Term], like: Term, index: int, taken: Sequence[int]) -> int | None:
    """The first step slot of ``like``'s parameter at ``index`` (section, mass, patch) not in ``taken``."""
    return next((k for k, t in enumerate(terms) if t.placement == "damage" and t.form == "on_step"
                 and (t.param, t.index) == (like.param, index) and k not in taken), None)


def pair_tries(terms: Sequence[Term], names: Sequence[tuple[str, str | None]], values: Mapping[str, float],
               kept: Sequence[int], slot: int, t_end: float) -> list[tuple[tuple[int, int], dict[str, float]]]:
    """The pairs probed for the kept step ``slot``: its change (size and instant) in place a (its own or another
    free one), a second step in another place b at each of :data:`PAIR_INSTANTS` instants over the record (none
    within :data:`~workbench.discover._staged_change.STAGES_APART_S` of the first) sized :data:`PAIR_ADD` × it.
    Each: ((slot a, slot b), the dictionary parameters)."""
    term = terms[slot]
    cname, gname = names[slot]
    c, t1 = float(values[cname]), float(values[str(gname)])
    out: list[tuple[tuple[int, int], dict[str, float]]] = []
    for a in range(N_PLACES):
        ka = slot if a == term.index else counterpart(terms, slot, a)
        if ka is None or (ka != slot and ka in kept):
            continue
        first = {cname: 0.0} | {names[ka][0]: c, str(names[ka][1]): t1}
        for b in range(N_PLACES):
            kb = None if b == a else free_step(terms, term, b, [*kept, slot, ka])
            if kb is None:
                continue
            for i in range(1, PAIR_INSTANTS + 1):
                t2 = t_end * i / (PAIR_INSTANTS + 1)
                if abs(t2 - t1) >= STAGES_APART_S:
                    out += [((ka, kb), first | {names[kb][0]: add * c, str(names[kb][1]): t2}) for add in PAIR_ADD]
    return out


@dataclass(frozen=True)
class PairChange:
    """The kept step refitted as two steps in two places: their slots (the kept change's place first), the refit,
    every dictionary value with it and the simulations run."""

    slots: tuple[int, int]
    outcome: FitOutcome
    values: dict[str, float]
    n_sims: int


def best_distinct(tries: Sequence[tuple[tuple[int, int], dict[str, float]]], scores: Sequence[float],
                  n: int) -> list[tuple[tuple[tuple[int, int], dict[str, float]], float]]:
    """The ``n`` lowest finite ``scores`` of ``tries``, one per pair of places in either order (the swap is scored
    after placing, :func:`swapped`), lowest first."""
    seen: set[frozenset[int]] = set()
    out: list[tuple[tuple[tuple[int, int], dict[str, float]], float]] = []
    for i in sorted(range(len(tries)), key=lambda j: scores[j]):
        key = frozenset(tries[i][0])
        if not math.isfinite(scores[i]) or len(out) == n:
            break
        if key not in seen:
            seen.add(key)
            out.append((tries[i], scores[i]))
    return out


def swapped(names: Sequence[tuple[str, str | None]], slots: tuple[int, int],
            values: Mapping[str, float]) -> tuple[tuple[int, int], dict[str, float]]:
    """The pair ``slots`` with its places swapped: each slot takes the other's size and instant. Returns the slots
    in their new order (the first instant's first) and the values changed."""
    (ca, ga), (cb, gb) = (names[k] for k in slots)
    return (slots[1], slots[0]), {ca: values[cb], str(ga): values[str(gb)], cb: values[ca], str(gb): values[str(ga)]}


def _placed(setup: Any, state: SearchState, found: Sequence[tuple[tuple[tuple[int, int], dict[str, float]], float]],
            threads: int | None) -> tuple[list[tuple[tuple[int, int], dict[str, float], float]], int]:
    """Each of ``found`` with its second instant placed on the whole record, and the same with its places swapped
    (scored over the whole record): (slots, values, whole RMS σ) and the simulations run."""
    out: list[tuple[tuple[int, int], dict[str, float], float]] = []
    n = 0
    for ((ka, kb), setting), score in found:
        start = dict(state.values) | setting
        gname = str(setup.names[kb][1])
        start[gname], score, m = placed_on_whole(setup.targets, setup.models, start, gname, score, threads)
        out.append(((ka, kb), start, score))
        n += m
    swaps = [swapped(setup.names, slots, start) for slots, start, _ in out]
    scores = whole_scores(setup.targets, setup.models, state.values,
                          [start | change for (_, start, _), (_, change) in zip(out, swaps)], threads)
    n += len(swaps) * len(setup.targets)
    out += [(slots, start | change, e) for (_, start, _), (slots, change), e in zip(out, swaps, scores)]
    return out, n


def pair_refit(setup: Any, state: SearchState, slot: int, threads: int | None, max_nfev: int) -> PairChange | None:
    """The kept step ``slot`` as a pair of :func:`pair_tries`: the best :data:`PAIR_PLACED` pairs of places by the
    whole record's RMS have their second instant placed on the whole record and are scored with their places
    swapped too (:func:`_placed`); those of :func:`refit_order` are refitted (both sizes, onsets within
    :data:`~workbench.discover._finite_change.ONSET_FREE_S`) and the refit the held-out blocks prefer is returned;
    None when no pair is possible or nothing integrates. ``setup``: the rounds' objects."""
    tries = pair_tries(setup.terms, setup.names, state.values, state.kept, slot, setup.scales["t"])
    if not tries:
        return None
    scores = whole_scores(setup.targets, setup.models, state.values, [s for _, s in tries], threads)
    n_sims = len(tries) * len(setup.targets)
    found = best_distinct(tries, scores, PAIR_PLACED)
    if not found:
        return None
    placed, m = _placed(setup, state, found, threads)
    best: PairChange | None = None
    for slots, start in refit_order(placed, len(found)):
        change = _pair_refit_one(setup, state, slot, slots, start, threads, max_nfev)
        m += change.n_sims
        if change.outcome.ok and (best is None or change.outcome.held_rms_sigma < best.outcome.held_rms_sigma):
            best = change
    return None if best is None else replace(best, n_sims=n_sims + m)


def refit_order(placed: Sequence[tuple[tuple[int, int], dict[str, float], float]], n_found: int
                ) -> list[tuple[tuple[int, int], dict[str, float]]]:
    """The pairs refitted: the :data:`PAIR_REFITS` lowest of ``placed`` (its first ``n_found`` as placed, the rest
    the same swapped, :func:`_placed`) and the best one swapped whatever its score — the grid's sizes may suit the
    order found, not the swap."""
    order = sorted(range(len(placed)), key=lambda i: placed[i][2])
    keep = order[:PAIR_REFITS]
    swap_of_best = order[0] + n_found if order[0] < n_found else order[0] - n_found
    keep += [swap_of_best] if swap_of_best not in keep else []
    return [(placed[i][0], placed[i][1]) for i in keep]


def _pair_refit_one(setup: Any, state: SearchState, slot: int, slots: tuple[int, int], start: dict[str, float],
                    threads: int | None, max_nfev: int) -> PairChange:
    """The pair ``slots`` refitted from ``start``: both sizes, onsets within
    :data:`~workbench.discover._finite_change.ONSET_FREE_S`, every other kept term; ``slot`` (the kept step) left
    out."""
    others = [k for k in state.kept if k != slot]
    obj = Objective(setup.targets, setup.models, placed_free(setup.terms, setup.names, others, start, list(slots),
                                                             setup.scales["t"]),
                    base_values=start, threads=threads)
    out = refine(obj, start, max_nfev)
    return PairChange(slots, out, start | out.values, obj.n_sims)


def pair_change(setup: Any, progress: Any, settings: Any, min_share: float) -> None:
    """The step the round kept last probed as two steps in two places at two instants (:func:`pair_refit`) while
    the round leaves more than :data:`PAIR_ABOVE_SIGMA`; kept in its place when it removes ``min_share`` of the
    excess left. ``setup``, ``progress``, ``settings``: the rounds' objects."""
    state = progress.state
    slot = state.kept[-1]
    term = setup.terms[slot]
    if term.placement != "damage" or term.form != "on_step" or term.index < 0 \
            or progress.current_held <= PAIR_ABOVE_SIGMA:
        return
    pair = pair_refit(setup, state, slot, settings.threads, settings.max_nfev)
    if pair is None:
        return
    progress.n_sims += pair.n_sims
    h = pair.outcome.held_rms_sigma
    gain = excess_share_removed(progress.current_held, h, noise_tolerance(setup.n_held))
    keep = gain is not None and gain >= min_share and h < progress.current_held
    a, b = (setup.terms[k].key for k in pair.slots)
    settings.say(f"  {term.key} as two steps in two places, {a} and {b} at its own instant ({h:.4g} σ held-out, "
                 f"here {progress.current_held:.4g} σ): " + ("kept" if keep else "not kept"))
    progress.rounds.append({"pair_change": {"term": term.key, "as": [a, b], "held_rms_sigma": h, "kept": keep}})
    if not keep:
        return
    state.kept = [k for k in state.kept if k != slot] + list(pair.slots)
    progress.twins.pop(slot, None)  # the single step's twins are no twins of the pair
    state.values.update(pair.values | ({setup.names[slot][0]: 0.0} if slot not in pair.slots else {}))
    progress.adopt(pair.outcome)
