"""Residual tests with confidence bands and verdicts: bias, whiteness, input cross-correlation and the
Billings–Voon nonlinear correlation tests — each tied in words to the kind of physical effect it points at.

Billings & Voon (1986) showed that a model is adequate (its residual e is unpredictable from past inputs and
residuals) if and only if, for all lags τ (we write the residual ``e``, not Billings & Voon's ε, to keep ε for the
paper's normalised error of Eq. 5):

============  ==========================================  ================
key           correlation                                 lags tested
============  ==========================================  ================
``ee``        φee(τ) = δ(τ)   (whiteness)                 τ = 1 … M
``ue``        φue(τ) = 0                                  τ = −M … M
``u2e``       φu²'e(τ) = 0                                τ = −M … M
``u2e2``      φu²'e²(τ) = 0                               τ = −M … M
``e_eu``      φe(eu)(τ) = E[e(t) e(t−1−τ) u(t−1−τ)] = 0   τ = 0 … M−1
============  ==========================================  ================

with ``φab(τ) = Σ a'(t) b'(t+τ) / √(Σa'² Σb'²)`` (primes: mean removed; the input is centred before squaring,
so φu²'e sees even-order behaviour only). Under the null hypothesis (the residual is white and independent of
the input) each φ(τ) is approximately N(0, 1/N), and two lags are correlated like the *first* signal ``a`` at
their lag difference (``b`` is white); for φee and φe(eu) the first signal is itself built from the white
residual, so their m lags are independent (m_eff = m). A test *fails* when ``max_τ |φ(τ)|`` leaves the band
``± z_{1−α/(2·m_eff)} / √N``: a Šidák/Bonferroni correction over the *effective* number of independent lags
``m_eff`` (Li & Ji 2005, from the eigenvalues of that lag-correlation matrix; ``m_eff = m`` for white ``a``,
about 2 for a pure sine). So a correct model fails each test with probability close to ``α`` (default 1 %,
MATLAB ``resid``'s 99 %), and the battery with probability at most about 6α; the test suite checks both rates
over many seeds.

The correlations remove means, so a constant error is invisible to them; a separate **bias test** (mean
residual against its standard error, same level α) catches offsets.

The tests are for the free-run (simulation) residual of an output-error model: when truth = model + white
sensor noise, that residual *is* the noise. They assume nothing about the input except that it varies
(a constant input makes the cross tests not applicable).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.special import ndtri

from board_config.errors import InputError

DEFAULT_LEVEL = 0.01
DEFAULT_LAGS = 25

#: What a failed test points at, in physical terms (used verbatim in reports).
POINTS_AT: dict[str, str] = {
    "bias": (
        "A constant offset between measurement and model: laser zero or mounting offset, a static preload or "
        "clamp settling, or slow drift (piezo creep, temperature) that averages to a bias."
    ),
    "ee": (
        "The residual has structure in time — dynamics the model lacks or mistunes: a shifted or missing bending "
        "mode, wrong damping, the RC pole of the patches, slow drift (piezo creep, dielectric leakage, "
        "temperature), or the sensor's own bandwidth. The residual spectrum shows which band."
    ),
    "ue": (
        "Error that follows the drive linearly: a wrong gain or time constant — piezo coefficient d_ep, section "
        "stiffness k_i, patch R_ep·C_ep, a resonance at the wrong frequency, a delay or an amplifier bandwidth "
        "or slew limit, a sensor gain error."
    ),
    "u2e": (
        "Error that follows the square of the drive (even-order, sign-asymmetric behaviour): a polarisation-"
        "dependent piezo coefficient (MFCs are asymmetric, −500…+1500 V), electrostriction, an amplifier that "
        "limits on one side, a sensor nonlinearity that depends on the sign of the deflection."
    ),
    "u2e2": (
        "Error whose size grows with the drive amplitude (odd-order or amplitude-dependent behaviour): geometric "
        "(Duffing) stiffening, amplitude-dependent (quadratic air) damping, hysteresis of the wrong width or shape "
        "(Bouc-Wen α, β, γ, n), saturation — the paper's Eq. 4 observation that the error grows with amplitude."
    ),
    "e_eu": (
        "Error that depends jointly on the drive and the model's own past error (interaction / memory terms): "
        "history- or direction-dependent behaviour such as hysteresis or creep whose state depends on the input's "
        "past, or a parameter that changes with the response (stiffness or d_ep varying with deflection)."
    ),
}
TITLES: dict[str, tuple[str, str]] = {
    "bias": ("mean(e)", "bias (mean residual)"),
    "ee": ("φee(τ)", "whiteness (autocorrelation)"),
    "ue": ("φue(τ)", "input–residual cross-correlation"),
    "u2e": ("φu²'e(τ)", "squared input vs residual"),
    "u2e2": ("φu²'e²(τ)", "squared input vs squared residual"),
    "e_eu": ("φe(eu)(τ)", "residual vs residual×input"),
}


@dataclass
class TestResult:
    """One test's verdict. ``r`` over ``lags``; ``band`` is the decision band; ``p_value`` Bonferroni-adjusted."""

    key: str
    symbol: str
    title: str
    lags: np.ndarray
    r: np.ndarray
    band: float
    level: float
    statistic: float  # max |r| over the lags (bias: |mean| / standard error)
    worst_lag: int
    p_value: float
    passed: bool | None  # None: not applicable
    points_at: str
    note: str = ""

    @property
    def verdict(self) -> str:
        return "n/a" if self.passed is None else ("pass" if self.passed else "FAIL")

    @property
    def ratio(self) -> float:
        """statistic / band: above 1 fails."""
        return self.statistic / self.band if self.band > 0 and np.isfinite(self.statistic) else math.nan

    def to_dict(self) -> dict:
        return {"key": self.key, "symbol": self.symbol, "title": self.title, "verdict": self.verdict,
                "statistic": self.statistic, "band": self.band, "ratio": self.ratio, "worst_lag": self.worst_lag,
                "p_value": self.p_value, "level": self.level, "points_at": self.points_at, "note": self.note,
                "lags": self.lags.tolist(), "r": self.r.tolist()}


