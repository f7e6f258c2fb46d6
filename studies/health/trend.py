"""Trend of one health parameter against operating time: the law chosen on the evidence, with its uncertainty.

Data: relative deviations y_i (from the nominal set) at operating hours h_i with standard errors s_i. Candidates
(``a`` is the value at entry into service), each fitted only when the visits can carry it (k ≤ n − 1):

=============  ================================  ==================================================
none           y = a                             k=1
linear         y = a + b·h                       k=2 (from 3 visits)
exponential    y = a + c·(exp(h/τ) − 1)          k=3 (from 4 visits)
power          y = a + c·h^m                     k=3 (from 4 visits)
change point   y = a + b·h + Δ·[h ≥ τ]           k=4 (from 5 visits; τ midway between two visits, searched)
=============  ================================  ==================================================

**The visits' own precision is the evidence.** Each visit's variance is its own s_i² + σ_f² (σ_f = 0.05 %: the
repeatability floor a fit's formal error does not show) plus, when a law leaves more scatter than those errors
allow, a between-visit scatter τ² estimated for that law (moment estimator: χ² = n − p with the p coefficients;
τ² = 0 when the law fits within the errors). The coefficients are weighted least squares with weights
1/(s_i² + σ_f² + τ²), their covariance from the same known variances (not rescaled), and each law's
log-likelihood ℓ uses them. Four precise visits on a line are therefore a trend; four scattered ones are not.

**Choice between laws: Akaike's criterion on that likelihood**, AIC = −2 ℓ + 2 k. AICc's small-sample correction
2k(k+1)/(n − k − 1) is undefined at k ≥ n − 1 and, at k = n − 2, adds 24 to a three-coefficient law on five visits —
it hides every curved law until the law has been seen for many visits. Laws are instead admitted by n (k ≤ n − 1),
and the likelihood carries each law's scatter. A *change point* (a sudden change claimed between two visits) must
earn it: its AIC must be lower than every other candidate's by at least :data:`CHANGE_POINT_MIN_DELTA_AICC` (2),
and its step must be significant on its own with the search over step positions accounted for (t-test, p <
:data:`P_STEP` / number of positions searched); otherwise the best smooth law is chosen.

**Significance** of the chosen law against ``none``: when the law fits within the visits' errors (χ²/(n − k) ≤ 1),
the χ² drop against ``none`` is tested on χ²(k − 1); when the visits scatter more, the F-test with the scale
estimated from the residuals (n − k degrees of freedom). p < 0.002 (0.5 % Bonferroni-split over the three monitor
parameters) is a trend; else "no significant trend".

**Hedge.** When the chosen law needs scatter beyond the errors (it does not fit them) and six visits or more are at
hand, :data:`RECENT_SHARE` of the paths follow the line through the latest :data:`RECENT_VISITS` visits — a law
outside the candidates (a two-stage wear past its knee) is then not extrapolated by the candidates alone.

**Model averaging.** Forecasts draw coefficient vectors from every admitted law in proportion to its Akaike weight
exp(−ΔAIC/2) — and, for a law whose scatter τ² was estimated, from a multivariate t with n − p degrees of freedom
(the scale itself is uncertain) — so the interval carries the doubt about which law holds.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy import stats
from scipy.optimize import brentq, least_squares

SIGMA_FLOOR = 5e-4
P_SIGNIFICANT = 0.002  # ~0.5 % per parameter, Bonferroni over the three monitor parameters
MODELS = ("none", "linear", "exponential", "power", "change_point")
#: visits each law needs (k ≤ n − 1: one more visit than coefficients)
MIN_VISITS_FOR = {"none": 1, "linear": 3, "exponential": 4, "power": 4, "change_point": 5}
#: AIC margin a change point must beat every smooth candidate by before a sudden change is claimed (docs/health.md)
CHANGE_POINT_MIN_DELTA_AICC = 2.0
#: family-wise significance of the change point's step, split (Bonferroni) over the step positions searched
P_STEP = 0.05
#: the hedge against a law outside the candidates: this share of the forecast's paths follows the line through the
#: latest RECENT_VISITS visits (a two-stage wear after its knee, a logistic before its inflection)
RECENT_SHARE = 0.2
RECENT_VISITS = 4
_H_SCALE = 1000.0  # h: power-law coefficients are per 1000 h (conditioning)


@dataclass
class ModelFit:
    name: str
    theta: np.ndarray
    cov: np.ndarray  # from the known variances s_i² + σ_f² + τ² (not rescaled)
    rss_w: float  # residuals weighted by 1/(s_i² + σ_f²): the χ² against the visits' own errors
    k: int  # coefficients (+1 for the change point's searched position)
    n: int
    tau: float | None = None  # change point (h)
    #: between-visit scatter beyond the visits' own errors (variance, relative deviation²; 0: none needed)
    scatter2: float = 0.0
    #: log-likelihood with the variances s_i² + σ_f² + τ² (constant 2π terms dropped)
    loglik: float = 0.0

    @property
    def dof(self) -> int:
        return self.n - len(self.theta)

    @property
    def ic(self) -> float:
        """Akaike's criterion on the known-variance likelihood, −2 ℓ + 2 k (inf when k ≥ n)."""
        if self.n < self.k + 1:
            return math.inf
        return -2.0 * self.loglik + 2.0 * self.k

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


