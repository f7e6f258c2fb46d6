"""Agreement metrics: fit % (1 − NRMSE, as MATLAB ``compare``), RMSE, and the paper's normalised error.

The seed paper (Sec. 3.2) observes that the model error grows linearly with the amplitude of the variable,
Eq. (4):  ``|y_md − y_hw| = e0 + kerr·|y_hw|``, and normalises the error by that law, Eq. (5):

    ε(t) = |y_md − y_hw| / (|y_hw| + e0/kerr)

``e0`` (bias, in the variable's unit) and ``kerr`` (gain, 1) are fitted to the record per Eq. (4) by
non-negative least squares, or given (the paper's monitor uses e0z = 0.75 mm, kerr = 0.075 for z3,
Sec. 4.1). ε is ``board_config.error_law.normalised_error(model, measured, e0, kerr)`` — the same function as the
board's monitor (Eq. 11), re-exported here: undefined (NaN) when the fit returns ``kerr = 0`` (the error does not
grow with amplitude). The threshold ε_th comes from the monitor's settings (``board_config.load_monitor_settings``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import nnls

from board_config import load_monitor_settings
from board_config.error_law import normalised_error  # the one Eq. 5/11 implementation (the monitor uses it too)
from board_config.errors import InputError
from board_config.json_values import JsonFields


def _as_float_pair(measured: np.ndarray, model: np.ndarray) -> np.ndarray:
    """Measurement and model as one ``(2, N)`` float array: integer records become numbers together (no
    difference is ever taken in a wrapping machine type)."""
    return np.asarray([measured, model], float)


def fit_percent(measured: np.ndarray, model: np.ndarray) -> float:
    """MATLAB-style fit: ``100·(1 − ‖y − ŷ‖ / ‖y − mean(y)‖)`` (%). 100 is perfect; it can be negative."""
    y, y_md = _as_float_pair(measured, model)
    e = y - y_md
    den = float(np.linalg.norm(y - y.mean()))
    if den == 0.0:
        return math.nan
    return 100.0 * (1.0 - float(np.linalg.norm(e)) / den)


def nrmse(measured: np.ndarray, model: np.ndarray) -> float:
    """``‖y − ŷ‖ / ‖y − mean(y)‖`` (1): the RMS error relative to the signal's own variation."""
    y, y_md = _as_float_pair(measured, model)
    den = float(np.linalg.norm(y - y.mean()))
    return float(np.linalg.norm(y - y_md) / den) if den > 0 else math.nan


def rmse(measured: np.ndarray, model: np.ndarray) -> float:
    y, y_md = _as_float_pair(measured, model)
    return float(np.sqrt(np.mean((y - y_md) ** 2)))


@dataclass(frozen=True)
class Eq4Fit:
    """Eq. (4) fitted: ``|e| ≈ e0 + kerr·|y_hw|`` with e0, kerr ≥ 0; ``r2`` is the fit's coefficient of
    determination (how well the error really follows the amplitude law)."""

    e0: float
    kerr: float
    r2: float
    source: str  # "fitted (Eq. 4)" or "given"


def fit_eq4(measured: np.ndarray, model: np.ndarray) -> Eq4Fit:
    """Fit Eq. (4) by non-negative least squares of ``|y_md − y_hw|`` on ``[1, |y_hw|]``."""
    y_hw, y_md = _as_float_pair(measured, model)
    y = np.abs(y_hw)
    e = np.abs(y_md - y_hw)
    (e0, k), _ = nnls(np.column_stack([np.ones_like(y), y]), e)
    pred = e0 + k * y
    ss = float(np.sum((e - e.mean()) ** 2))
    r2 = 1.0 - float(np.sum((e - pred) ** 2)) / ss if ss > 0 else math.nan
    return Eq4Fit(float(e0), float(k), r2, "fitted (Eq. 4)")


@dataclass(frozen=True)
class EpsStats:
    """Summary of ε(t) over a stretch: mean, standard deviation, 95th percentile, maximum, and the fraction of
    samples above the monitor's threshold ε_th (Table 3: 0.225)."""

    mean: float
    std: float
    p95: float
    max: float
    frac_above_th: float

    @classmethod
    def of(cls, eps: np.ndarray, eps_th: float) -> EpsStats:
        e = eps[np.isfinite(eps)]
        if e.size == 0:
            return cls(*(math.nan,) * 5)
        return cls(float(e.mean()), float(e.std()), float(np.percentile(e, 95)), float(e.max()),
                   float(np.mean(e > eps_th)))