@dataclass
class ResidualTests:
    """The battery for one residual channel against one input."""

    channel: str
    input_name: str
    n: int
    level: float
    max_lag: int
    decimate: int
    tests: list[TestResult] = field(default_factory=list)

    def __getitem__(self, key: str) -> TestResult:
        for t in self.tests:
            if t.key == key:
                return t
        raise KeyError(key)

    @property
    def failed(self) -> list[TestResult]:
        return [t for t in self.tests if t.passed is False]

    @property
    def adequate(self) -> bool | None:
        """True when every applicable test passes (a correct model: probability ≥ 1 − 6α)."""
        applicable = [t for t in self.tests if t.passed is not None]
        return None if not applicable else all(t.passed for t in applicable)

    def to_dict(self) -> dict:
        return {"channel": self.channel, "input": self.input_name, "n": self.n, "level": self.level,
                "max_lag": self.max_lag, "decimate": self.decimate, "adequate": self.adequate,
                "tests": [t.to_dict() for t in self.tests]}


def _norm_sf2(z: np.ndarray) -> np.ndarray:
    """Two-sided normal tail probability 2·(1 − Φ(|z|))."""
    from scipy.special import ndtr

    return 2.0 * ndtr(-np.abs(z))


def cross_correlation(a: np.ndarray, b: np.ndarray, lags: np.ndarray) -> np.ndarray:
    """``φab(τ) = Σ_t a'(t) b'(t+τ) / √(Σa'² Σb'²)`` for each lag (primes: mean removed). NaN if a or b is flat."""
    a = np.asarray(a, float) - np.mean(a)
    b = np.asarray(b, float) - np.mean(b)
    den = float(np.sqrt(np.einsum("i,i->", a, a) * np.einsum("i,i->", b, b)))
    n = a.size
    if den == 0.0 or not np.all(np.isfinite(den)):
        return np.full(lags.size, np.nan)
    lags = np.asarray(lags, dtype=int)
    if lags.size <= 128:  # a few lags of a long record: direct sums beat the FFT
        out = np.empty(lags.size)
        for i, tau in enumerate(lags):  # einsum, not BLAS: no thread start-up per call on a busy machine
            out[i] = (np.einsum("i,i->", a[: n - tau], b[tau:]) if tau >= 0 else
                      np.einsum("i,i->", a[-tau:], b[: n + tau]))
        return out / den
    nfft = 1 << int(np.ceil(np.log2(2 * n)))
    full = np.fft.irfft(np.conj(np.fft.rfft(a, nfft)) * np.fft.rfft(b, nfft), nfft)  # full[τ] = Σ a(t) b(t+τ)
    return full[lags % nfft] / den


def band_for(n: int, m_eff: float, level: float) -> float:
    """Decision band ``z_{1−α/(2 m_eff)} / √N`` for the max of lag correlations at family level α."""
    return float(ndtri(1.0 - level / (2.0 * m_eff)) / np.sqrt(n))


def effective_lags(a: np.ndarray, lags: np.ndarray) -> float:
    """Effective number of independent lags (Li & Ji 2005) of ``φab`` over ``lags`` when ``b`` is white.

    The correlation between lags τ and τ' is the autocorrelation of ``a`` at τ − τ'; ``m_eff = Σ f(|λ_i|)`` over
    the eigenvalues of that matrix, ``f(x) = [x ≥ 1] + (x − ⌊x⌋)``.
    """
    m = lags.size
    span = int(lags.max() - lags.min())
    rho = cross_correlation(a, a, np.arange(span + 1))
    if not np.all(np.isfinite(rho)):
        return float(m)
    d = np.abs(lags[:, None] - lags[None, :])
    lam = np.abs(np.linalg.eigvalsh(rho[d]))
    return float(max(1.0, min(m, np.sum((lam >= 1.0) + (lam - np.floor(lam))))))


