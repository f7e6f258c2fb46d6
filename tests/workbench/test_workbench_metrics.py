"""Fit %, NRMSE and the paper's normalised error (Eq. 4-5) on cases with known answers."""

from __future__ import annotations

import numpy as np
import pytest

from workbench.compare import channel_metrics, fit_eq4, fit_percent, normalised_error
from workbench.compare._metrics import frf_metrics, nrmse


def test_fit_percent_known_cases() -> None:
    t = np.linspace(0, 10, 1001)
    y = np.sin(t)
    assert fit_percent(y, y) == pytest.approx(100.0)
    assert fit_percent(y, 0.9 * y + 0.1 * y.mean()) == pytest.approx(90.0)  # error = 0.1 (y - mean)
    assert fit_percent(y, np.full_like(y, y.mean())) == pytest.approx(0.0, abs=1e-12)
    assert fit_percent(y, -y + 2 * y.mean()) == pytest.approx(-100.0)  # mirror: error twice the variation
    assert nrmse(y, 0.75 * y + 0.25 * y.mean()) == pytest.approx(0.25)
    assert np.isnan(fit_percent(np.ones(5), np.zeros(5)))  # a flat measurement has no variation to explain


def test_eq4_recovers_bias_and_gain_and_eq5_is_then_kerr() -> None:
    rng = np.random.default_rng(0)
    y = 5e-3 * np.sin(np.linspace(0, 20, 2000))
    e0, k = 0.75e-3, 0.075
    err = (e0 + k * np.abs(y)) * rng.choice([-1.0, 1.0], y.size)
    fit = fit_eq4(y, y + err)
    assert fit.e0 == pytest.approx(e0, rel=1e-9) and fit.kerr == pytest.approx(k, rel=1e-9) and fit.r2 > 0.999
    eps = normalised_error(y + err, y, fit.e0, fit.kerr)  # model first, measurement second
    np.testing.assert_allclose(eps, k, rtol=1e-9)  # exactly on the law, ε(t) = kerr everywhere


def test_eq4_with_no_amplitude_dependence_and_eq5_undefined() -> None:
    y = np.sin(np.linspace(0, 20, 500))
    fit = fit_eq4(y, y + 0.01)  # constant error: e0 = 0.01, kerr = 0
    assert fit.e0 == pytest.approx(0.01, rel=1e-6) and fit.kerr == pytest.approx(0.0, abs=1e-9)
    assert np.all(np.isnan(normalised_error(y + 0.01, y, fit.e0, 0.0)))


def test_given_constants_paper_monitor() -> None:
    t = np.linspace(0, 20, 2001)
    y = 5e-3 * np.sin(2 * np.pi * 0.1 * t)
    model = y * 1.05  # 5 % gain error
    m = channel_metrics("z3", "m", t, y, model, given=(0.75e-3, 0.075))
    expect = 0.075 * 0.05 * np.abs(y) / (0.075 * np.abs(y) + 0.75e-3)
    assert m.eps_given is not None and m.eps_given.max == pytest.approx(expect.max(), rel=1e-9)
    assert m.eps_given.frac_above_th == 0.0
    assert m.fit_pct == pytest.approx(95.0, abs=0.01)
    # transient skip removes the first 10 s
    m2 = channel_metrics("z3", "m", t, y, model, skip_s=10.0)
    assert m2.n_samples == 1001


def test_frf_metrics() -> None:
    f = np.array([1.0, 10.0, 20.0])
    h = np.array([1.0, 3.0, 0.5]) * np.exp(1j * np.radians([0, -45, -120]))
    m = frf_metrics("z3", "m/V", f, h, h * 10 ** (1 / 20) * np.exp(1j * np.radians(5)))
    assert m.amp_err_db_rms == pytest.approx(1.0) and m.phase_err_deg_max == pytest.approx(5.0)
    assert m.peak_measured_Hz == 10.0 and m.peak_model_Hz == 10.0
    assert frf_metrics("z3", "m/V", f, h, h).fit_pct == pytest.approx(100.0)
