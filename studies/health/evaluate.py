"""Remaining life against time, and how good the prognosis was on a life whose truth is known.

:func:`sweep_predictions` moves the as-of time over the visits: at every visit from the :data:`MIN_VISITS`-th on,
trends and forecast are rebuilt from the visits up to it (the per-visit estimates are made once; they do not depend
on the as-of time) — the remaining-life-against-time curve of the page. :func:`evaluate_sweep` scores those
predictions against the true first FAULT with the prognostics metrics of ProgPy / Saxena et al. (2010)
(:mod:`.metrics`): α-λ accuracy at λ points, prognostic horizon, relative accuracy, and the coverage of the 90 %
interval. As in the prognosis challenge (:mod:`.challenge`), a predicted trip time counts where the board would see
it — at the first visit at or after it — and the truth is the hours of the first FAULT visit; only predictions with a
significant trend are a date (the others give a lower bound) and enter the scores.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from studies.health.follow import floor_of
from studies.health.forecast import forecast_trip
from studies.health.metrics import (
    alpha_lambda_point,
    interval_covers,
    prognostic_horizon,
    relative_accuracy,
    within_alpha,
)
from studies.health.trend import fit_trend
from studies.health.trip import TripBoundary

#: visits a prediction needs (as the challenge: the 3-parameter trend laws are fitted from 5, linear from 3)
MIN_VISITS = 4
ALPHA = 0.2
BETA = 0.5
LAMBDAS: tuple[float, ...] = (0.25, 0.5, 0.75)
#: Monte Carlo size of each swept forecast (the page's main forecast uses forecast.N_PATHS)
SWEEP_PATHS = 600
SWEEP_GRID = 600


def seen_at_visits(samples: np.ndarray, start: float, interval: float) -> np.ndarray:
    """Trip samples moved to the visit at which the board would see them (h; inf beyond the horizon)."""
    s = np.asarray(samples, float)
    out = np.full(s.shape, np.inf)
    fin = np.isfinite(s)
    out[fin] = start + interval * np.ceil((s[fin] - start) / interval - 1e-9)
    return out


def _quantiles(x: np.ndarray, qs: Sequence[float]) -> list[float | None]:
    with np.errstate(invalid="ignore"):
        q = np.quantile(x, qs)
    return [float(v) if np.isfinite(v) else None for v in q]


@dataclass(frozen=True)
class SweepPrediction:
    """The forecast as of one visit (:func:`sweep_predictions`); ``health.json``'s ``remaining_life`` rows."""

    as_of_hours: float
    """The as-of time (h): the visit the prediction is made at."""
    visits_used: int
    """Visits up to and including it."""
    significant: bool
    """Whether any trend is significant (only then is the prediction a date)."""
    trip_hours_median: float | None
    """Median trip time seen at a visit (h); None beyond the horizon."""
    trip_interval_90: list[float | None]
    """90 % interval of the trip time seen at visits, [lo, hi] (h; None beyond the horizon)."""
    lower_bound_hours: float | None
    """No-trend lower bound of the trip time (h)."""
    rul_median_hours: float | None
    """Median remaining useful life from the as-of time (h)."""
    rul_interval_90: list[float | None]
    """90 % interval of the remaining useful life (h)."""
    samples: np.ndarray
    """Trip time samples seen at visits (h; inf beyond the horizon); not written to JSON."""

    def to_json(self) -> dict[str, Any]:
        """Every field but ``samples``, by name, in field order."""
        return {f.name: getattr(self, f.name) for f in fields(self) if f.name != "samples"}


