"""A sudden change is claimed only with a margin (issue 27, point 3): on the aging run health claimed a change of β_h
at ~1550 h for a linear truth because the change-point model won by ΔAICc 0.3."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from studies.health.trend import CHANGE_POINT_MIN_DELTA_AICC, fit_trend


def _linear_life(seed: int, n: int, slope: float, noise: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    h = np.arange(n) * 100.0
    return h, 0.001 + slope * h + rng.normal(0.0, noise, n), np.full(n, noise)


@settings(max_examples=60, deadline=None)
@given(slope=st.floats(-3e-4, 3e-4), noise=st.floats(1e-4, 1e-2), n=st.integers(6, 24), seed=st.integers(0, 10**6))
def test_a_change_point_is_only_chosen_with_the_margin(slope, noise, n, seed):
    t = fit_trend("beta_h", *_linear_life(seed, n, slope, noise))
    if t.best.name == "change_point":
        others = [f.ic for k, f in t.fits.items() if k != "change_point"]
        assert t.best.ic <= min(others) - CHANGE_POINT_MIN_DELTA_AICC
    if "change_point" in t.fits and t.best.name != "change_point":
        cp = t.fits["change_point"].ic
        if cp < min(f.ic for k, f in t.fits.items() if k != "change_point"):
            assert t.change_point_note and "not claimed" in t.change_point_note


@pytest.mark.slow
def test_linear_lives_rarely_get_a_sudden_change():
    """300 linear lives (6-24 visits, slopes ±3 % per 100 h, noise 0.01-1 %): the change point won 18 % of them on
    AICc alone; with the margin and the step's own test, at most 5 %."""
    rng = np.random.default_rng(0)
    claimed = 0
    for _ in range(300):
        n = int(rng.integers(6, 25))
        t = fit_trend("beta_h", *_linear_life(int(rng.integers(1 << 30)), n, rng.uniform(-3e-4, 3e-4),
                                              10 ** rng.uniform(-4, -2)))
        claimed += t.significant and t.model == "change_point"
    assert claimed <= 15, claimed


def test_the_aging_runs_beta_h_case_is_linear():
    """β_h of the aging run: -1 % per 100 h, 24 visits, estimates to ±0.025 % with a little visit-to-visit scatter.
    Where a change point fits best by less than the margin (as on the run: ΔAICc 0.3), the law stays smooth and the
    trend says why."""
    h = np.arange(24) * 100.0
    se = np.full(24, 2.5e-4)
    marginal = 0
    for seed in range(80):  # 40 gave 3 marginal cases before the two-stage and logistic laws joined the smooth ones
        y = -1e-4 * h + np.random.default_rng(seed).normal(0.0, 4e-4, 24)
        t = fit_trend("beta_h", h, y, se)
        cp = t.fits["change_point"].ic
        smooth = min(f.ic for k, f in t.fits.items() if k != "change_point")
        if 0 <= smooth - cp < CHANGE_POINT_MIN_DELTA_AICC:
            marginal += 1
            assert t.model != "change_point" and t.significant
            assert t.change_point_note and "ΔAIC" in t.change_point_note and "not claimed" in t.change_point_note
    assert marginal >= 3, marginal


def test_a_real_step_is_still_claimed():
    rng = np.random.default_rng(5)
    h = np.arange(10) * 100.0
    for size in (-0.04, 0.05, -0.15):
        y = np.where(h >= 450, size, 0.0) + rng.normal(0, 0.002, h.size)
        t = fit_trend("k3", h, y, np.full(h.size, 0.002))
        assert t.significant and t.model == "change_point" and 400 < (t.best.tau or 0) < 500
