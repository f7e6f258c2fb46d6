"""Trend of one health parameter against operating time: the law chosen on the evidence, with its uncertainty.

Data: relative deviations y_i (from the nominal set) at operating hours h_i with standard errors s_i. Candidates
(``a`` is the value at entry into service), each fitted only when the visits can carry it (k ≤ n − 1):

=============  ================================  ==================================================
none           y = a                             k=1
linear         y = a + b·h                       k=2 (from 3 visits)
exponential    y = a + c·(exp(h/τ) − 1)          k=3 (from 4 visits)
power          y = a + c·h^m                     k=3 (from 4 visits)
logistic       y = a + A·(σ((h−m)/w) − σ(−m/w))  k=4 (from 5 visits; w ≥ the visit spacing, m ≤ 4 × span)
two stage      y = a + b·h + c·max(h − κ, 0)     k=4 (from 5 visits; κ at a visit or midway, searched)
change point   y = a + b·h + Δ·[h ≥ τ]           k=4 (from 5 visits; τ midway between two visits, searched)
=============  ================================  ==================================================

The logistic (a wear that accelerates, then saturates) and the two-stage wear (one rate, then another from a knee)
are the shapes of the issue's out-of-family lives; a searched position (τ, κ) counts as a coefficient.

**The visits' own precision is the evidence.** Each visit's variance is its own s_i² + σ_f² (σ_f = 0.05 %: the
repeatability floor a fit's formal error does not show) plus, when a law leaves more scatter than those errors
allow, a between-visit scatter τ² estimated for that law (moment estimator: χ² = n − p with the p coefficients;
τ² = 0 when the law fits within the errors). The coefficients are weighted least squares with weights
1/(s_i² + σ_f² + τ²), their covariance from the same known variances (not rescaled), and each law's
log-likelihood ℓ uses them. Four precise visits on a line are therefore a trend; four scattered ones are not.

**Choice between laws: Akaike's criterion on that likelihood**, AIC = −2 ℓ + 2 k. AICc's small-sample correction
2k(k+1)/(n − k − 1) is undefined at k ≥ n − 1 and, at k = n − 2, adds 24 to a three-coefficient law on five visits —
it hides every curved law until the law has been seen for many visits (measured with the logistic and two-stage laws
among the candidates: the challenge's out-of-family lives 31/42 covered with AICc weights against 35/44 with AIC,
in-family synthetic shapes 97 % against 100 %). Laws are instead admitted by n (k ≤ n − 1), and the likelihood
carries each law's scatter. A *change point* (a sudden change claimed between two visits) must
earn it: its AIC must be lower than every other candidate's by at least :data:`CHANGE_POINT_MIN_DELTA_AICC` (2),
and its step must be significant on its own with the search over step positions accounted for (t-test, p <
:data:`P_STEP` / number of positions searched); otherwise the best smooth law is chosen.

**Significance** of the chosen law against ``none``: when the law fits within the visits' errors (χ²/(n − k) ≤ 1),
the χ² drop against ``none`` is tested on χ²(k − 1); when the visits scatter more, the F-test with the scale
estimated from the residuals (n − k degrees of freedom). p < 0.002 (0.5 % Bonferroni-split over the three monitor
parameters) is a trend; else "no significant trend".

**Hedge.** When the chosen law needs scatter beyond the errors (it does not fit them) and six visits or more are at
hand, :data:`RECENT_SHARE` of the paths follow the line through the latest :data:`RECENT_VISITS` visits — a law
outside the candidates (a wear whose rate changed again) is then not extrapolated by the candidates alone.

**The latest-visit check.** The laws fitted to every visit but the latest predict the latest one (their mixture's
mean paths plus the visit's own variance and the chosen law's scatter); when it falls outside that 90 % band by a
ratio r (the miss over the band's half-width on its side), the forecast paths' spread around their median is
multiplied by r (at most :data:`CHECK_MAX_FACTOR`). It needs no assumption on the shape: right after a knee or an
inflection no law fitted so far represents the new regime, and the miss says by how much to trust them less.

**Model averaging.** Forecasts draw coefficient vectors from every admitted law in proportion to its Akaike weight
exp(−ΔAIC/2) — and, for a law whose scatter τ² was estimated, from a multivariate t with n − p degrees of freedom
(the scale itself is uncertain) — so the interval carries the doubt about which law holds.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import brentq, least_squares
from scipy.special import chdtrc, expit, fdtrc, stdtr  # χ², F, t survival functions: what scipy.stats calls

SIGMA_FLOOR = 5e-4
P_SIGNIFICANT = 0.002  # ~0.5 % per parameter, Bonferroni over the three monitor parameters
#: visits each law needs (k ≤ n − 1: one more visit than coefficients)
MIN_VISITS_FOR = {"none": 1, "linear": 3, "exponential": 4, "power": 4, "logistic": 5, "two_stage": 5,
                  "change_point": 5}
#: laws whose position (a change point's step, a two-stage wear's knee) is searched over a grid and counted in k
SEARCHED = ("change_point", "two_stage")
#: AIC margin a change point must beat every smooth candidate by before a sudden change is claimed (docs/health.md)
CHANGE_POINT_MIN_DELTA_AICC = 2.0
#: family-wise significance of the change point's step, split (Bonferroni) over the step positions searched
P_STEP = 0.05
#: the hedge against a law outside the candidates: this share of the forecast's paths follows the line through the
#: latest RECENT_VISITS visits (a two-stage wear after its knee, a logistic before its inflection)
RECENT_SHARE = 0.2
RECENT_VISITS = 4
_H_SCALE = 1000.0  # h: power-law coefficients are per 1000 h (conditioning)
#: the latest-visit check (:func:`latest_visit_check`) from this many visits on; its spread factor at most
#: CHECK_MAX_FACTOR and its Monte Carlo seed (the check is deterministic)
CHECK_MIN_VISITS = 5
CHECK_MAX_FACTOR = 30.0
CHECK_SEED = 2028
#: a logistic's midpoint is searched up to this many times the span of the visits (beyond, it is an exponential)
LOGISTIC_MID_SPAN = 4.0


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
    if name == "two_stage":
        return a + th[..., 1:2] * h + th[..., 2:3] * np.maximum(h - (tau if tau is not None else np.inf), 0.0)
    if name == "logistic":
        return a + th[..., 1:2] * logistic_rise(h, th[..., 2:3], th[..., 3:4])
    raise ValueError(name)


def logistic_rise(h: np.ndarray, mid: np.ndarray | float, width: np.ndarray | float) -> np.ndarray:
    """σ((h − mid)/width) − σ(−mid/width): a logistic step of unit size that is 0 at entry into service."""
    w = np.maximum(width, 1e-9)
    return expit((h - mid) / w) - expit(-mid / w)


def _coefficients(name: str, h: np.ndarray, y: np.ndarray, w: np.ndarray, tau: float | None,
                  x0: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Weighted least squares of one law: (θ, raw residuals y − f, raw Jacobian ∂f/∂θ) or None."""
    n = h.size
    sw = np.sqrt(w)
    if name in ("none", "linear", "change_point", "two_stage"):
        cols = [np.ones(n)]
        if name != "none":
            cols.append(h)
        if name == "change_point":
            cols.append((h >= tau).astype(float))
        if name == "two_stage":
            cols.append(np.maximum(h - (tau if tau is not None else np.inf), 0.0))
        x = np.column_stack(cols)
        theta, *_ = np.linalg.lstsq(x * sw[:, None], y * sw, rcond=None)
        return theta, y - x @ theta, x
    span = max(float(h.max()), 1.0)
    if name == "logistic":
        lb, ub = logistic_bounds(h)
        x0 = _logistic_start(h, y, sw, lb, ub) if x0 is None else x0
    else:
        if x0 is None:
            lin = np.polyfit(h, y, 1, w=sw)
            x0 = np.array([y[0], lin[0] * span / 2, span / 2] if name == "exponential" else
                          [y[0], lin[0] * _H_SCALE, 1.5])
        lb, ub = ([-np.inf, -np.inf, span / 20], [np.inf, np.inf, 50 * span]) if name == "exponential" else \
            ([-np.inf, -np.inf, 0.3], [np.inf, np.inf, 6.0])
    x0 = np.clip(x0, np.array(lb) + 1e-12, np.array(ub) - 1e-12)

    def res(th: np.ndarray) -> np.ndarray:
        return (model_value(name, h, th) - y) * sw

    def jac(th: np.ndarray) -> np.ndarray:
        return model_jacobian(name, h, th) * sw[:, None]

    try:
        sol = least_squares(res, x0, jac=jac, bounds=(lb, ub), x_scale="jac", max_nfev=400)
    except (ValueError, FloatingPointError):
        return None
    return sol.x, -sol.fun / sw, sol.jac / sw[:, None]


