"""When will the board's own monitor first say FAULT? P(FAULT) at future operating hours, trip time, RUL.

Sampled future paths of every health parameter (:meth:`.trend.Trend.sample_paths`: coefficient uncertainty and
model averaging) go through the monitor's trip boundary (:mod:`.trip`, the campaign's MBIT simulation + Eq. 11 +
Table 3 counter). A path's trip time is the first hour at which it faults; P(FAULT by h) is the share of paths
tripped by h. The trip time is their median, the 90 % interval their 5–95 % quantiles, the RUL the median minus the
last visit's hours. Without a significant trend there is no date: the forecast is a lower bound — the earliest trip
of the paths drawn from each parameter's *linear* fit (its slope's uncertainty included), "no FAULT expected before".
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from studies.health.trend import Trend, paths_of
from studies.health.trip import HEALTH_PARAMS, TripBoundary

N_PATHS = 2000
N_GRID = 1500
#: uncertainty of the monitor's trip limit in alpha_h (relative deviation, 1 sigma)
BOUNDARY_SIGMA = 0.003
#: relative uncertainty of an added effect's trip limit (1 sigma)
EFFECT_LIMIT_SHARE = 0.03


@dataclass
class Forecast:
    trip_operating_hours: float | None
    trip_interval_90: list[float | None] | None  # upper end None: beyond the horizon
    rul_hours: float | None
    p_fault_next_visit: float | None
    lower_bound_hours: float | None  # no significant trend: no FAULT expected before this
    last_hours: float
    next_visit_hours: float
    horizon_hours: float
    already_faulty: bool
    grid_hours: np.ndarray
    p_fault: np.ndarray  # P(tripped by h) on grid_hours
    trip_samples: np.ndarray  # sampled trip hours (inf: beyond the horizon)
    significant: bool

    def as_dict(self) -> dict[str, Any]:  # JSON at the edge (health.json's forecast)
        return {"trip_operating_hours": self.trip_operating_hours, "trip_interval_90": self.trip_interval_90,
                "rul_hours": self.rul_hours, "p_fault_next_visit": self.p_fault_next_visit,
                "lower_bound_hours": self.lower_bound_hours, "last_visit_hours": self.last_hours,
                "next_visit_hours": self.next_visit_hours, "horizon_hours": self.horizon_hours,
                "already_faulty": self.already_faulty, "significant_trend": self.significant,
                "share_tripping_within_horizon": float(np.mean(np.isfinite(self.trip_samples)))}


def _first_trip(grid: np.ndarray, faults: np.ndarray) -> np.ndarray:
    hit = faults.any(axis=1)
    first = np.argmax(faults, axis=1)
    return np.where(hit, grid[first], np.inf)


def forecast_trip(trends: Mapping[str, Trend], boundary: TripBoundary, last_hours: float, visit_interval: float,
                  *, current: Mapping[str, float] | None = None, seed: int = 1, horizon_factor: float = 4.0,
                  n_paths: int = N_PATHS, n_grid: int = N_GRID,
                  effect_limits: Mapping[str, float] | None = None) -> Forecast:
    """The forecast from per-parameter trends (relative deviations) through the monitor's trip boundary.
    ``effect_limits``: an added effect's parameter (trended in its own unit, e.g. G_leak in S) → the value at which
    the monitor trips (:func:`.trip.effect_trip_limit`); a path also trips when it reaches that value (known to
    :data:`EFFECT_LIMIT_SHARE` of itself, 1 σ)."""
    rng = np.random.default_rng(seed)
    horizon = last_hours + max(horizon_factor * max(last_hours, visit_interval), 20 * visit_interval)
    grid = np.linspace(last_hours, horizon, n_grid)
    significant = any(t.significant for t in trends.values())
    devs = np.zeros((n_paths, grid.size, 3))
    for j, name in enumerate(HEALTH_PARAMS):
        t = trends.get(name)
        if t is not None:
            devs[:, :, j] = _parameter_paths(t, significant, grid, n_paths, rng)
    effect_trip = np.zeros((n_paths, grid.size), bool)
    for name, limit in (effect_limits or {}).items():
        t = trends.get(name)
        if t is None or not math.isfinite(limit):
            continue
        lim = limit * (1.0 + rng.normal(0.0, EFFECT_LIMIT_SHARE, n_paths))
        effect_trip |= _parameter_paths(t, significant, grid, n_paths, rng) >= lim[:, None]
    # the trip limit itself is known to about BOUNDARY_SIGMA in alpha_h (noise-dependent counter near the limit,
    # the board's visit history against the campaign's MBITs from rest): each path gets its own limit offset
    shift = rng.normal(0.0, BOUNDARY_SIGMA, n_paths)
    devs[:, :, 1] -= shift[:, None]
    faults = boundary.fault(devs) | effect_trip
    trips = _first_trip(grid, faults)
    already = False
    if current is not None:
        cur = np.array([[current.get(n, 0.0) for n in HEALTH_PARAMS]])
        already = bool(boundary.fault(cur)[0])
    p_fault = np.mean(trips[:, None] <= grid[None, :], axis=0)
    next_visit = last_hours + visit_interval
    if not significant:
        with np.errstate(invalid="ignore"):
            q = float(np.quantile(trips, 0.05))
        lb = q if math.isfinite(q) else horizon
        return Forecast(None, None, None, None, lb, last_hours, next_visit, horizon, already, grid, p_fault,
                        trips, False)
    with np.errstate(invalid="ignore"):
        q05, q50, q95 = np.quantile(trips, [0.05, 0.5, 0.95])
    p_next = float(np.mean(trips <= next_visit + 1e-9))
    trip = float(q50) if math.isfinite(q50) else None
    return Forecast(trip, [float(q05), float(q95) if math.isfinite(q95) else None], (trip - last_hours) if trip
                    is not None else None, p_next, None, last_hours, next_visit, horizon, already, grid, p_fault,
                    trips, True)


def _parameter_paths(t: Trend, significant: bool, grid: np.ndarray, n_paths: int, rng: np.random.Generator
                     ) -> np.ndarray:
    """Future paths of one parameter: its trend laws when significant; else, when another parameter trends, its
    constant; with no trend anywhere, its linear fit (the lower bound's extrapolation)."""
    if significant and t.significant:
        return t.sample_paths(grid, n_paths, rng)
    f = t.fits.get("linear") if not significant else t.fits.get("none")
    return paths_of(f if f is not None else t.fits["none"], grid, n_paths, rng)


def visit_of(hours: float | None, schedule_start: float, interval: float) -> int | None:
    """The visit index (0-based from ``schedule_start``) at or after ``hours``: when the board would first see it."""
    if hours is None or not math.isfinite(hours):
        return None
    return max(0, math.ceil((hours - schedule_start) / interval - 1e-9))