def _coefficients(name: str, h: np.ndarray, y: np.ndarray, w: np.ndarray, tau: float | None,
                  x0: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Weighted least squares of one law: (θ, raw residuals y − f, raw Jacobian ∂f/∂θ) or None."""
    n = h.size
    sw = np.sqrt(w)
    if name in ("none", "linear", "change_point"):
        cols = [np.ones(n)]
        if name != "none":
            cols.append(h)
        if name == "change_point":
            cols.append((h >= tau).astype(float))
        x = np.column_stack(cols)
        theta, *_ = np.linalg.lstsq(x * sw[:, None], y * sw, rcond=None)
        return theta, y - x @ theta, x
    span = max(float(h.max()), 1.0)
    if x0 is None:
        lin = np.polyfit(h, y, 1, w=sw)
        x0 = np.array([y[0], lin[0] * span / 2, span / 2] if name == "exponential" else
                      [y[0], lin[0] * _H_SCALE, 1.5])
    lb, ub = ([-np.inf, -np.inf, span / 20], [np.inf, np.inf, 50 * span]) if name == "exponential" else \
        ([-np.inf, -np.inf, 0.3], [np.inf, np.inf, 6.0])
    x0 = np.clip(x0, np.array(lb) + 1e-12, np.array(ub) - 1e-12)

    def res(th: np.ndarray) -> np.ndarray:
        return (model_value(name, h, th) - y) * sw

    try:
        sol = least_squares(res, x0, bounds=(lb, ub), x_scale="jac", max_nfev=400)
    except (ValueError, FloatingPointError):
        return None
    return sol.x, -sol.fun / sw, sol.jac / sw[:, None]


def between_visit_scatter(resid: np.ndarray, var0: np.ndarray, dof: int) -> float:
    """τ² ≥ 0 with Σ r_i² / (var0_i + τ²) = dof (0 when the residuals fit within ``var0`` already)."""
    chi = float(np.sum(resid ** 2 / var0))
    if dof < 1 or chi <= dof:
        return 0.0
    hi = float(np.sum(resid ** 2)) / dof
    return float(brentq(lambda t: float(np.sum(resid ** 2 / (var0 + t))) - dof, 0.0, hi, xtol=1e-14 + 1e-9 * hi))


def _wls(name: str, h: np.ndarray, y: np.ndarray, var0: np.ndarray, tau: float | None = None) -> ModelFit | None:
    got = _coefficients(name, h, y, 1.0 / var0, tau)
    if got is None:
        return None
    theta, e, jac = got
    dof = h.size - theta.size
    tau2 = 0.0
    for _ in range(4):  # scatter and coefficients in turn (a few alternations converge at these sizes)
        t2 = between_visit_scatter(e, var0, dof)
        if abs(t2 - tau2) <= 1e-3 * t2 or t2 == tau2:
            break
        tau2 = t2
        got = _coefficients(name, h, y, 1.0 / (var0 + tau2), tau, x0=theta)
        if got is None:
            return None
        theta, e, jac = got
    v = var0 + tau2
    jw = jac / np.sqrt(v)[:, None]
    cov = np.linalg.pinv(jw.T @ jw)
    loglik = -0.5 * float(np.sum(e ** 2 / v + np.log(v)))
    k = theta.size + (1 if name == "change_point" else 0)
    return ModelFit(name, np.asarray(theta, float), cov, float(np.sum(e ** 2 / var0)), k, h.size, tau, tau2,
                    loglik)


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
    #: the line through the latest :data:`RECENT_VISITS` visits (None: too few visits for a separate window)
    recent: ModelFit | None = None

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
        """(n, len(h)) sampled mean paths (coefficient uncertainty, model averaging over the trend laws; a share
        :data:`RECENT_SHARE` from the line through the latest visits when there is one)."""
        if self.recent is None or RECENT_SHARE <= 0:
            return sample_mixture(self.fits, self.weights, h, n, rng)
        n_recent = round(RECENT_SHARE * n)
        out = np.empty((n, h.size))
        out[: n - n_recent] = sample_mixture(self.fits, self.weights, h, n - n_recent, rng)
        out[n - n_recent:] = _paths_of(self.recent, h, n_recent, rng)
        return out

    def band(self, h: np.ndarray, rng: np.random.Generator, n: int = 400, q: float = 0.9) -> tuple[np.ndarray, ...]:
        """(median, low, high) of the mean path at ``h`` (band q)."""
        paths = self.sample_paths(h, n, rng) if self.significant else _paths_of(self.fits["none"], h, n, rng)
        lo, hi = np.quantile(paths, [(1 - q) / 2, (1 + q) / 2], axis=0)
        return np.median(paths, axis=0), lo, hi


def sample_mixture(fits: dict[str, ModelFit], weights: dict[str, float], h: np.ndarray, n: int,
                   rng: np.random.Generator) -> np.ndarray:
    """(n, len(h)) mean paths drawn from the laws ``fits`` in proportion to ``weights`` (model averaging)."""
    names = [k for k, w in weights.items() if w > 0]
    probs = np.array([weights[k] for k in names])
    pick = rng.choice(len(names), size=n, p=probs / probs.sum())
    out = np.empty((n, h.size))
    for j, name in enumerate(names):
        idx = np.flatnonzero(pick == j)
        if idx.size:
            out[idx] = _paths_of(fits[name], h, idx.size, rng)
    return out


def _paths_of(f: ModelFit, h: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    """Mean paths of one law: θ ~ N(θ̂, cov), or a multivariate t with n − p degrees of freedom when the law's
    scatter τ² was estimated from its residuals."""
    th = rng.multivariate_normal(np.zeros(f.theta.size), _psd(f.cov), size=n, method="svd")
    if f.scatter2 > 0 and f.dof >= 1:
        th *= np.sqrt(f.dof / rng.chisquare(f.dof, size=n))[:, None]
    th += f.theta
    if f.name == "exponential":
        th[:, 2] = np.maximum(th[:, 2], 1e-6)
    return model_value(f.name, h[None, :], th, f.tau)


def _psd(c: np.ndarray) -> np.ndarray:
    c = 0.5 * (c + c.T)
    w, v = np.linalg.eigh(c)
    return (v * np.maximum(w, 0.0)) @ v.T


def fit_trend(parameter: str, hours: Sequence[float] | np.ndarray, y: Sequence[float] | np.ndarray,
              stderr: Sequence[float | None] | np.ndarray, *, floor: float = SIGMA_FLOOR) -> Trend:
    """Choose the trend of one parameter (see the module docstring). ``floor``: the repeatability floor σ_f in the
    unit of ``y`` (default: 0.05 % for relative deviations; an effect's parameter trended in its own unit has its
    own)."""
    h = np.asarray(hours, float)
    yv = np.asarray(y, float)
    s = np.array([v if v is not None and math.isfinite(v) else 0.0 for v in stderr], float)
    var0 = s ** 2 + floor ** 2
    n = h.size
    fits: dict[str, ModelFit] = {}
    for name in ("none", "linear", "exponential", "power"):
        if n >= MIN_VISITS_FOR[name]:
            f = _wls(name, h, yv, var0)
            if f is not None:
                fits[name] = f
    if n >= MIN_VISITS_FOR["change_point"]:
        best_cp = None
        for j in range(1, n - 1):  # a step between visits j-1 and j, at least two visits after it
            f = _wls("change_point", h, yv, var0, 0.5 * (h[j - 1] + h[j]))
            if f is not None and (best_cp is None or f.ic < best_cp.ic):
                best_cp = f
        if best_cp is not None:
            fits["change_point"] = best_cp
    ic = {k: f.ic for k, f in fits.items()}
    best_name = min(ic, key=lambda k: ic[k])
    cp_note = None
    if best_name == "change_point":
        cp_note = change_point_refusal(fits, n)
        if cp_note is not None:
            best_name = min((k for k in ic if k != "change_point"), key=lambda k: ic[k])
    best = fits[best_name]
    p = trend_p_value(best, h, yv, var0) if best_name != "none" else 1.0
    significant = best_name != "none" and p < P_SIGNIFICANT
    recent = None
    if significant and n >= RECENT_VISITS + 2 and best_name != "change_point" and best.scatter2 > 0:
        recent = _wls("linear", h[-RECENT_VISITS:], yv[-RECENT_VISITS:], var0[-RECENT_VISITS:])
    return Trend(parameter, best, fits, significant, p, akaike_weights(fits), cp_note, recent)


def akaike_weights(fits: dict[str, ModelFit]) -> dict[str, float]:
    """exp(−ΔAIC/2) over the trend laws (not ``none``), normalised; laws under 0.1 % are left out."""
    trend_models = {k: f.ic for k, f in fits.items() if k != "none" and math.isfinite(f.ic)}
    if not trend_models:
        return {}
    amin = min(trend_models.values())
    raw = {k: math.exp(-0.5 * (v - amin)) for k, v in trend_models.items()}
    tot = sum(raw.values())
    return {k: v / tot for k, v in raw.items() if v / tot > 1e-3}


def trend_p_value(best: ModelFit, h: np.ndarray, y: np.ndarray, var0: np.ndarray) -> float:
    """p of ``best`` against ``none``: χ² drop on χ²(k − 1) when ``best`` fits within the visits' errors, else the
    F-test with the scale from its residuals (see the module docstring)."""
    w = 1.0 / var0
    mean = float(np.sum(w * y) / np.sum(w))
    chi_none = float(np.sum(w * (y - mean) ** 2))
    df1 = best.k - 1
    df2 = best.n - best.k
    if df1 < 1 or df2 < 1:
        return 1.0
    drop = max(chi_none - best.rss_w, 0.0)
    reduced = best.rss_w / df2
    if reduced <= 1.0:
        return float(stats.chi2.sf(drop, df1))
    return float(stats.f.sf((drop / df1) / reduced, df1, df2))


def change_point_refusal(fits: dict[str, ModelFit], n: int) -> str | None:
    """Why the best-fitting change point is not claimed (None: it earned it). See the module docstring."""
    cp = fits["change_point"]
    smooth = {k: f.ic for k, f in fits.items() if k != "change_point" and math.isfinite(f.ic)}
    if not smooth:
        return None
    runner = min(smooth, key=lambda k: smooth[k])
    margin = smooth[runner] - cp.ic
    if margin < CHANGE_POINT_MIN_DELTA_AICC:
        return (f"a sudden change at {cp.tau:g} h fits better than {runner} by ΔAIC {margin:.1f} only (a margin of "
                f"{CHANGE_POINT_MIN_DELTA_AICC:g} is required): not claimed")
    var = float(cp.cov[2, 2])
    positions = max(n - 2, 1)
    if var > 0:
        t = abs(float(cp.theta[2])) / math.sqrt(var)
        p = float(2 * stats.t.sf(t, max(n - cp.k, 1)))
        if p >= P_STEP / positions:
            return (f"a sudden change at {cp.tau:g} h fits better than {runner} by ΔAIC {margin:.1f}, but its step "
                    f"is not significant over the {positions} positions searched (p = {p:.2g} ≥ {P_STEP:g}/"
                    f"{positions}): not claimed")
    return None