def model_jacobian(name: str, h: np.ndarray, th: np.ndarray) -> np.ndarray:
    """∂f/∂θ (len(h), 3 or 4) of the non-linear laws (exponential, power, logistic) at one coefficient vector."""
    ones = np.ones(h.size)
    if name == "exponential":
        c, tau_e = th[1], max(th[2], 1e-9)
        x = h / tau_e
        inside = x < 50.0
        ex = np.exp(np.minimum(x, 50.0))
        return np.column_stack([ones, np.expm1(np.minimum(x, 50.0)), np.where(inside, -c * ex * x / tau_e, 0.0)])
    if name == "power":
        r = np.maximum(h, 0.0) / _H_SCALE
        rm = np.power(r, th[2])
        log_r = np.log(np.where(r > 0, r, 1.0))
        return np.column_stack([ones, rm, th[1] * rm * log_r])
    if name == "logistic":
        amp, mid, w = th[1], th[2], max(th[3], 1e-9)
        s, s0 = expit((h - mid) / w), float(expit(-mid / w))
        ds, ds0 = s * (1.0 - s), s0 * (1.0 - s0)
        return np.column_stack([ones, s - s0, -amp / w * (ds - ds0), -amp / w ** 2 * (ds * (h - mid) + ds0 * mid)])
    raise ValueError(name)


