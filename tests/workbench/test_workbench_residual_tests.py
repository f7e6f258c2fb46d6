"""Residual tests validated statistically on cheap synthetic residual series (no simulation).

Null hypothesis: the residual is white noise independent of the input (truth = model + white noise). Each test
must then fail with probability ≈ α (at most α plus binomial slack) — checked over many seeds for several
realistic drives (MBIT.a-like slow sine, MBIT.b-like step, chirp, random). Under each kind of model error, the
test meant to catch it must fail.
"""

from __future__ import annotations

import numpy as np
import pytest

from workbench.compare import residual_tests
from workbench.compare._residual_tests import POINTS_AT, cross_correlation

N = 2000
T = np.arange(N) * 1e-3
DRIVES = {
    "slow sine": 600 * np.sin(2 * np.pi * 0.5 * T),
    "step": np.where(T > 0.5, 300.0, 0.0),
    "chirp": 300 * np.sin(2 * np.pi * (1.0 * T + 10.0 * T ** 2)),
    "random": np.random.default_rng(12345).normal(0, 100, N),
}
KEYS = ("bias", "ee", "ue", "u2e", "u2e2", "e_eu")


def _rejections(u: np.ndarray, seeds: int, levels: tuple[float, ...]) -> dict[float, dict[str, int]]:
    counts = {a: dict.fromkeys(KEYS, 0) for a in levels}
    battery = dict.fromkeys(levels, 0)
    for s in range(seeds):
        e = np.random.default_rng(1000 + s).normal(0.0, 2e-6, N)
        rt = residual_tests(e, u, level=0.01)
        for a in levels:
            rejected = False
            for t in rt.tests:
                if t.passed is not None and t.p_value < a:
                    counts[a][t.key] += 1
                    rejected = True
            battery[a] += rejected
    for a in levels:
        counts[a]["battery"] = battery[a]
    return counts


@pytest.mark.parametrize("drive", list(DRIVES))
def test_false_rejection_rate_under_white_noise(drive: str) -> None:
    """Truth = model + white noise: each test rejects at about its stated level, never much more."""
    seeds = 300
    counts = _rejections(DRIVES[drive], seeds, (0.01, 0.05))
    for alpha in (0.01, 0.05):
        slack = 3.0 * np.sqrt(alpha * (1 - alpha) / seeds)
        for key in KEYS:
            rate = counts[alpha][key] / seeds
            assert rate <= alpha + slack, f"{drive}: {key} rejects {rate:.3f} of white residuals at α={alpha}"
        # the battery (6 tests) stays within the Bonferroni bound
        assert counts[alpha]["battery"] / seeds <= 6 * alpha + 3.0 * np.sqrt(6 * alpha / seeds)
    # not absurdly conservative either: the whiteness and bias tests sit near their level at α = 5 %
    for key in ("ee", "bias"):
        assert counts[0.05][key] / seeds >= 0.015, f"{drive}: {key} far more conservative than stated"


def test_verdict_uses_the_band_and_p_value_consistently() -> None:
    rt = residual_tests(np.random.default_rng(0).normal(size=N), DRIVES["chirp"])
    for t in rt.tests:
        assert t.passed == (t.statistic <= t.band)
        assert (t.p_value >= 0.01) == t.passed or abs(t.p_value - 0.01) < 2e-3


def _fails(e: np.ndarray, u: np.ndarray) -> set[str]:
    return {t.key for t in residual_tests(e, u).failed}


def test_each_test_catches_its_kind_of_error() -> None:
    rng = np.random.default_rng(7)
    u = DRIVES["random"] / 100.0  # zero-mean, white: the textbook setting of Billings & Voon
    n = rng.normal(0, 1, N)
    # coloured residual (missing dynamics): whiteness fails
    coloured = np.convolve(n, np.ones(5) / 5, mode="same")
    assert "ee" in _fails(coloured, u)
    # a linear gain error: the residual carries the input
    assert "ue" in _fails(n + 0.3 * u, u)
    # an even (quadratic) input term: φu²'e fails, the linear test does not
    f = _fails(n + 0.3 * (u ** 2 - 1.0), u)
    assert "u2e" in f and "ue" not in f
    # error whose size grows with the drive: φu²'e² fails
    assert "u2e2" in _fails(n * (0.2 + np.abs(u)), u)
    # bilinear residual × input interaction: φe(eu) fails
    e = n.copy()
    e[1:] += 0.6 * n[:-1] * u[:-1]
    assert "e_eu" in _fails(e, u)
    # a constant offset: only the bias test sees it (the correlations remove means)
    assert _fails(n + 0.5, u) == {"bias"}


def test_not_applicable_cases_and_bad_input() -> None:
    e = np.random.default_rng(1).normal(size=500)
    rt = residual_tests(e, np.full(500, 300.0))
    assert [t.verdict for t in rt.tests[2:]] == ["n/a"] * 4 and rt.tests[1].passed is not None
    rt0 = residual_tests(np.zeros(500), DRIVES["slow sine"][:500])
    assert rt0.adequate is None and all(t.passed is None for t in rt0.tests)
    with pytest.raises(ValueError, match="same length"):
        residual_tests(e, np.zeros(400))
    with pytest.raises(ValueError, match="at least"):
        residual_tests(e[:50], e[:50])
    with pytest.raises(ValueError, match="finite"):
        residual_tests(np.r_[e[:-1], np.nan], e)


def test_every_test_names_the_physics_it_points_at() -> None:
    rt = residual_tests(np.random.default_rng(2).normal(size=N), DRIVES["chirp"])
    for t in rt.tests:
        assert t.points_at == POINTS_AT[t.key] and len(t.points_at) > 60
    assert "hysteresis" in POINTS_AT["u2e2"] and "offset" in POINTS_AT["bias"] and "mode" in POINTS_AT["ee"]


def test_cross_correlation_matches_direct_sum() -> None:
    rng = np.random.default_rng(3)
    a, b = rng.normal(size=300), rng.normal(size=300)
    lags = np.arange(-20, 21)
    r = cross_correlation(a, b, lags)
    a0, b0 = a - a.mean(), b - b.mean()
    den = np.sqrt(a0 @ a0 * (b0 @ b0))
    direct = [np.dot(a0[: 300 - k], b0[k:]) / den if k >= 0 else np.dot(a0[-k:], b0[: 300 + k]) / den for k in lags]
    np.testing.assert_allclose(r, direct, atol=1e-12)
