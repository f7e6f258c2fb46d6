"""Who may be named in a verdict of ``shm diagnose``, and what its first sentence may claim (pure logic, no I/O).

A *member* is one thing a diagnosis could blame: a core-parameter re-estimation (or a group of them) or a library
effect, alone or inside a combination. It is **named** only when all four hold (issue 26 point 1):

1. it is identifiable on the records (its estimates have finite standard errors, a re-estimation is pinned to
   :data:`MAX_REL_SE` and no other core parameter mimics it: :mod:`workbench.diagnose._identifiability`);
2. none of its estimates is at a range bound;
3. undoing it in the fitted set (parameters back to the set's values, an effect to its neutral values, no refit)
   changes the prediction by more than the noise: RMS change > :data:`CHANGE_ABOVE_SIGMA` (1 σ, the noise's own RMS);
4. its removal costs more than the noise: the set refitted without it (the *drop-one fit*; for a single member the
   nominal model) leaves a held-out RMS more than ``tolerance_sigma`` above the set's — the band within which two
   held-out RMS values are the same up to white noise and model tolerance
   (:func:`workbench.fit.noise_tolerance`).

The first sentence may present a cure ("m3 is wrong … — re-estimate it", "Missing effect: …", "Two things at
once: …") only when the *named* members, fitted together, leave at most :data:`CURE_AT_MOST_SIGMA` held out;
otherwise it says that the library and the core parameters explain only part of the excess over the noise, with the
share (:func:`excess_share`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

#: a named cure must bring the held-out RMS to at most this (σ): the noise floor of the verdicts
CURE_AT_MOST_SIGMA = 1.5
#: undoing a named member must change the prediction by more than this RMS (σ): the noise's own RMS
CHANGE_ABOVE_SIGMA = 1.0
#: a re-estimated parameter known only to worse than this relative standard error is not identifiable
MAX_REL_SE = 0.5


@dataclass(frozen=True)
class MemberEvidence:
    """What decides whether ``name`` may be named (σ: the noise level of the records)."""

    name: str
    kind: str  # "parameter" | "effect"
    identifiable: bool
    at_bound: bool
    change_sigma: float  # RMS change of the prediction when the member is undone in the fitted set (σ)
    drop_cost_sigma: float  # held-out RMS of the set refitted without it minus the set's (σ)
    tolerance_sigma: float  # held-out RMS differences up to this are noise (σ)
    why_not_identifiable: str = ""


def why_not_named(m: MemberEvidence) -> str:
    """'' when ``m`` may be named, else the reason in words (the first rule it fails)."""
    if not m.identifiable:
        return "not identifiable on these records" + (f" ({m.why_not_identifiable})" if m.why_not_identifiable
                                                       else "")
    if m.at_bound:
        return "at a range bound"
    if not m.change_sigma > CHANGE_ABOVE_SIGMA:  # NaN fails too
        return f"changes the prediction by only {m.change_sigma:.2g} σ RMS (noise: {CHANGE_ABOVE_SIGMA:g} σ)"
    if not m.drop_cost_sigma > m.tolerance_sigma:
        return (f"the rest refitted without it does as well (held-out {m.drop_cost_sigma:+.2g} σ, within the "
                f"noise band ±{m.tolerance_sigma:.2g} σ)")
    return ""


def nameable(m: MemberEvidence) -> bool:
    return why_not_named(m) == ""


def named(members: Sequence[MemberEvidence]) -> list[str]:
    """The names of the members that may be named, in their order."""
    return [m.name for m in members if nameable(m)]


def reaches_floor(held_sigma: float) -> bool:
    """Whether a held-out RMS (σ) is at the verdicts' noise floor (≤ :data:`CURE_AT_MOST_SIGMA`)."""
    return math.isfinite(held_sigma) and held_sigma <= CURE_AT_MOST_SIGMA


def excess_share(base_held_sigma: float, held_sigma: float) -> float:
    """Share (0–1) of the nominal model's held-out energy above the noise (RMS² − 1) that a model leaving
    ``held_sigma`` removes."""
    base_excess = base_held_sigma ** 2 - 1.0
    if not (math.isfinite(base_excess) and base_excess > 0 and math.isfinite(held_sigma)):
        return 0.0
    return min(max((base_excess - max(held_sigma ** 2 - 1.0, 0.0)) / base_excess, 0.0), 1.0)


def head_kind(named_kinds: Sequence[str], held_named_sigma: float, base_held_sigma: float,
              nominal_at_floor: float = 1.25) -> str:
    """What the first sentence may say, from the kinds of the *named* members (in order) and the held-out RMS (σ)
    they leave fitted together:

    * "nothing_missing": nothing named and the nominal model at the floor (≤ ``nominal_at_floor``);
    * "unexplained": nothing named on a record the nominal model misses;
    * "partial": the named members do not reach :data:`CURE_AT_MOST_SIGMA`: the library and the parameters explain
      only part;
    * "wrong_parameter": one re-estimation alone reaches it ("X is wrong — re-estimate it");
    * "missing": one effect alone reaches it; "combination": several named members together reach it.
    """
    if not named_kinds:
        return "nothing_missing" if base_held_sigma <= nominal_at_floor else "unexplained"
    if not reaches_floor(held_named_sigma):
        return "partial"
    if len(named_kinds) > 1:
        return "combination"
    return "wrong_parameter" if named_kinds[0] == "parameter" else "missing"
