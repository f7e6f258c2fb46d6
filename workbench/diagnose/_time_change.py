"""Did the physics change during the record? A split-record refit of what a verdict names (issue 26 point 3).

A constant error of a parameter and a change at an instant can look alike to a fit over the whole record: damping
c1 doubled half way through a sweep is "c1 is wrong (+100 %)" to a re-estimation, and that re-estimation may even
reach the noise floor of the verdicts. Whatever a verdict names (re-estimated parameters or a library effect's
parameters) is therefore refitted on the record's *early* part and on its *late* part separately — the parts split at
the instant the nominal model's residual leaves the noise (:func:`workbench.discover.change_point`: for an
event, its instant; kept within the middle half of the record) — and the two estimates of each parameter compared: a
constant parameter gives the same value on both parts within their standard errors, a change inside the record does
not. When some differ (:func:`differs`: by more than :data:`SPLIT_Z` combined standard errors and
:data:`MIN_REL_CHANGE` of their size), the diagnosis does not present the re-estimation as the cure: ``shm diagnose``
runs its discovery step, whose dictionary holds every core parameter behind a step and a ramp in time with the
instant fitted (:mod:`workbench.diagnose._discovery`).

Both parts are simulated from the record's start (the state at the split comes from the early part); only the
samples of a part are scored in its fit.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

from board_config import ParameterSet
from workbench.discover import change_point
from workbench.fit import CandidateResult, SimBatch, Target, fit_spec

#: two estimates differ when they are more than this many combined standard errors apart …
SPLIT_Z = 4.0
#: … and more than this share of the larger one
MIN_REL_CHANGE = 0.05
#: the split stays within this share of the record from either end (each part needs its own information)
SPLIT_MARGIN = 0.25


@dataclass(frozen=True)
class PartEstimates:
    """One parameter fitted on the early and on the late part of the records (value, standard error; SI)."""

    name: str
    unit: str
    early: float
    early_se: float
    late: float
    late_se: float

    @property
    def z(self) -> float:
        """Their difference in combined standard errors (∞ when a standard error is 0; NaN when one is unknown)."""
        se = math.hypot(self.early_se, self.late_se)
        if not math.isfinite(se):
            return math.nan
        return abs(self.late - self.early) / se if se > 0 else math.inf

    @property
    def relative_change(self) -> float:
        """(late − early) / |early| (∞ from 0)."""
        return (self.late - self.early) / abs(self.early) if self.early != 0 else math.inf


def differs(p: PartEstimates) -> bool:
    """Whether the two parts' estimates differ beyond their standard errors (:data:`SPLIT_Z`) and materially
    (:data:`MIN_REL_CHANGE`); an estimate without a finite standard error never counts."""
    size = max(abs(p.early), abs(p.late))
    return bool(p.z > SPLIT_Z) and abs(p.late - p.early) > MIN_REL_CHANGE * size


@dataclass
class TimeChange:
    """The split-record refit of a named set: the split (s), every parameter's two estimates, and which differ."""

    split_s: float
    parts: list[PartEstimates] = field(default_factory=list)

    @property
    def changed(self) -> list[PartEstimates]:
        return [p for p in self.parts if differs(p)]

    def sentence(self) -> str:
        """'c1 is not constant over the record: 0.098 ± 0.002 N*s/m before t ≈ 3 s, 0.196 ± 0.004 N*s/m after (+100 %,
        31 standard errors apart) — the physics changed during the record' ('' when nothing changed)."""
        if not self.changed:
            return ""
        parts = [f"{p.name} {p.early:.4g} ± {p.early_se:.2g} {p.unit} before t ≈ {self.split_s:.3g} s, "
                 f"{p.late:.4g} ± {p.late_se:.2g} {p.unit} after ({100 * p.relative_change:+.3g} %, "
                 f"{p.z:.3g} standard errors apart)" for p in self.changed]
        return ("not constant over the record: " + "; ".join(parts)
                + " — the physics changed during the record")

    def to_dict(self) -> dict[str, Any]:
        return {"split_s": self.split_s, "changed": [p.name for p in self.changed],
                "parts": [p.__dict__ | {"z": p.z, "differs": differs(p)} for p in self.parts]}


def split_time(targets: Sequence[Target], sim: SimBatch) -> float:
    """Where to split (s): where the nominal model's residual leaves the noise on the record where that is clearest,
    kept within the middle of the record (:data:`SPLIT_MARGIN`)."""
    best: tuple[float, float, Target] | None = None
    for tg, y in zip(targets, sim.y):
        t_hat, gain = change_point(tg.t, (tg.measured - y[0]) / tg.sigma[:, None])
        if best is None or gain > best[1]:
            best = (t_hat, gain, tg)
    assert best is not None
    t_hat, _, tg = best
    lo, hi = float(tg.t[0]), float(tg.t[-1])
    return min(max(t_hat, lo + SPLIT_MARGIN * (hi - lo)), hi - SPLIT_MARGIN * (hi - lo))


def part_targets(targets: Sequence[Target], split_s: float, late: bool) -> list[Target]:
    """The targets with only the samples of one part (before ``split_s``, or from it) in training and held-out."""
    out = []
    for tg in targets:
        inside = tg.t >= split_s if late else tg.t < split_s
        out.append(replace(tg, train=tg.train & inside, held=tg.held & inside))
    return out


def time_change(cand: CandidateResult, base: ParameterSet, targets: Sequence[Target], sim: SimBatch,
                data: Mapping[str, Any], rss0_held: float, **fit_kw: Any) -> TimeChange | None:
    """The split-record refit of the fitted ``cand`` (the set a verdict names) on ``targets`` (``sim``: the nominal
    model's simulation, for the split); None when it cannot be made (no fitted set)."""
    if cand.spec is None or cand.outcome is None:
        return None
    split_s = split_time(targets, sim)
    start = dict(cand.outcome.values)
    fits = [fit_spec(cand.spec, base, part_targets(targets, split_s, late), data, rss0_held, start=start, **fit_kw)
            for late in (False, True)]
    if any(f.outcome is None for f in fits):
        return TimeChange(split_s)
    early = {e.name: e for e in fits[0].outcome.estimates}  # type: ignore[union-attr]
    late = {e.name: e for e in fits[1].outcome.estimates}  # type: ignore[union-attr]
    parts = [PartEstimates(n, e.unit, e.value, e.stderr, late[n].value, late[n].stderr)
             for n, e in early.items() if n in late]
    return TimeChange(split_s, parts)

