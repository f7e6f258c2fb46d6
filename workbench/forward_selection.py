"""Two (or three) things wrong at once: forward selection over fitted candidates.

Starting from the best single candidate, each step fits the current set together with each of the strongest
remaining candidates (every parameter free, starting from the values each found alone), scores each enlarged set
on the held-out data against the *current* set (ΔBIC with the added parameters as penalty), and keeps the best
— if it clears the margin: ΔBIC_held > 0, and it removes at least :data:`EXCESS_SHARE_TO_ADD` of what the current
set leaves above the noise floor and at least ``min_reduction`` of its held-out residual energy. It stops when
nothing clears the margin, when the set explains the held-out data to the noise floor, or at
:data:`MAX_MEMBERS` members.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from board_config import ParameterSet
from workbench.candidate_fit import CandidateResult, explained, fit_spec, score
from workbench.candidates import CandidateSpec
from workbench.fit import Target

MAX_MEMBERS = 3
#: remaining candidates tried at each step (the strongest by their own held-out ΔBIC)
POOL = 3
POOL_SCREENED = 2
EXCESS_SHARE_TO_ADD = 0.2
#: a member is dropped when the set without it leaves at most this factor more held-out residual energy
PRUNE_WITHIN = 1.02


def _touches(c: CandidateResult) -> set[str]:
    """What a candidate changes: its effects, its independent parameters, its tied groups (a single parameter may
    join the group that holds it — the group then scales the others — and the backward step can drop the group)."""
    spec = c.spec
    if spec is None:
        return {c.effect}
    return ({e.name for e in spec.effects} | {n for p in spec.params if not p.tied for n in p.members}
            | {p.name for p in spec.params if p.tied})


def forward_select(winner: CandidateResult, others: Sequence[CandidateResult], base: ParameterSet,
                   targets: Sequence[Target], data: Mapping[str, Any], rss0_held: float, *, min_reduction: float,
                   threads: int | None, max_nfev: int, seed: int,
                   base_held: float) -> tuple[CandidateResult, list[CandidateResult]]:
    """(the final set, the sets accepted in order — the first is ``winner``); see the module docstring."""
    current = winner
    steps = [winner]
    fitted = sorted((c for c in others if c.spec is not None and c.outcome is not None and c.stable
                     and c.status == "fitted" and c.held_reduction > 0), key=lambda c: -c.delta_bic_held)
    screened = sorted((c for c in others if c.spec is not None and c.outcome is None and c.stable
                       and c.status == "screened out"), key=lambda c: c.screen_train_rms_sigma)
    # the strongest fitted ones first, then the best of those screened out (what the rest needs may have looked
    # weak against the nominal model)
    pool = fitted[:POOL] + screened[:POOL_SCREENED]
    while len(current.members) < MAX_MEMBERS and current.spec is not None and not explained(
            current.held_rms_sigma, base_held, current.n_eff_held):
        tries = []
        for c in [c for c in pool if not (_touches(c) & _touches(current))][:POOL + POOL_SCREENED]:
            spec = current.spec.plus(c.spec)
            own = dict(c.outcome.values) if c.outcome is not None else dict(c.screen_start)
            start = own | dict(current.outcome.values)
            r = fit_spec(spec, base, targets, data, rss0_held, start=start, min_reduction=min_reduction,
                         threads=threads, max_nfev=max_nfev, seed=seed)
            score(r, current.held_rss, min_reduction, k_ref=len(current.free))
            tries.append((r, c))
        if not tries:
            break
        best, added = max(tries, key=lambda rc: rc[0].delta_bic_held if rc[0].stable else float("-inf"))
        n_held = current.outcome.n_held if current.outcome else 0
        gain = current.held_rss - best.held_rss
        excess = max(current.held_rss - n_held, 0.0)
        if not (best.accepted and gain >= EXCESS_SHARE_TO_ADD * excess):
            break
        score(best, rss0_held, min_reduction)  # from here on, judged against the nominal model like the others
        current = best
        steps.append(best)
        pool = [c for c in pool if c is not added]
    if len(current.members) > 1:
        current = _prune(current, base, targets, data, rss0_held, min_reduction=min_reduction, threads=threads,
                         max_nfev=max_nfev, seed=seed)
        if current is not steps[-1]:
            steps.append(current)
    return current, steps


def _without(spec: CandidateSpec, name: str) -> CandidateSpec:
    return CandidateSpec(tuple(e for e in spec.effects if e.name != name),
                         tuple(p for p in spec.params if p.name != name),
                         tuple((k, v) for k, v in spec.extras if k != name))


def _prune(current: CandidateResult, base: ParameterSet, targets: Sequence[Target], data: Mapping[str, Any],
           rss0_held: float, **kw: Any) -> CandidateResult:
    """Backward step: drop a member the others made redundant (the set without it explains the held-out data
    within :data:`PRUNE_WITHIN`) — e.g. a parameter taken first that returns to its value once the effects are in."""
    assert current.spec is not None and current.outcome is not None
    for name in current.members:
        if len(current.members) < 2:
            break
        spec = _without(current.spec, name)
        start = dict(current.outcome.values)
        r = fit_spec(spec, base, targets, data, rss0_held, start=start, **kw)
        if r.accepted and r.held_rss <= PRUNE_WITHIN * current.held_rss:
            current = r
    return current
