"""The workbench's agreement metrics on cases whose answer is known by hand (fit %, NRMSE, RMSE, Eq. 4 fit, Eq. 5
error, ε statistics, FRF metrics), plus the properties that tie them together."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from board_config.errors import InputError
from workbench.compare import channel_metrics, fit_eq4, fit_percent, normalised_error
from workbench.compare._metrics import EpsStats, frf_metrics, nrmse, rmse

Y = np.array([0.0, 1.0, 2.0, 3.0])


def test_fit_nrmse_rmse_by_hand():
    yh = np.array([0.0, 1.0, 2.0, 2.0])
    assert fit_percent(Y, yh) == pytest.approx(100.0 * (1.0 - 1.0 / math.sqrt(5.0)))
    assert nrmse(Y, yh) == pytest.approx(1.0 / math.sqrt(5.0))
    assert rmse(Y, yh) == pytest.approx(0.5)
    assert fit_percent(Y, Y) == 100.0 and nrmse(Y, Y) == 0.0 and rmse(Y, Y) == 0.0
    assert fit_percent(Y, np.full(4, Y.mean())) == pytest.approx(0.0)
    assert fit_percent(Y, -Y) < 0.0
    assert math.isnan(fit_percent(np.ones(4), Y)) and math.isnan(nrmse(np.ones(4), Y))


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(-10, 10), min_size=3, max_size=20), st.floats(-2, 2))
def test_fit_is_one_minus_nrmse(ys, shift):
    y = np.array(ys)
    yh = y + shift * np.cos(np.arange(y.size))
    if np.ptp(y) < 1e-6:
        return
    assert fit_percent(y, yh) == pytest.approx(100.0 * (1.0 - nrmse(y, yh)))
    assert rmse(y, yh) == pytest.approx(float(np.sqrt(np.mean((y - yh) ** 2))))


def test_eq4_fit_recovers_the_amplitude_law():
    rng = np.random.default_rng(3)
    y = rng.uniform(-5.0, 5.0, 200)
    err = 0.2 + 0.05 * np.abs(y)
    fit = fit_eq4(y, y + err * np.sign(rng.standard_normal(200)))
    assert (fit.e0, fit.kerr, fit.r2, fit.source) == (pytest.approx(0.2), pytest.approx(0.05), pytest.approx(1.0),
                                                      "fitted (Eq. 4)")
    # a constant error: no amplitude law, r2 undefined
    q = np.arange(-4, 5) * 0.5  # exact in binary: the error is exactly constant
    fit = fit_eq4(q, q + 0.5)
    assert fit.e0 == pytest.approx(0.5) and fit.kerr == pytest.approx(0.0, abs=1e-12) and math.isnan(fit.r2)
    # non-negative: an error that shrinks with amplitude gets kerr = 0
    fit = fit_eq4(y, y + (3.0 - 0.5 * np.abs(y)))
    assert fit.kerr == 0.0 and fit.e0 == pytest.approx(np.mean(3.0 - 0.5 * np.abs(y)))
    # a pure gain error of a tiny signal (scaling must not lose it)
    fit = fit_eq4(1e-6 * y, 1e-6 * y * 1.1)
    assert fit.kerr == pytest.approx(0.1, rel=1e-6) and fit.e0 == pytest.approx(0.0, abs=1e-12)
    fit = fit_eq4(np.zeros(5), np.full(5, 2.0))
    assert fit.e0 == pytest.approx(2.0)


def test_eq5_normalised_error():
    y, yh = np.array([1.0, -2.0, 0.0, 0.0]), np.array([1.5, -1.0, 0.0, 1.0])
    eps = normalised_error(yh, y, e0=0.5, kerr=0.1)  # model first, measurement second
    assert eps.tolist() == pytest.approx([0.5 / (1.0 + 5.0), 1.0 / (2.0 + 5.0), 0.0, 1.0 / 5.0])
    assert np.isnan(normalised_error(yh, y, 0.5, 0.0)).all() and np.isnan(normalised_error(yh, y, 0.5, -1.0)).all()
    at_zero = normalised_error(yh, y, e0=0.0, kerr=0.1)  # no floor: zero signal and zero error is 0, else inf
    assert at_zero[2] == 0.0 and at_zero[3] == math.inf and at_zero[0] == pytest.approx(0.5)


def test_eps_stats():
    s = EpsStats.of(np.array([0.1, 0.2, 0.3, 0.225, np.nan, np.inf]), eps_th=0.225)
    assert s.mean == pytest.approx(0.20625) and s.max == 0.3
    assert s.std == pytest.approx(np.std([0.1, 0.2, 0.3, 0.225]))
    assert s.p95 == pytest.approx(np.percentile([0.1, 0.2, 0.3, 0.225], 95))
    assert s.frac_above_th == 0.25  # strictly above: 0.225 itself does not count
    assert all(math.isnan(v) for v in vars(EpsStats.of(np.array([np.nan]), 0.2)).values())


def test_channel_metrics_skip_and_given():
    t = np.arange(10) * 0.1
    y = np.sin(t) + 1.0
    yh = y - 0.1
    m = channel_metrics("z3", "m", t, y, yh, skip_s=0.3, given=(0.05, 0.1))
    assert m.n_samples == 7 and m.skip_s == 0.3  # t >= 0.3 (inclusive)
    assert m.mean_error == pytest.approx(0.1) and m.max_abs_error == pytest.approx(0.1)
    assert m.rmse == pytest.approx(0.1) and m.fit_pct == pytest.approx(fit_percent(y[3:], yh[3:]))
    assert m.nrmse == pytest.approx(nrmse(y[3:], yh[3:]))
    assert (m.eq4_given.e0, m.eq4_given.kerr, m.eq4_given.source) == (0.05, 0.1, "given")
    assert math.isnan(m.eq4_given.r2)
    assert m.eps_given.max == pytest.approx(float(np.max(0.1 * 0.1 / (0.1 * np.abs(y[3:]) + 0.05))))
    assert m.eq4_fitted.e0 == pytest.approx(0.1)
    assert m.to_dict()["eq4_given"]["source"] == "given" and m.to_dict()["channel"] == "z3"
    m = channel_metrics("z3", "m", t, y, yh)
    assert m.n_samples == 10 and m.eq4_given is None and m.eps_given is None
    with pytest.raises(InputError, match=r"channel 'z3': transient skip 0\.85 s leaves fewer than 2 samples"):
        channel_metrics("z3", "m", t, y, yh, skip_s=0.85)
    assert channel_metrics("z3", "m", t, y, yh, skip_s=0.8).n_samples == 2


def test_frf_metrics_by_hand():
    f = np.array([1.0, 2.0, 3.0, 4.0])
    h = np.array([1.0, 3.0, 2.0, 0.5], complex)
    m = frf_metrics("z3/v", "m/V", f, h, h)
    assert (m.fit_pct, m.amp_err_db_rms, m.amp_err_db_max, m.phase_err_deg_rms, m.phase_err_deg_max) == \
        (100.0, 0.0, 0.0, 0.0, 0.0)
    assert (m.peak_measured_Hz, m.peak_model_Hz, m.channel, m.unit) == (2.0, 2.0, "z3/v", "m/V")
    hm = 2.0 * h * np.exp(1j * np.radians(30.0))
    hm[2] = 10.0  # the model's peak moved to 3 Hz
    m = frf_metrics("z3/v", "m/V", f, h, hm)
    db = 20 * np.log10(np.abs(hm) / np.abs(h))
    assert m.amp_err_db_max == pytest.approx(np.max(np.abs(db)))
    assert m.amp_err_db_rms == pytest.approx(np.sqrt(np.mean(db ** 2)))
    assert m.phase_err_deg_max == pytest.approx(30.0)
    assert m.phase_err_deg_rms == pytest.approx(np.sqrt(np.mean([30.0 ** 2] * 3 + [0.0])))
    assert m.peak_model_Hz == 3.0 and m.peak_measured_Hz == 2.0
    assert m.fit_pct == pytest.approx(100 * (1 - np.linalg.norm(h - hm) / np.linalg.norm(h)))
    z = frf_metrics("x", "1", f, np.zeros(4, complex), np.ones(4, complex))
    assert math.isnan(z.fit_pct) and math.isnan(z.amp_err_db_rms) and math.isnan(z.amp_err_db_max)
    half = frf_metrics("x", "1", f, np.array([0, 1, 1, 1], complex), np.array([1, 2, 2, 2], complex))
    assert half.amp_err_db_max == pytest.approx(20 * np.log10(2.0))  # the zero bin is left out


def test_channel_metrics_on_a_record_exactly_on_the_eq4_law():
    # |model - measured| = e0 + kerr |measured| exactly: the fit recovers the law, its ε is kerr everywhere, and the
    # threshold comparison of both ε summaries uses the monitor's ε_th
    t = np.arange(400) * 0.01
    y = 5e-3 * np.sin(2 * np.pi * 0.5 * t)
    e0, kerr = 0.5e-3, 0.3
    model = y + (e0 + kerr * np.abs(y)) * np.where(np.arange(400) % 2, 1.0, -1.0)
    m = channel_metrics("z3", "m", t, y, model, given=(e0, kerr))
    assert (m.channel, m.unit, m.n_samples, m.skip_s) == ("z3", "m", 400, 0.0)
    assert m.eq4_fitted.e0 == pytest.approx(e0, rel=1e-6) and m.eq4_fitted.kerr == pytest.approx(kerr, rel=1e-6)
    assert m.eq4_fitted.r2 == pytest.approx(1.0) and m.eq4_fitted.source == "fitted (Eq. 4)"
    for eps in (m.eps_fitted, m.eps_given):
        assert eps.mean == pytest.approx(kerr, rel=1e-6) and eps.max == pytest.approx(kerr, rel=1e-6)
        assert eps.std == pytest.approx(0.0, abs=1e-6) and eps.frac_above_th == 1.0  # 0.3 > ε_th = 0.225


@pytest.mark.parametrize("dtype", [np.int8, np.int16])
def test_integer_records_are_numbers_not_wrapping_machine_words(dtype):
    # raw counts in a small integer type: differences and magnitudes near the type's limits must not wrap around
    y = np.array([-128, 100, -50, 127, 0, 3], dtype)
    yh = np.array([127, -128, 60, -100, 5, 1], dtype)
    yf, yhf = y.astype(float), yh.astype(float)
    t = np.arange(6) * 0.1
    assert fit_percent(y, yh) == fit_percent(yf, yhf) and nrmse(y, yh) == nrmse(yf, yhf)
    assert rmse(y, yh) == rmse(yf, yhf)
    assert fit_eq4(y, yh) == fit_eq4(yf, yhf)
    assert channel_metrics("n", "1", t, y, yh, given=(1.0, 0.5)) == channel_metrics("n", "1", t, yf, yhf,
                                                                                   given=(1.0, 0.5))
    f = np.arange(1.0, 7.0)
    a, b = frf_metrics("n", "1", f, y, yh), frf_metrics("n", "1", f, yf, yhf)
    assert all(x == z or (math.isnan(x) and math.isnan(z)) for x, z in zip(vars(a).values(), vars(b).values()))


def test_eq4_r2_is_the_coefficient_of_determination_of_the_law():
    # an error only roughly linear in the amplitude, both coefficients positive: NNLS is the ordinary least-squares
    # line, and r2 is 1 - SS_res / SS_tot of that line (numpy's polyfit as the independent reference)
    y = np.array([0.0, 1.0, 2.0, 3.0, 4.0, 5.0])
    err = np.array([0.5, 1.0, 1.0, 2.0, 2.5, 2.6])
    fit = fit_eq4(y, y + err)
    k, e0 = np.polyfit(y, err, 1)
    assert fit.e0 == pytest.approx(e0) and fit.kerr == pytest.approx(k)
    res = err - (e0 + k * y)
    want = 1.0 - np.sum(res ** 2) / np.sum((err - err.mean()) ** 2)
    assert fit.r2 == pytest.approx(want, rel=1e-9) and 0.8 < fit.r2 < 1.0


def test_frf_metrics_of_a_small_response_and_at_zero_bins():
    f = np.array([1.0, 2.0, 3.0])
    h = np.array([0.1, 0.3, 0.2], complex)  # |H| < 1 everywhere: a fit % is still defined
    m = frf_metrics("z3/v", "m/V", f, h, 1.1 * h)
    assert m.fit_pct == pytest.approx(90.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # zero bins are expected (no RuntimeWarning)
        half = frf_metrics("x", "1", np.arange(4.0), np.array([0, 1, 1, 1], complex), np.array([1, 2, 2, 2], complex))
        both_zero = frf_metrics("x", "1", np.arange(3.0), np.array([0, 1, 2], complex), np.array([0, 1, 2], complex))
        none = frf_metrics("x", "1", np.arange(3.0), np.zeros(3, complex), np.ones(3, complex))  # no dB bin at all
    assert both_zero.amp_err_db_max == 0.0 and both_zero.fit_pct == 100.0
    assert math.isnan(none.amp_err_db_rms) and math.isnan(none.amp_err_db_max) and math.isnan(none.fit_pct)
    # a zero measured bin has no dB error (left out) and is compared in phase against the model's own angle (0 here)
    assert half.amp_err_db_rms == pytest.approx(20 * np.log10(2.0))
    assert half.phase_err_deg_rms == 0.0 and half.phase_err_deg_max == 0.0