@dataclass(frozen=True)
class ChannelMetrics(JsonFields):
    """Agreement of one channel (free-run simulation unless stated). Units: the channel's SI unit."""

    channel: str
    unit: str
    n_samples: int
    skip_s: float
    fit_pct: float
    nrmse: float
    rmse: float
    max_abs_error: float
    mean_error: float  # mean of measured − model (bias)
    eq4_fitted: Eq4Fit
    eps_fitted: EpsStats
    eq4_given: Eq4Fit | None
    eps_given: EpsStats | None


def channel_metrics(channel: str, unit: str, t: np.ndarray, measured: np.ndarray, model: np.ndarray, *,
                    skip_s: float = 0.0, given: tuple[float, float] | None = None, eps_th: float | None = None
                    ) -> ChannelMetrics:
    """All metrics of one channel over ``t >= t[0] + skip_s`` (transient skip, as nonlinearbenchmark.org);
    ``eps_th`` defaults to the monitor's threshold (Table 3, ``board_config/monitor.toml``)."""
    if eps_th is None:
        eps_th = load_monitor_settings().eps_th
    k = np.asarray(t) >= t[0] + skip_s
    if np.count_nonzero(k) < 2:
        raise InputError(f"channel '{channel}': transient skip {skip_s} s leaves fewer than 2 samples")
    y, yh = _as_float_pair(measured, model)[:, k]
    e = y - yh
    fit4 = fit_eq4(y, yh)
    eps_f = EpsStats.of(normalised_error(yh, y, fit4.e0, fit4.kerr), eps_th)
    g4 = eps_g = None
    if given is not None:
        g4 = Eq4Fit(float(given[0]), float(given[1]), math.nan, "given")
        eps_g = EpsStats.of(normalised_error(yh, y, g4.e0, g4.kerr), eps_th)
    return ChannelMetrics(
        channel=channel, unit=unit, n_samples=int(y.size), skip_s=float(skip_s), fit_pct=fit_percent(y, yh),
        nrmse=nrmse(y, yh), rmse=rmse(y, yh), max_abs_error=float(np.max(np.abs(e))), mean_error=float(e.mean()),
        eq4_fitted=fit4, eps_fitted=eps_f, eq4_given=g4, eps_given=eps_g,
    )


@dataclass(frozen=True)
class FrfMetrics:
    """Agreement of a frequency response: complex fit % ``100·(1 − ‖H − Ĥ‖/‖H‖)``, amplitude error (dB) and
    phase error (deg) statistics, and where the peaks sit (resonance shift)."""

    channel: str
    unit: str
    fit_pct: float
    amp_err_db_rms: float
    amp_err_db_max: float
    phase_err_deg_rms: float
    phase_err_deg_max: float
    peak_measured_Hz: float
    peak_model_Hz: float


def frf_metrics(channel: str, unit: str, f: np.ndarray, measured: np.ndarray, model: np.ndarray) -> FrfMetrics:
    h, hm = np.asarray([measured, model], complex)  # both at once: an integer record cannot wrap around
    den = float(np.linalg.norm(h))
    fit = 100.0 * (1.0 - float(np.linalg.norm(h - hm)) / den) if den > 0 else math.nan
    with np.errstate(divide="ignore", invalid="ignore"):
        db = 20 * np.log10(np.abs(hm) / np.abs(h))
    ph = np.degrees(np.angle(hm / np.where(h == 0, 1, h)))
    db_f = db[np.isfinite(db)]
    return FrfMetrics(
        channel, unit, fit,
        float(np.sqrt(np.mean(db_f ** 2))) if db_f.size else math.nan,
        float(np.max(np.abs(db_f))) if db_f.size else math.nan,
        float(np.sqrt(np.mean(ph ** 2))), float(np.max(np.abs(ph))),
        float(f[int(np.argmax(np.abs(h)))]), float(f[int(np.argmax(np.abs(hm)))]),
    )