def _corr_test(key: str, a: np.ndarray, b: np.ndarray, lags: np.ndarray, level: float, note: str = "",
               a_white_under_h0: bool = False) -> TestResult:
    """``a_white_under_h0``: the first signal is built from the residual (φee, φe(eu)), so under the null
    hypothesis its lags are independent and m_eff = m (estimating it from a failing residual would be wrong)."""
    n = a.size
    r = cross_correlation(a, b, lags)
    symbol, title = TITLES[key]
    m_eff = float(lags.size) if a_white_under_h0 else effective_lags(a, lags)
    band = band_for(n, m_eff, level)
    if not np.all(np.isfinite(r)):
        return TestResult(key, symbol, title, lags, r, band, level, math.nan, 0, math.nan, None,
                          POINTS_AT[key], note or "not applicable: a signal in the test has no variation")
    k = int(np.argmax(np.abs(r)))
    stat = float(abs(r[k]))
    p = float(min(1.0, m_eff * _norm_sf2(np.array([stat * np.sqrt(n)]))[0]))
    return TestResult(key, symbol, title, lags, r, band, level, stat, int(lags[k]), p, bool(stat <= band),
                      POINTS_AT[key], note or f"{lags.size} lags, {m_eff:.1f} effectively independent")


def bias_test(e: np.ndarray, level: float = DEFAULT_LEVEL) -> TestResult:
    """Mean residual against its standard error (two-sided, level α), assuming a white residual."""
    e = np.asarray(e, float)
    n = e.size
    sd = float(np.std(e, ddof=1)) if n > 1 else 0.0
    symbol, title = TITLES["bias"]
    zc = float(ndtri(1.0 - level / 2.0))
    if sd == 0.0:
        return TestResult("bias", symbol, title, np.zeros(1, int), np.array([float(np.mean(e))]), zc, level,
                          math.nan, 0, math.nan, None, POINTS_AT["bias"],
                          "not applicable: the residual is constant")
    t = float(np.mean(e) / (sd / np.sqrt(n)))
    p = float(_norm_sf2(np.array([t]))[0])
    return TestResult("bias", symbol, title, np.zeros(1, int), np.array([float(np.mean(e))]), zc, level, abs(t), 0,
                      p, bool(abs(t) <= zc), POINTS_AT["bias"], f"mean residual {np.mean(e):.4g} (SI), t = {t:.3g}")


def residual_tests(residual: np.ndarray, u: np.ndarray, *, channel: str = "y", input_name: str = "u",
                   level: float = DEFAULT_LEVEL, max_lag: int = DEFAULT_LAGS, decimate: int = 1) -> ResidualTests:
    """Run the bias test and the five Billings–Voon tests on a residual ``e`` (measured − model) against an
    input ``u`` sampled at the same instants. ``decimate`` keeps every k-th sample first (longer time scales
    per lag). Returns verdicts at family level ``level`` per test (see the module docstring).
    """
    e = np.asarray(residual)[:: max(1, int(decimate))]  # every use below works in float (means removed first)
    u = np.asarray(u)[:: max(1, int(decimate))]
    if e.shape != u.shape:
        raise ValueError(f"residual and input must have the same length, got {e.size} and {u.size}")
    if not np.all(np.isfinite(e)) or not np.all(np.isfinite(u)):
        raise ValueError("residual and input must be finite")
    if not 0.0 < level < 1.0:
        raise InputError(f"level must be in (0, 1), got {level}")
    n = e.size
    m = int(max_lag)
    if m < 1 or n < 4 * m + 10:
        raise InputError(f"need at least {4 * m + 10} samples for {m} lags, got {n}")
    out = ResidualTests(channel, input_name, n, level, m, max(1, int(decimate)))
    out.tests.append(bias_test(e, level))
    pos = np.arange(1, m + 1)
    both = np.arange(-m, m + 1)
    ec = e - e.mean()
    uc = u - u.mean()
    u2 = uc ** 2  # cross_correlation removes the mean of the square itself
    out.tests.append(_corr_test("ee", e, e, pos, level, a_white_under_h0=True))
    out.tests.append(_corr_test("ue", uc, e, both, level))
    out.tests.append(_corr_test("u2e", u2, e, both, level))
    out.tests.append(_corr_test("u2e2", u2, ec ** 2, both, level))
    # φe(eu)(τ) = corr(e(t), w(t−1−τ)) with w = e·u: a = w, b = e at lag 1+τ
    out.tests.append(_corr_test("e_eu", ec * uc, e, pos, level, a_white_under_h0=True))
    if np.ptp(u) == 0.0:  # a constant input: the four cross tests say nothing
        for t in out.tests[2:]:
            t.passed = None
            t.note = "not applicable: the input does not vary"
    return out
