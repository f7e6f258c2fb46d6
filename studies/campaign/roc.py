"""ROC view: sweep the monitor's ``eps_th`` and ``count_max`` over a campaign's stored error traces.

No re-simulation: the normalised-error traces do not depend on the thresholds. For each ``eps_th`` the counter
trajectory of every run is computed in closed form (:func:`~firmware_sim.condition_monitor.counter_trajectory`);
a run latches a fault for ``count_max`` iff its peak counter exceeds ``count_max``, so one pass per ``eps_th``
serves every ``count_max``.

Classes (maintenance view): a unit whose deviation range lies entirely at or below ``healthy_max`` (default 10 %)
is *acceptable*: a fault on it is a **false alarm**. A unit whose range starts at or above ``faulty_min``
(default also 10 %) is *degraded*: a fault on it is a **detection**. With ``faulty_min > healthy_max`` the
ranges in between are a grey zone that counts in neither. ``P_fa`` and ``P_d`` are fractions of the runs of each
class (integration failures excluded), with 95 % Wilson intervals. Without measurement noise a 0 % deviation unit
can never alarm (the model is the hardware), so false alarms come from small but real deviations, as in the paper.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from board_config import MonitorSettings
from board_config.errors import InputError
from firmware_sim.condition_monitor import counter_trajectory
from studies.campaign.statistics import wilson_interval

_TOL = 1e-9


@dataclass(frozen=True)
class RocTable:
    """Detection and false-alarm probabilities over an ``eps_th × count_max`` grid for one MBIT."""

    mbit: str
    label: str
    eps_th: np.ndarray  # (E,)
    count_max: np.ndarray  # (C,)
    n_healthy: int
    n_degraded: int
    false_alarms: np.ndarray  # (E, C) counts
    detections: np.ndarray  # (E, C) counts
    healthy_max: float
    faulty_min: float

    @property
    def p_false_alarm(self) -> np.ndarray:
        return self.false_alarms / self.n_healthy if self.n_healthy else np.full(self.false_alarms.shape, np.nan)

    @property
    def p_detection(self) -> np.ndarray:
        return self.detections / self.n_degraded if self.n_degraded else np.full(self.detections.shape, np.nan)

    def rows(self) -> list[dict[str, Any]]:  # the ROC table's CSV rows (column name → cell): the file's edge
        out = []
        for i, e in enumerate(self.eps_th):
            for j, c in enumerate(self.count_max):
                fa_lo, fa_hi = wilson_interval(int(self.false_alarms[i, j]), self.n_healthy)
                d_lo, d_hi = wilson_interval(int(self.detections[i, j]), self.n_degraded)
                out.append({"mbit": self.mbit, "eps_th": float(e), "count_max": int(c),
                            "n_healthy": self.n_healthy, "false_alarms": int(self.false_alarms[i, j]),
                            "p_false_alarm": float(self.p_false_alarm[i, j]), "p_false_alarm_ci95_low": fa_lo,
                            "p_false_alarm_ci95_high": fa_hi, "n_degraded": self.n_degraded,
                            "detections": int(self.detections[i, j]), "p_detection": float(self.p_detection[i, j]),
                            "p_detection_ci95_low": d_lo, "p_detection_ci95_high": d_hi})
        return out


def peak_counts(eps: np.ndarray, eps_th: float, settings: MonitorSettings) -> np.ndarray:
    """Peak counter value of each run (rows of ``eps``) for threshold ``eps_th``."""
    valid = np.isfinite(eps)
    with np.errstate(invalid="ignore"):
        exceeded = valid & (eps > eps_th)
    count = counter_trajectory(exceeded, valid, settings.counter_up, settings.counter_down)
    return count.max(axis=-1) if count.shape[-1] else np.zeros(eps.shape[:-1], dtype=np.int64)


def roc_sweep(eps: np.ndarray, range_lo: np.ndarray, range_hi: np.ndarray, ok: np.ndarray,
              eps_grid: np.ndarray, count_grid: np.ndarray, settings: MonitorSettings, *, mbit: str = "",
              label: str = "", healthy_max: float = 0.10, faulty_min: float = 0.10) -> RocTable:
    """Fault counts of the acceptable and degraded classes over the threshold grid (see the module doc)."""
    eps = np.asarray(eps, dtype=float)
    eps_grid = np.asarray(eps_grid, dtype=float)
    count_grid = np.asarray(count_grid, dtype=np.int64)
    if eps_grid.ndim != 1 or eps_grid.size == 0 or np.any(eps_grid <= 0):
        raise InputError("eps_th grid must be a non-empty list of positive thresholds")
    if count_grid.ndim != 1 or count_grid.size == 0 or np.any(count_grid < 1):
        raise InputError("count_max grid must be a non-empty list of integers >= 1")
    if not 0 <= healthy_max <= faulty_min:
        raise InputError(f"need 0 <= healthy_max <= faulty_min, got {healthy_max!r}, {faulty_min!r}")
    ok = np.asarray(ok, dtype=bool)
    healthy = ok & (np.asarray(range_hi) <= healthy_max + _TOL)
    degraded = ok & (np.asarray(range_lo) >= faulty_min - _TOL)
    fa = np.zeros((eps_grid.size, count_grid.size), dtype=np.int64)
    det = np.zeros_like(fa)
    for i, th in enumerate(eps_grid):
        peak = peak_counts(eps, float(th), settings)
        fault = peak[:, None] > count_grid[None, :]
        fa[i] = (fault & healthy[:, None]).sum(axis=0)
        det[i] = (fault & degraded[:, None]).sum(axis=0)
    return RocTable(mbit, label, eps_grid, count_grid, int(healthy.sum()), int(degraded.sum()), fa, det,
                    healthy_max, faulty_min)


def verdicts_at(eps: np.ndarray, settings: MonitorSettings, eps_th: float, count_max: int) -> np.ndarray:
    """Fault verdicts of every run for one threshold pair (as the campaign would have given)."""
    return peak_counts(eps, eps_th, replace(settings, eps_th=eps_th, count_max=count_max)) > count_max
