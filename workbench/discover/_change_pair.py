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

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from workbench.discover._change_place import N_PLACES, counterpart, placed_free
from workbench.discover._dictionary import Term
from workbench.discover._finite_change import lowest, whole_scores
from workbench.discover._onset_profile import placed_on_whole
from workbench.discover._results import excess_share_removed
from workbench.discover._search import SearchState, refine
from workbench.discover._staged_change import STAGES_APART_S
from workbench.fit import FitOutcome, Objective, noise_tolerance

#: second instants probed, evenly over the record, and the second step's size as shares of the kept one's
PAIR_INSTANTS = 10
PAIR_ADD = (0.5, 1.0)
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


def pair_refit(setup: Any, state: SearchState, slot: int, threads: int | None, max_nfev: int) -> PairChange | None:
    """The kept step ``slot`` as the pair of :func:`pair_tries` that leaves the whole record lowest, its second
    instant placed on the whole record, both sizes refitted (onsets within
    :data:`~workbench.discover._finite_change.ONSET_FREE_S`); None when no pair is possible or nothing integrates.
    ``setup``: the rounds' objects."""
    tries = pair_tries(setup.terms, setup.names, state.values, state.kept, slot, setup.scales["t"])
    if not tries:
        return None
    found = lowest(tries, whole_scores(setup.targets, setup.models, state.values, [s for _, s in tries], threads))
    n_sims = len(tries) * len(setup.targets)
    if found is None:
        return None
    ((ka, kb), setting), score = found
    start = dict(state.values) | setting
    gname = str(setup.names[kb][1])
    start[gname], _, m = placed_on_whole(setup.targets, setup.models, start, gname, score, threads)
    others = [k for k in state.kept if k != slot]
    obj = Objective(setup.targets, setup.models, placed_free(setup.terms, setup.names, others, start, [ka, kb],
                                                             setup.scales["t"]),
                    base_values=start, threads=threads)
    out = refine(obj, start, max_nfev)
    if not out.ok:
        return None
    return PairChange((ka, kb), out, start | out.values, n_sims + m + obj.n_sims)


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
    progress.stderr.update({e.name: e.stderr for e in pair.outcome.estimates})
    progress.current_train, progress.current_held = pair.outcome.train_rms_sigma, h
    progress.outcome = pair.outcome
