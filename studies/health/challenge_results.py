"""The prognosis challenge's results, typed: one life's scores and verdicts (:class:`LifeChallengeResult`), the
summary over the lives (:class:`ChallengeSummary`, :func:`summarise`) and the whole run (:class:`ChallengeResult`).

Each result crosses the process pool and the scale-out runner as itself (picklable); ``to_json`` builds the
challenge's JSON document (``health_challenge.json``, written by ``bench/bench_health.py``) in one place, with the
keys in the order they always had.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import Any, Literal

import numpy as np

from studies.health.follow import Followed
from studies.health.metrics import alpha_lambda, interval_covers, prognostic_horizon


@dataclass(frozen=True, slots=True)
class VisitPrediction:
    """The trip forecast made as of one visit (0-based ``as_of_visit``, at ``hours`` h): whether its trend was
    significant, its 90 % interval in visits (0-based; None: beyond the horizon) and each sample path's trip time
    moved to the visit that would see it (h; inf beyond the horizon)."""

    as_of_visit: int
    hours: float
    significant: bool
    interval_visits: list[int | None]
    samples_seen: np.ndarray


@dataclass(frozen=True, slots=True)
class LifeScore:
    """One life's predictions (physics-based or baseline) scored against its true first FAULT visit.

    ``predictions`` counts the significant ones (every one made when the life never FAULTs: then nothing else is
    scored and ``intervals`` is None). ``covered``: how many 90 % intervals (in visits) hold the true first FAULT
    visit; ``alpha_lambda``: ProgPy's α-λ verdict (None: no prediction judged); ``prognostic_horizon_h`` (h)."""

    predictions: int
    covered: int | None = None
    coverage: float | None = None
    alpha_lambda: bool | None = None
    prognostic_horizon_h: float | None = None
    intervals: list[list[int | None]] | None = None

    @property
    def scored(self) -> bool:
        return self.intervals is not None

    def to_json(self) -> dict[str, Any]:  # a life's "physics" / "baseline" in health_challenge.json
        if not self.scored:
            return {"predictions": self.predictions, "covered": None, "alpha_lambda": None,
                    "prognostic_horizon_h": None}
        return {"predictions": self.predictions, "covered": self.covered, "coverage": self.coverage,
                "alpha_lambda": self.alpha_lambda, "prognostic_horizon_h": self.prognostic_horizon_h,
                "intervals": self.intervals}


def score_predictions(preds: Sequence[VisitPrediction], k_true: int | None, hours: np.ndarray) -> LifeScore:
    """``preds`` scored against the true first FAULT visit ``k_true`` (0-based; None: the life never FAULTs) of a
    life visited at ``hours`` (h)."""
    if k_true is None:
        return LifeScore(len(preds))
    sig = [p for p in preds if p.significant]
    covered = [interval_covers(p.interval_visits, k_true) for p in sig]
    t_eol = float(hours[k_true])
    times = [p.hours for p in sig]
    samples = [p.samples_seen for p in sig]
    return LifeScore(len(sig), int(sum(covered)), (sum(covered) / len(covered)) if covered else None,
                     alpha_lambda(times, samples, t_eol), prognostic_horizon(times, samples, t_eol),
                     [p.interval_visits for p in sig])


@dataclass(frozen=True, slots=True)
class StepVerdict:
    """A sudden-damage life's change point: placed between the two visits that bracket the truth's step, and
    the step time the chosen model put (h; None: no change point)."""

    placed: bool
    tau_h: float | None


@dataclass(frozen=True, slots=True)
class LifeChallengeResult:
    """One simulated life of the challenge: what it was (name, kind, group, added effects, visits every
    ``interval_h`` h, laser noise in µm), its true first FAULT visit (0-based; None: never), each visit's first
    natural frequency (Hz, the baseline's feature), the scores of both forecasts, what was followed (re-estimated
    set and why), the final visit's trend verdicts per parameter and, for a sudden damage, the step's placement."""

    life: str
    kind: str
    group: str
    effects: tuple[str, ...]
    visits: int
    interval_h: float
    noise_um: float
    hours: tuple[float, ...]
    true_first_fault_visit: int | None
    f1_Hz: list[float]
    physics: LifeScore
    baseline: LifeScore | None
    followed: Followed
    final_significant: dict[str, bool]
    final_models: dict[str, str]
    step: StepVerdict | None
    wall_s: float

    @property
    def true_first_fault_hours(self) -> float | None:
        k = self.true_first_fault_visit
        return None if k is None else self.hours[k]

    @property
    def followed_effect(self) -> bool:
        """Whether the re-estimated set became the added effects' parameters (an effect life followed to its
        cause)."""
        return self.followed.switched and set(self.followed.effects) == set(self.effects)

    def to_json(self) -> dict[str, Any]:  # one of health_challenge.json's "lives"
        doc: dict[str, Any] = {
            "life": self.life, "kind": self.kind, "visits": self.visits, "interval_h": self.interval_h,
            "noise_um": self.noise_um, "true_first_fault_visit": self.true_first_fault_visit,
            "true_first_fault_hours": self.true_first_fault_hours, "f1_Hz": self.f1_Hz, "wall_s": self.wall_s,
            "physics": self.physics.to_json(), "baseline": None if self.baseline is None else self.baseline.to_json(),
            "followed": self.followed.as_dict(self.hours), "group": self.group, "effects": list(self.effects),
            "final_significant": self.final_significant, "final_models": self.final_models}
        if self.step is not None:
            doc["step_placed"] = self.step.placed
            doc["step_tau_h"] = self.step.tau_h
        return doc


