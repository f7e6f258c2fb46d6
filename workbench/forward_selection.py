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
from workbench.fit import Target

MAX_MEMBERS = 3
#: remaining candidates tried at each step (the strongest by their own held-out ΔBIC)
POOL = 4
EXCESS_SHARE_TO_ADD = 0.2


def _touches(c: CandidateResult) -> set[str]:
    spec = c.spec
    if spec is None:
        return {c.effect}
    return {e.name for e in spec.effects} | {n for p in spec.params for n in p.members}


def forward_select(winner: CandidateResult, others: Sequence[CandidateResult], base: ParameterSet,
                   targets: Sequence[Target], data: Mapping[str, Any], rss0_held: float, *, min_reduction: float,
                   threads: int | None, max_nfev: int, seed: int,
                   base_held: float) -> tuple[CandidateResult, list[CandidateResult]]:
    """(the final set, the sets accepted in order — the first is ``winner``); see the module docstring."""
    current = winner
    steps = [winner]
    pool = sorted((c for c in others if c.spec is not None and c.outcome is not None and c.stable
                   and c.status == "fitted" and c.held_reduction > 0), key=lambda c: -c.delta_bic_held)
    while len(current.members) < MAX_MEMBERS and current.spec is not None and not explained(
            current.held_rms_sigma, base_held, current.n_eff_held):
        tries = []
        for c in [c for c in pool if not (_touches(c) & _touches(current))][:POOL]:
            spec = current.spec.plus(c.spec)
            start = dict(c.outcome.values) | dict(current.outcome.values)
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
    return current, steps
