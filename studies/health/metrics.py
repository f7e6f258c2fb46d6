"""Prognostic metrics as NASA ProgPy (``progpy.metrics``) and the PHM literature (Saxena et al. 2010) define them.

A *prediction* at time t (h) is a sample of time-of-event (ToE, here the operating hours at which the board's
monitor first says FAULT). The ground truth t_EOL is the hours of the first FAULT visit.

* :func:`alpha_lambda` — ProgPy ``alpha_lambda``: at t_λ = t_P + λ·(t_EOL − t_P) (t_P the first prediction), on the
  first prediction made at or after t_λ (ProgPy: "at this time or the next prediction following"), is the share of
  the ToE sample inside t_EOL ± α·(t_EOL − t) at least β (ProgPy's default β = 0.5)? One definition
  (:func:`alpha_lambda_point`) for the challenge and ``shm health --evaluate``.
* :func:`prognostic_horizon` — ProgPy ``prognostic_horizon``: t_EOL minus the first prediction time from which every
  later prediction meets the α criterion (None if the last one does not).
* :func:`interval_covers` — does the 90 % interval (5–95 % quantiles) of a prediction hold the truth?
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np


def within_alpha(samples: np.ndarray, t: float, t_eol: float, alpha: float, beta: float = 0.5) -> bool:
    """The ProgPy α criterion of one prediction made at ``t``: share of ToE samples within t_EOL ± α(t_EOL − t)
    ≥ β."""
    s = np.asarray(samples, float)
    if s.size == 0:
        return False
    half = alpha * max(t_eol - t, 0.0)
    inside = (s >= t_eol - half - 1e-9) & (s <= t_eol + half + 1e-9)
    return float(np.mean(inside)) >= beta


def alpha_lambda(times: Sequence[float], samples: Sequence[np.ndarray], t_eol: float, *, lam: float = 0.5,
                 alpha: float = 0.2, beta: float = 0.5) -> bool | None:
    """ProgPy's α-λ accuracy for one life at one λ: :func:`alpha_lambda_point`'s verdict — the prediction judged is
    the first one made at or after t_λ (and before t_EOL); None without one. The challenge and ``--evaluate`` both
    use this one definition."""
    ok = alpha_lambda_point(times, samples, t_eol, lam=lam, alpha=alpha, beta=beta)["ok"]
    return None if ok is None else bool(ok)


def prognostic_horizon(times: Sequence[float], samples: Sequence[np.ndarray], t_eol: float, *, alpha: float = 0.2,
                       beta: float = 0.5) -> float | None:
    """ProgPy's prognostic horizon (h): t_EOL − the first time from which every prediction meets the α criterion."""
    ok = [within_alpha(s, t, t_eol, alpha, beta) for t, s in zip(times, samples)]
    first = None
    for i in range(len(ok) - 1, -1, -1):
        if not ok[i]:
            break
        first = i
    return None if first is None else t_eol - times[first]


def interval_covers(interval: Sequence[float | None] | None, truth: float) -> bool:
    if interval is None or interval[0] is None:
        return False
    lo, hi = interval[0], interval[1] if interval[1] is not None else np.inf
    return lo <= truth <= hi


def relative_accuracy(samples: np.ndarray, t: float, t_eol: float) -> float | None:
    """Relative accuracy of one prediction made at ``t`` (Saxena et al. 2010; ProgPy's ``relative_accuracy``):
    1 − |RUL* − RUL| / RUL*, RUL* = t_EOL − t the true remaining life, RUL the prediction's central tendency —
    here the *median* of the ToE samples minus t (paths that never trip within the horizon make the mean infinite).
    None when RUL* ≤ 0 or the median is beyond the horizon."""
    s = np.asarray(samples, float)
    r_true = t_eol - t
    if s.size == 0 or r_true <= 0:
        return None
    med = float(np.median(s))
    if not np.isfinite(med):
        return None
    return 1.0 - abs(r_true - (med - t)) / r_true


def alpha_lambda_point(times: Sequence[float], samples: Sequence[np.ndarray], t_eol: float, *, lam: float,
                       alpha: float = 0.2, beta: float = 0.5) -> dict[str, float | bool | None]:
    """ProgPy's α-λ at one λ point: t_λ = t_P + λ·(t_EOL − t_P) (t_P the first prediction), judged on the first
    prediction made at or after t_λ (ProgPy's ``alpha_lambda``: "at this time or the next prediction following"),
    before t_EOL. Returns ``lambda``, ``t_lambda_hours``, ``prediction_hours`` (None: no prediction there), ``ok``
    (None without one) and that prediction's ``relative_accuracy``."""
    out: dict[str, float | bool | None] = {"lambda": lam, "t_lambda_hours": None, "prediction_hours": None,
                                           "ok": None, "relative_accuracy": None}
    if not times:
        return out
    t_lam = times[0] + lam * (t_eol - times[0])
    out["t_lambda_hours"] = t_lam
    idx = next((i for i, t in enumerate(times) if t >= t_lam - 1e-9 and t < t_eol), None)
    if idx is None:
        return out
    out.update({"prediction_hours": times[idx], "ok": within_alpha(samples[idx], times[idx], t_eol, alpha, beta),
                "relative_accuracy": relative_accuracy(samples[idx], times[idx], t_eol)})
    return out