@dataclass(frozen=True, slots=True)
class GroupScore:
    """One forecast's scores over the trend lives of a group (or of all): lives scored, significant predictions,
    their coverage, the mean α-λ verdict over the lives judged, the median prognostic horizon (h) over the lives
    with one."""

    lives_scored: int
    predictions: int
    coverage: float | None
    alpha_lambda: float | None
    alpha_lambda_lives: int
    prognostic_horizon_h_median: float | None
    lives_with_a_horizon: int


def group_score(lives: Sequence[LifeChallengeResult], side: Literal["physics", "baseline"],
                group: str | None = None) -> GroupScore:
    """The ``side`` forecast's scores over the trend lives (of ``group``; None: every group) that were scored."""
    tr = [s for x in lives if x.kind == "trend" and (group is None or x.group == group)
          for s in [x.physics if side == "physics" else x.baseline] if s is not None and s.coverage is not None]
    n_pred = sum(t.predictions for t in tr)
    n_cov = sum(t.covered or 0 for t in tr)
    al = [t.alpha_lambda for t in tr if t.alpha_lambda is not None]
    ph = [t.prognostic_horizon_h for t in tr if t.prognostic_horizon_h is not None]
    return GroupScore(len(tr), n_pred, n_cov / n_pred if n_pred else None, (sum(al) / len(al)) if al else None,
                      len(al), float(np.median(ph)) if ph else None, len(ph))


@dataclass(frozen=True, slots=True)
class SideBySide:
    """The physics-based forecast's scores beside the feature-only baseline's (None: no baseline ran)."""

    physics: GroupScore
    baseline: GroupScore | None

    def to_json(self) -> dict[str, Any]:  # health_challenge.json's "by_group" entries
        return {"physics": asdict(self.physics), "baseline": None if self.baseline is None else asdict(self.baseline)}


@dataclass(frozen=True, slots=True)
class CauseFollowed:
    """The lives where an added effect degrades: how many, the share followed to the effect, the others' names."""

    lives: int
    followed_to_the_effect: float
    not_followed: list[str]


@dataclass(frozen=True, slots=True)
class ChallengeSummary:
    """The challenge's scores over all lives: both forecasts overall and by group, the share of stable lives with
    no significant trend at the last visit, the share of sudden damages placed, the trend lives that never FAULT,
    and the effect lives followed to their cause (None: no effect life)."""

    overall: SideBySide
    stable_no_trend: float | None
    stable_lives: int
    sudden_placed: float | None
    sudden_lives: int
    trend_lives_without_fault: list[str]
    by_group: dict[str, SideBySide]
    effect_cause_followed: CauseFollowed | None

    @property
    def physics(self) -> GroupScore:
        return self.overall.physics

    @property
    def baseline(self) -> GroupScore | None:
        return self.overall.baseline

    def to_json(self) -> dict[str, Any]:  # health_challenge.json's "summary"
        doc = self.overall.to_json()
        doc |= {"stable_no_trend": self.stable_no_trend, "stable_lives": self.stable_lives,
                "sudden_placed": self.sudden_placed, "sudden_lives": self.sudden_lives,
                "trend_lives_without_fault": self.trend_lives_without_fault,
                "by_group": {g: s.to_json() for g, s in self.by_group.items()},
                "effect_cause_followed": None if self.effect_cause_followed is None
                else asdict(self.effect_cause_followed)}
        return doc


def summarise(lives: Sequence[LifeChallengeResult]) -> ChallengeSummary:
    """The challenge's scores over ``lives`` (the baseline's only when every life ran it)."""
    with_baseline = all(x.baseline is not None for x in lives)

    def side_by_side(group: str | None = None) -> SideBySide:
        return SideBySide(group_score(lives, "physics", group),
                          group_score(lives, "baseline", group) if with_baseline else None)

    stable = [x for x in lives if x.kind == "stable"]
    sudden = [x for x in lives if x.kind == "sudden"]
    return ChallengeSummary(
        side_by_side(),
        (sum(not any(x.final_significant.values()) for x in stable) / len(stable)) if stable else None,
        len(stable),
        (sum(x.step is not None and x.step.placed for x in sudden) / len(sudden)) if sudden else None,
        len(sudden),
        [x.life for x in lives if x.kind == "trend" and x.true_first_fault_visit is None],
        {g: side_by_side(g) for g in sorted({x.group for x in lives if x.kind == "trend"})},
        cause_followed(lives))


def cause_followed(lives: Sequence[LifeChallengeResult]) -> CauseFollowed | None:
    """Lives where an added effect degrades: the share whose re-estimated set became that effect's parameters."""
    eff = [x for x in lives if x.effects]
    if not eff:
        return None
    right = [x.life for x in eff if x.followed_effect]
    return CauseFollowed(len(eff), len(right) / len(eff), [x.life for x in eff if x.life not in right])


@dataclass(frozen=True, slots=True)
class ChallengeResult:
    """Every life's result in life order, their summary, the run's wall time (s) and the baseline's alarm threshold
    (relative f1 change)."""

    lives: list[LifeChallengeResult]
    summary: ChallengeSummary
    wall_s: float
    f1_threshold: float

    def to_json(self) -> dict[str, Any]:  # health_challenge.json (bench/bench_health.py writes it)
        return {"summary": self.summary.to_json(), "lives": [x.to_json() for x in self.lives],
                "f1_threshold": self.f1_threshold}