def logistic_bounds(h: np.ndarray) -> tuple[list[float], list[float]]:
    """Bounds of (a, A, mid, width): the midpoint up to :data:`LOGISTIC_MID_SPAN` × the span seen, the width at
    least the typical visit spacing (narrower, the logistic would be a step between two visits — a change point's
    claim, which must earn it) and at most the span."""
    span = max(float(h.max() - h.min()), 1.0)
    spacing = float(np.median(np.diff(h))) if h.size > 1 else span
    w_min = min(max(spacing, span / 20), span / 2)
    return [-np.inf, -np.inf, float(h.min()) - span, w_min], [np.inf, np.inf, LOGISTIC_MID_SPAN * span, span]


def _logistic_start(h: np.ndarray, y: np.ndarray, sw: np.ndarray, lb: list[float], ub: list[float]) -> np.ndarray:
    """The best (a, A) by weighted least squares on a grid of (mid, width) — linear in (a, A) once those are
    fixed, solved for the whole grid at once — as the start of the non-linear fit."""
    grid = np.meshgrid(np.linspace(lb[2], ub[2], 14), np.geomspace(lb[3], ub[3], 8), indexing="ij")
    mids, widths = grid[0].ravel(), grid[1].ravel()
    r = logistic_rise(h[None, :], mids[:, None], widths[:, None])  # (grid, visits)
    w = sw ** 2
    s0, sy = float(w.sum()), float(w @ y)
    sr, srr, sry = r @ w, (r * r) @ w, r @ (w * y)
    det = s0 * srr - sr ** 2
    ok = det > 1e-12 * max(s0 * float(np.max(srr)), 1e-300)
    amp = np.where(ok, (s0 * sry - sr * sy) / np.where(ok, det, 1.0), 0.0)
    a = (sy - amp * sr) / s0
    rss = np.where(ok, ((y[None, :] - a[:, None] - amp[:, None] * r) ** 2) @ w, np.inf)
    k = int(np.argmin(rss))
    return np.array([a[k], amp[k], mids[k], widths[k]])


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
    k = theta.size + (1 if name in SEARCHED else 0)
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
    #: the latest-visit check (:func:`latest_visit_check`): the paths' spread around their median is multiplied
    #: by this (1: the laws fitted to the earlier visits foresaw the latest one within their 90 % band)
    spread_factor: float = 1.0
    #: the check's numbers (None: too few visits to check)
    check: dict[str, float] | None = None

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
            out = sample_mixture(self.fits, self.weights, h, n, rng)
        else:
            n_recent = round(RECENT_SHARE * n)
            out = np.empty((n, h.size))
            out[: n - n_recent] = sample_mixture(self.fits, self.weights, h, n - n_recent, rng)
            out[n - n_recent:] = paths_of(self.recent, h, n_recent, rng)
        if self.spread_factor > 1.0:
            med = np.median(out, axis=0)
            out = med + self.spread_factor * (out - med)
        return out

    def band(self, h: np.ndarray, rng: np.random.Generator, n: int = 400, q: float = 0.9) -> tuple[np.ndarray, ...]:
        """(median, low, high) of the mean path at ``h`` (band q)."""
        paths = self.sample_paths(h, n, rng) if self.significant else paths_of(self.fits["none"], h, n, rng)
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
            out[idx] = paths_of(fits[name], h, idx.size, rng)
    return out


