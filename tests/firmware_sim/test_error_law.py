"""Eq. 4/5/11: the one normalised-error implementation the board's monitor and the workbench share
(board_config/error_law.py): model first, measurement second, the measurement alone in the denominator."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import firmware_sim.condition_monitor as monitor
import workbench.compare._metrics as metrics
from board_config import load_monitor_settings
from board_config.error_law import normalised_error

S = load_monitor_settings()


def test_one_implementation_for_monitor_and_workbench():
    assert monitor.normalised_error is normalised_error
    assert metrics.normalised_error is normalised_error
    mon = monitor.ConditionMonitor(S)
    assert mon.error(6.5e-3, 5e-3) == normalised_error(6.5e-3, 5e-3, S.e0z, S.kerr_z)


def test_measurement_alone_in_the_denominator():
    # Eq. 11: a 5 mm measured deflection with a 1.5 mm model error, floor e0z/kerr_z = 10 mm: 1.5 / (5 + 10)
    assert normalised_error(6.5e-3, 5e-3, S.e0z, S.kerr_z) == pytest.approx(0.1, rel=1e-12)
    # the same numbers the other way round divide by the model's 6.5 mm instead: a different value
    assert normalised_error(5e-3, 6.5e-3, S.e0z, S.kerr_z) == pytest.approx(1.5 / 16.5, rel=1e-12)
    arr = normalised_error(np.array([6.5e-3, 5e-3]), np.array([5e-3, 6.5e-3]), S.e0z, S.kerr_z)
    np.testing.assert_allclose(arr, [0.1, 1.5 / 16.5], rtol=1e-12)
    # the sign of either does not matter, only magnitudes
    assert normalised_error(-6.5e-3, -5e-3, S.e0z, S.kerr_z) == pytest.approx(0.1, rel=1e-12)
    assert normalised_error(0.0, 0.0, S.e0z, S.kerr_z) == 0.0


@settings(max_examples=200, deadline=None)
@given(y=st.floats(-1e3, 1e3), e0=st.floats(1e-6, 10.0), kerr=st.floats(1e-3, 1.0), sign=st.sampled_from([-1, 1]))
def test_an_error_exactly_on_the_eq4_law_normalises_to_kerr(y, e0, kerr, sign):
    model = y + sign * (e0 + kerr * abs(y))
    assert normalised_error(model, y, e0, kerr) == pytest.approx(kerr, rel=1e-9, abs=1e-12)


finite = st.floats(-0.05, 0.05)
special = st.sampled_from([0.0, -0.0, 1e-3, math.nan, math.inf, -math.inf])


@settings(max_examples=300, deadline=None)
@given(md=finite | special, hw=finite | special, e0=st.sampled_from([0.0, 0.75e-3, 2.0]),
       kerr=st.sampled_from([-0.1, 0.0, 0.075, 1.0]))
def test_float_and_array_forms_agree_bit_for_bit(md, hw, e0, kerr):
    a = normalised_error(md, hw, e0, kerr)
    b = normalised_error(np.array([md]), np.array([hw]), e0, kerr)
    assert type(a) is float and isinstance(b, np.ndarray) and b.shape == (1,)
    assert (math.isnan(a) and math.isnan(b[0])) or a == b[0]
    assert math.isnan(a) or a >= 0.0


def test_integer_arrays_are_numbers_not_wrapping_machine_words():
    # raw counts in a small integer type: the difference and the magnitude must not wrap around
    eps = normalised_error(np.array([100], np.int8), np.array([-100], np.int8), 0.0, 1.0)
    assert eps.tolist() == [2.0]  # |100 - (-100)| / |-100|
    assert normalised_error(np.zeros(1), np.array([-128], np.int8), 0.0, 1.0).tolist() == [1.0]
    assert normalised_error(np.array([-128], np.int8), np.zeros(1), 1.0, 1.0).tolist() == [128.0]


def test_edges_compute_without_warnings():
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the board logs warnings: the documented edges must stay silent
        assert normalised_error(np.array([1.0, 0.0]), np.array([0.0, 0.0]), 0.0, 1.0).tolist() == [math.inf, 0.0]
        assert np.isnan(normalised_error(np.array([math.inf]), np.array([math.inf]), 1.0, 1.0)).all()
        assert np.isnan(normalised_error(np.array([math.nan]), np.array([0.0]), 0.0, 1.0)).all()


def test_ints_are_scalars_and_arrays_broadcast():
    assert normalised_error(3, 1, 1, 1) == 1.0 and type(normalised_error(3, 1, 1, 1)) is float  # 2 / (1 + 1)
    out = normalised_error(np.zeros((2, 3)), np.ones(3), 1.0, 1.0)
    assert out.shape == (2, 3) and np.all(out == 0.5)
    nan = normalised_error(np.zeros((2, 3)), np.ones(3), 1.0, 0.0)
    assert nan.shape == (2, 3) and np.isnan(nan).all()
    nan = normalised_error(np.zeros(3), np.ones((2, 3)), 1.0, 0.0)  # the measurement's shape may be the larger
    assert nan.shape == (2, 3) and np.isnan(nan).all()
    assert normalised_error([0.0, 2.0], 1.0, 0.0, 1.0).tolist() == [1.0, 1.0]  # a list is an array


@pytest.mark.parametrize("kerr", [0.0, -0.075, -math.inf])
def test_no_amplitude_law_is_undefined(kerr):
    # kerr <= 0: the error does not grow with the amplitude, Eq. 5 divides by an infinite floor -> NaN
    assert math.isnan(normalised_error(1e-3, 0.0, 0.75e-3, kerr))
    assert math.isnan(normalised_error(0.0, 0.0, 0.75e-3, kerr))
    assert np.isnan(normalised_error(np.array([1e-3, 0.0]), np.array([0.0, 0.0]), 0.75e-3, kerr)).all()


def test_smallest_positive_kerr_is_defined():
    kerr = 5e-324  # the smallest positive float: e0/kerr overflows to an infinite floor, eps -> 0
    assert normalised_error(1.0, 0.0, 1.0, kerr) == 0.0
    assert normalised_error(np.array([1.0]), np.array([0.0]), 1.0, kerr).tolist() == [0.0]


def test_zero_floor_at_a_zero_measurement():
    # e0 = 0 and a zero measurement: no error is 0, any error is infinitely large, a NaN stays NaN
    for f in (lambda md, hw: normalised_error(md, hw, 0.0, 0.5),
              lambda md, hw: float(normalised_error(np.array([md]), np.array([hw]), 0.0, 0.5)[0])):
        assert f(0.0, 0.0) == 0.0
        assert f(1e-9, 0.0) == math.inf and f(-2.0, -0.0) == math.inf
        assert math.isnan(f(math.nan, 0.0))
        assert f(3.0, 1.0) == 2.0  # e0 = 0 elsewhere: the plain relative error
    arr = normalised_error(np.array([0.0, 1.0, 3.0]), np.array([0.0, 0.0, 1.0]), 0.0, 0.5)
    assert arr.tolist() == [0.0, math.inf, 2.0]


def test_non_finite_inputs_give_non_finite_errors():
    for md, hw in [(math.nan, 1e-3), (1e-3, math.nan), (math.inf, 1e-3), (1e-3, math.inf), (math.inf, math.inf)]:
        assert not math.isfinite(normalised_error(md, hw, S.e0z, S.kerr_z))
        assert not np.isfinite(normalised_error(np.array([md]), np.array([hw]), S.e0z, S.kerr_z)).any()


def test_workbench_threshold_defaults_to_the_monitor_setting():
    t = np.arange(6) * 0.1
    y = np.zeros(6)
    # with the given z3 law the floor is 10 mm: errors of 2.2 mm and 2.3 mm straddle eps_th = 0.225
    model = np.array([2.2e-3, 2.3e-3, 2.3e-3, 0.0, 0.0, 0.0])
    m = metrics.channel_metrics("z3", "m", t, y, model, given=(S.e0z, S.kerr_z))
    assert S.eps_th == pytest.approx(0.225)
    assert m.eps_given.frac_above_th == pytest.approx(2 / 6)
    lower = metrics.channel_metrics("z3", "m", t, y, model, given=(S.e0z, S.kerr_z), eps_th=0.2)
    assert lower.eps_given.frac_above_th == pytest.approx(3 / 6)
