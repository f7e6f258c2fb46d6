"""Trend of one health parameter against operating time: the model chosen on the evidence, with its uncertainty.

Data: relative deviations y_i (from the nominal set) at operating hours h_i with standard errors s_i. Candidates
(``a`` is the value at entry into service):

=============  ================================  ===
none           y = a                             k=1
linear         y = a + b·h                       k=2
exponential    y = a + c·(exp(h/τ) − 1)          k=3
power          y = a + c·h^m                     k=3
change point   y = a + b·h + Δ·[h ≥ τ]           k=4 (τ: midway between two visits, searched)
=============  ================================  ===

Weighted least squares with weights 1/(s_i² + σ_f²) (σ_f = 0.05 %: the repeatability floor a fit's formal error
does not show), the residual scale estimated from the data. The model with the lowest AICc wins — except that a
*change point* (a sudden change claimed between two visits) must earn it: its AICc must be lower than every other
candidate's by at least :data:`CHANGE_POINT_MIN_DELTA_AICC` (2), and its step must be significant on its own with
the search over step positions accounted for (t-test, p < :data:`P_STEP` / number of positions searched); otherwise
the best smooth law is chosen (a linear life scored a change point by ΔAICc 0.3 on the ``aging`` run). A trend is
*significant* when the F-test of the chosen model against ``none`` gives p < 0.002 (0.5 % Bonferroni-split over the
three monitor parameters; else "no significant trend").
Forecasts draw coefficient vectors from each candidate's N(θ̂, cov) in proportion to the Akaike weights of the trend
models (model averaging: the interval carries the doubt about which law holds).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy import stats
from scipy.optimize import least_squares

SIGMA_FLOOR = 5e-4
P_SIGNIFICANT = 0.002  # ~0.5 % per parameter, Bonferroni over the three monitor parameters
MODELS = ("none", "linear", "exponential", "power", "change_point")
#: AICc margin a change point must beat every smooth candidate by before a sudden change is claimed (docs/health.md)
CHANGE_POINT_MIN_DELTA_AICC = 2.0
#: family-wise significance of the change point's step, split (Bonferroni) over the step positions searched
P_STEP = 0.05


@dataclass
class ModelFit:
    name: str
    theta: np.ndarray
    cov: np.ndarray
    rss_w: float  # weighted residual sum of squares
    k: int
    n: int
    tau: float | None = None  # change point (h)

    @property
    def aicc(self) -> float:
        n, k = self.n, self.k
        if n - k - 1 <= 0:
            return math.inf
        return n * math.log(max(self.rss_w, 1e-300) / n) + 2 * k + 2 * k * (k + 1) / (n - k - 1)

    def predict(self, h: np.ndarray, theta: np.ndarray | None = None) -> np.ndarray:
        return model_value(self.name, np.asarray(h, float), self.theta if theta is None else theta, self.tau)


def model_value(name: str, h: np.ndarray, th: np.ndarray, tau: float | None = None) -> np.ndarray:
    """Model ``name`` at hours ``h`` for coefficient rows ``th`` (..., k) → broadcast (..., len(h))."""
    th = np.asarray(th, float)
    h = np.asarray(h, float)
    a = th[..., 0:1]
    if name == "none":
        return a + 0.0 * h
    if name == "linear":
        return a + th[..., 1:2] * h
    if name == "exponential":
        c, tau_e = th[..., 1:2], np.maximum(th[..., 2:3], 1e-9)
        return a + c * np.expm1(np.minimum(h / tau_e, 50.0))
    if name == "power":
        c, m = th[..., 1:2], th[..., 2:3]
        return a + c * np.power(np.maximum(h, 0.0) / _H_SCALE, m)
    if name == "change_point":
        return a + th[..., 1:2] * h + th[..., 2:3] * (h >= (tau if tau is not None else np.inf))
    raise ValueError(name)


_H_SCALE = 1000.0  # h: power-law coefficients are per 1000 h (conditioning)


def _wls(name: str, h: np.ndarray, y: np.ndarray, w: np.ndarray, tau: float | None = None) -> ModelFit | None:
    n = h.size
    sw = np.sqrt(w)
    if name in ("none", "linear", "change_point"):
        cols = [np.ones(n)]
        if name != "none":
            cols.append(h)
        if name == "change_point":
            cols.append((h >= tau).astype(float))
        x = np.column_stack(cols)
        xw = x * sw[:, None]
        theta, *_ = np.linalg.lstsq(xw, y * sw, rcond=None)
        r = (y - x @ theta) * sw
        k = x.shape[1] + (1 if name == "change_point" else 0)
        jtj = xw.T @ xw
    else:
        span = max(float(h.max()), 1.0)
        lin = np.polyfit(h, y, 1, w=sw)
        if name == "exponential":
            x0 = [y[0], lin[0] * span / 2, span / 2]
            lb, ub = [-np.inf, -np.inf, span / 20], [np.inf, np.inf, 50 * span]
        else:
            x0 = [y[0], lin[0] * _H_SCALE, 1.5]
            lb, ub = [-np.inf, -np.inf, 0.3], [np.inf, np.inf, 6.0]

        def res(th):
            return (model_value(name, h, th)[...] - y) * sw

        try:
            sol = least_squares(res, x0, bounds=(lb, ub), x_scale="jac", max_nfev=400)
        except (ValueError, FloatingPointError):
            return None
        theta, r = sol.x, sol.fun
        jtj = sol.jac.T @ sol.jac
        k = 3
    dof = max(n - len(theta), 1)
    scale = float(r @ r) / dof
    try:
        cov = np.linalg.pinv(jtj) * max(scale, 1e-12)
    except np.linalg.LinAlgError:
        return None
    return ModelFit(name, np.asarray(theta, float), cov, float(r @ r), k, n, tau)


@dataclass
class Trend:
    """The chosen trend of one parameter and the candidates it was chosen from."""

    parameter: str
    best: ModelFit
    fits: dict[str, ModelFit]
    significant: bool
    p_value: float
    weights: dict[str, float] = field(default_factory=dict)
    #: why a change point that fitted best was not claimed (None: it was not the best fit, or it was claimed)
    change_point_note: str | None = None

    @property
    def model(self) -> str:
        return self.best.name if self.significant else "none"

    def rate_per_100h(self, h: float) -> float:
        """Slope of the chosen model at ``h`` (relative deviation per 100 h)."""
        m = self.best
        if not self.significant:
            lin = self.fits.get("linear")
            return float(lin.theta[1] * 100) if lin is not None else 0.0
        d = 1.0
        return float((m.predict(np.array([h + d]))[0] - m.predict(np.array([h - d]))[0]) / (2 * d) * 100)

    def sample_paths(self, h: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
        """(n, len(h)) sampled mean paths (coefficient uncertainty, model averaging over the trend models)."""
        names = [k for k, w in self.weights.items() if w > 0]
        probs = np.array([self.weights[k] for k in names])
        probs = probs / probs.sum()
        pick = rng.choice(len(names), size=n, p=probs)
        out = np.empty((n, h.size))
        for j, name in enumerate(names):
            idx = np.flatnonzero(pick == j)
            if idx.size == 0:
                continue
            f = self.fits[name]
            th = rng.multivariate_normal(f.theta, _psd(f.cov), size=idx.size, method="svd")
            if name == "exponential":
                th[:, 2] = np.maximum(th[:, 2], 1e-6)
            out[idx] = model_value(name, h[None, :], th, f.tau)
        return out

    def band(self, h: np.ndarray, rng: np.random.Generator, n: int = 400, q: float = 0.9) -> tuple[np.ndarray, ...]:
        """(median, low, high) of the mean path plus the observation scatter at ``h`` (prediction band, q)."""
        paths = self.sample_paths(h, n, rng) if self.significant else \
            _paths_of(self.fits["none"], h, n, rng)
        scatter = math.sqrt(self.best.rss_w / max(self.best.n - len(self.best.theta), 1)) * 0  # mean band
        lo, hi = np.quantile(paths, [(1 - q) / 2, (1 + q) / 2], axis=0)
        return np.median(paths, axis=0), lo - scatter, hi + scatter


def _paths_of(f: ModelFit, h: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    th = rng.multivariate_normal(f.theta, _psd(f.cov), size=n, method="svd")
    return model_value(f.name, h[None, :], th, f.tau)


def _psd(c: np.ndarray) -> np.ndarray:
    c = 0.5 * (c + c.T)
    w, v = np.linalg.eigh(c)
    return (v * np.maximum(w, 0.0)) @ v.T


def fit_trend(parameter: str, hours: Sequence[float] | np.ndarray, y: Sequence[float] | np.ndarray,
              stderr: Sequence[float | None] | np.ndarray) -> Trend:
    """Choose the trend of one parameter (see the module docstring)."""
    h = np.asarray(hours, float)
    yv = np.asarray(y, float)
    s = np.array([v if v is not None and math.isfinite(v) else 0.0 for v in stderr], float)
    w = 1.0 / (s ** 2 + SIGMA_FLOOR ** 2)
    n = h.size
    fits: dict[str, ModelFit] = {}
    for name in ("none", "linear", "exponential", "power"):
        if n >= {"none": 1, "linear": 3, "exponential": 5, "power": 5}[name]:
            f = _wls(name, h, yv, w)
            if f is not None:
                fits[name] = f
    if n >= 5:
        best_cp = None
        for j in range(1, n - 1):  # at least one visit before, two after... a step between visits j-1 and j
            tau = 0.5 * (h[j - 1] + h[j])
            f = _wls("change_point", h, yv, w, tau)
            if f is not None and (best_cp is None or f.rss_w < best_cp.rss_w):
                best_cp = f
        if best_cp is not None:
            fits["change_point"] = best_cp
    aicc = {k: f.aicc for k, f in fits.items()}
    best_name = min(aicc, key=lambda k: aicc[k])
    cp_note = None
    if best_name == "change_point":
        cp_note = change_point_refusal(fits, n)
        if cp_note is not None:
            best_name = min((k for k in aicc if k != "change_point"), key=lambda k: aicc[k])
    best = fits[best_name]
    p = 1.0
    if best_name != "none" and "none" in fits:
        f0 = fits["none"]
        df1 = best.k - f0.k
        df2 = max(n - best.k, 1)
        if best.rss_w > 0 and df1 > 0:
            fstat = ((f0.rss_w - best.rss_w) / df1) / (best.rss_w / df2)
            p = float(stats.f.sf(fstat, df1, df2))
        elif best.rss_w <= 0:
            p = 0.0
    significant = best_name != "none" and p < P_SIGNIFICANT
    trend_models = {k: v for k, v in aicc.items() if k != "none" and math.isfinite(v)}
    weights: dict[str, float] = {}
    if trend_models:
        amin = min(trend_models.values())
        raw = {k: math.exp(-0.5 * (v - amin)) for k, v in trend_models.items()}
        tot = sum(raw.values())
        weights = {k: v / tot for k, v in raw.items() if v / tot > 1e-3}
    return Trend(parameter, best, fits, significant, p, weights, cp_note)


def change_point_refusal(fits: dict[str, ModelFit], n: int) -> str | None:
    """Why the best-fitting change point is not claimed (None: it earned it). See the module docstring."""
    cp = fits["change_point"]
    smooth = {k: f.aicc for k, f in fits.items() if k != "change_point" and math.isfinite(f.aicc)}
    if not smooth:
        return None
    runner = min(smooth, key=lambda k: smooth[k])
    margin = smooth[runner] - cp.aicc
    if margin < CHANGE_POINT_MIN_DELTA_AICC:
        return (f"a sudden change at {cp.tau:g} h fits better than {runner} by ΔAICc {margin:.1f} only (a margin of "
                f"{CHANGE_POINT_MIN_DELTA_AICC:g} is required): not claimed")
    var = float(cp.cov[2, 2])
    positions = max(n - 2, 1)
    if var > 0:
        t = abs(float(cp.theta[2])) / math.sqrt(var)
        p = float(2 * stats.t.sf(t, max(n - cp.k, 1)))
        if p >= P_STEP / positions:
            return (f"a sudden change at {cp.tau:g} h fits better than {runner} by ΔAICc {margin:.1f}, but its step "
                    f"is not significant over the {positions} positions searched (p = {p:.2g} ≥ {P_STEP:g}/"
                    f"{positions}): not claimed")
    return None