def paths_of(f: ModelFit, h: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    """Mean paths of one law: θ ~ N(θ̂, cov), or a multivariate t with n − p degrees of freedom when the law's
    scatter τ² was estimated from its residuals."""
    th = rng.multivariate_normal(np.zeros(f.theta.size), _psd(f.cov), size=n, method="svd")
    if f.scatter2 > 0 and f.dof >= 1:
        th *= np.sqrt(f.dof / rng.chisquare(f.dof, size=n))[:, None]
    th += f.theta
    if f.name == "exponential":
        th[:, 2] = np.maximum(th[:, 2], 1e-6)
    if f.name == "logistic":
        th[:, 3] = np.maximum(th[:, 3], 0.5 * f.theta[3])
    return model_value(f.name, h[None, :], th, f.tau)


def _psd(c: np.ndarray) -> np.ndarray:
    c = 0.5 * (c + c.T)
    w, v = np.linalg.eigh(c)
    return (v * np.maximum(w, 0.0)) @ v.T


def fit_trend(parameter: str, hours: Sequence[float] | np.ndarray, y: Sequence[float] | np.ndarray,
              stderr: Sequence[float | None] | np.ndarray, *, floor: float = SIGMA_FLOOR, check: bool = True
              ) -> Trend:
    """Choose the trend of one parameter (see the module docstring). ``floor``: the repeatability floor σ_f in the
    unit of ``y`` (default: 0.05 % for relative deviations; an effect's parameter trended in its own unit has its
    own)."""
    h = np.asarray(hours, float)
    yv = np.asarray(y, float)
    s = np.array([v if v is not None and math.isfinite(v) else 0.0 for v in stderr], float)
    var0 = s ** 2 + floor ** 2
    n = h.size
    fits: dict[str, ModelFit] = {}
    for name in ("none", "linear", "exponential", "power", "logistic"):
        if n >= MIN_VISITS_FOR[name]:
            f = _wls(name, h, yv, var0)
            if f is not None:
                fits[name] = f
    for name in SEARCHED:
        if n >= MIN_VISITS_FOR[name]:
            f = _best_position(name, h, yv, var0)
            if f is not None:
                fits[name] = f
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
    trend = Trend(parameter, best, fits, significant, p, akaike_weights(fits), cp_note, recent)
    if check and n >= CHECK_MIN_VISITS:
        earlier = fit_trend(parameter, h[:-1], yv[:-1], s[:-1], floor=floor, check=False)
        trend.check = latest_visit_check(earlier, float(h[-1]), float(yv[-1]), float(var0[-1]))
        trend.spread_factor = trend.check["spread_factor"]
    return trend


def latest_visit_check(earlier: Trend, h: float, y: float, var: float, n: int = 4000) -> dict[str, float]:
    """How well the laws fitted to the visits before the latest one foresaw it: their predictive band at the
    latest visit's hours (the mean paths of the mixture — or of ``none`` without a trend — plus the visit's own
    variance ``var`` and the chosen law's scatter), and the ratio of the miss to the band's half-width on the
    miss's side. ``spread_factor`` = max(1, that ratio): a law outside the candidates (a knee just passed, an
    inflection) shows as a miss here before the laws can represent it, whatever its shape."""
    rng = np.random.default_rng(CHECK_SEED)
    hh = np.array([h])
    paths = earlier.sample_paths(hh, n, rng)[:, 0] if earlier.significant else \
        paths_of(earlier.fits["none"], hh, n, rng)[:, 0]
    pred = paths + rng.normal(0.0, 1.0, n) * math.sqrt(var + earlier.best.scatter2)
    med, lo, hi = (float(v) for v in np.quantile(pred, [0.5, 0.05, 0.95]))
    half = (hi - med) if y >= med else (med - lo)
    ratio = abs(y - med) / half if half > 0 else (0.0 if y == med else CHECK_MAX_FACTOR)  # finite: JSON
    return {"hours": h, "observed": y, "predicted_median": med, "predicted_low": lo, "predicted_high": hi,
            "miss_ratio": ratio, "spread_factor": min(max(1.0, ratio), CHECK_MAX_FACTOR)}


def searched_positions(name: str, h: np.ndarray) -> list[float]:
    """Where a change point's step (midway between two visits, at least two visits after it) or a two-stage
    wear's knee (at a visit or midway between two, at least two visits after it) is searched."""
    if name == "change_point":
        return [0.5 * (h[j - 1] + h[j]) for j in range(1, h.size - 1)]
    knees = [float(h[j]) for j in range(1, h.size - 2)]
    return sorted(knees + [0.5 * (h[j] + h[j + 1]) for j in range(1, h.size - 3)])


def _best_position(name: str, h: np.ndarray, y: np.ndarray, var0: np.ndarray) -> ModelFit | None:
    best = None
    for tau in searched_positions(name, h):
        f = _wls(name, h, y, var0, tau)
        if f is not None and (best is None or f.ic < best.ic):
            best = f
    return best


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
    F-test with the scale from its residuals (see the module docstring). The survival functions come from
    scipy.special (what scipy.stats.chi2/f.sf call, bit for bit): importing scipy.stats cost every health process
    0.25 s of CPU, a fleet worker's start-up included."""
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
        return float(chdtrc(df1, drop))
    return float(fdtrc(df1, df2, (drop / df1) / reduced))


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
        p = float(2 * stdtr(max(n - cp.k, 1), -t))
        if p >= P_STEP / positions:
            return (f"a sudden change at {cp.tau:g} h fits better than {runner} by ΔAIC {margin:.1f}, but its step "
                    f"is not significant over the {positions} positions searched (p = {p:.2g} ≥ {P_STEP:g}/"
                    f"{positions}): not claimed")
    return None