def sweep_predictions(hours: Sequence[float], rel: Mapping[str, Sequence[float]],
                      rel_se: Mapping[str, Sequence[float | None]], boundary: TripBoundary, interval: float, *,
                      seed: int = 1, until_hours: float | None = None, n_paths: int = SWEEP_PATHS,
                      n_grid: int = SWEEP_GRID, effect_limits: Mapping[str, float] | None = None
                      ) -> list[SweepPrediction]:
    """One prediction per visit from the :data:`MIN_VISITS`-th (as of its hours; before ``until_hours`` when
    given)."""
    h = np.asarray(hours, float)
    out = []
    for j in range(MIN_VISITS - 1, h.size):
        t = float(h[j])
        if until_hours is not None and t >= until_hours - 1e-9:
            break
        trends = {n: fit_trend(n, h[: j + 1], list(rel[n])[: j + 1], list(rel_se[n])[: j + 1], floor=floor_of(n))
                  for n in rel}
        fc = forecast_trip(trends, boundary, t, interval, seed=seed + j, n_paths=n_paths, n_grid=n_grid,
                           effect_limits=effect_limits)
        seen = seen_at_visits(fc.trip_samples, float(h[0]), interval)
        med, lo, hi = _quantiles(seen, [0.5, 0.05, 0.95])
        out.append(SweepPrediction(
            as_of_hours=t, visits_used=j + 1, significant=fc.significant, trip_hours_median=med,
            trip_interval_90=[lo, hi], lower_bound_hours=fc.lower_bound_hours,
            rul_median_hours=None if med is None else med - t,
            rul_interval_90=[None if lo is None else lo - t, None if hi is None else hi - t], samples=seen))
    return out


@dataclass(frozen=True, slots=True)
class ScoredPrediction:
    """One prediction made before the true first FAULT (``t_eol``), scored: the true remaining life (h) and, for a
    dated one (significant trend), whether it is within α of the truth, its relative accuracy and whether its 90 %
    interval holds the truth (None for an undated one)."""

    prediction: SweepPrediction
    rul_true_hours: float
    within_alpha: bool | None
    relative_accuracy: float | None
    covered: bool | None

    def to_json(self) -> dict[str, Any]:  # a row of health.json's evaluation.predictions
        return self.prediction.to_json() | {
            "rul_true_hours": self.rul_true_hours, "within_alpha": self.within_alpha,
            "relative_accuracy": self.relative_accuracy, "covered": self.covered}


@dataclass(frozen=True, slots=True)
class SweepEvaluation:
    """The scores of the swept predictions against the true first FAULT (h): each prediction's, the α-λ verdict at
    each λ point (:func:`.metrics.alpha_lambda_point`'s), the prognostic horizon (h), the mean relative accuracy and
    the 90 % interval's coverage over the dated predictions."""

    alpha: float
    beta: float
    lambdas: list[float]
    true_first_fault_hours: float
    predictions: list[ScoredPrediction]
    dated_predictions: int
    first_prediction_hours: float | None
    alpha_lambda: list[dict[str, float | bool | None]]
    alpha_lambda_all_met: bool | None
    prognostic_horizon_hours: float | None
    relative_accuracy_mean: float | None
    coverage_90: float | None

    def to_json(self) -> dict[str, Any]:  # health.json's evaluation (docs/health.md), before its truth keys
        return {f.name: [p.to_json() for p in self.predictions] if f.name == "predictions"
                else getattr(self, f.name) for f in fields(self)}


def evaluate_sweep(preds: Sequence[SweepPrediction], t_eol: float, *, alpha: float = ALPHA, beta: float = BETA,
                   lambdas: Sequence[float] = LAMBDAS) -> SweepEvaluation:
    """The scores of the predictions made before ``t_eol`` (h, the true first FAULT visit)."""
    before = [p for p in preds if p.as_of_hours < t_eol - 1e-9]
    dated = [p for p in before if p.significant]
    times = [p.as_of_hours for p in dated]
    samples = [p.samples for p in dated]
    rows = [ScoredPrediction(
        p, t_eol - p.as_of_hours,
        within_alpha(p.samples, p.as_of_hours, t_eol, alpha, beta) if p.significant else None,
        relative_accuracy(p.samples, p.as_of_hours, t_eol) if p.significant else None,
        interval_covers(p.trip_interval_90, t_eol) if p.significant else None) for p in before]
    ras = [r.relative_accuracy for r in rows if r.relative_accuracy is not None]
    covered = [r.covered for r in rows if r.covered is not None]
    points = [alpha_lambda_point(times, samples, t_eol, lam=lam, alpha=alpha, beta=beta) for lam in lambdas]
    return SweepEvaluation(
        alpha, beta, list(lambdas), t_eol, rows, len(dated), times[0] if times else None, points,
        all(pt["ok"] for pt in points) if points and all(pt["ok"] is not None for pt in points) else None,
        prognostic_horizon(times, samples, t_eol, alpha=alpha, beta=beta),
        float(np.mean(ras)) if ras else None, (sum(covered) / len(covered)) if covered else None)
