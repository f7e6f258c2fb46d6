"""Eq. 11 (normalised error), the monitor's settings from board_config, and the streaming API's edges."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from board_config import load_monitor_settings
from firmware_sim.condition_monitor import ConditionMonitor, evaluate, evaluate_z3, normalised_error

S = load_monitor_settings()


def test_eq11_uses_e0z_and_kerr_from_config():
    assert S.e0z == pytest.approx(0.75e-3) and S.kerr_z == pytest.approx(0.075)
    floor = S.e0z / S.kerr_z  # 10 mm
    assert normalised_error(1e-3, 0.0, S.e0z, S.kerr_z) == pytest.approx(1e-3 / floor)
    # Eq. 5 divides by |y_hw| + e0/kerr: a 5 mm deflection measured with a 1.5 mm error gives 0.1
    assert normalised_error(6.5e-3, 5e-3, S.e0z, S.kerr_z) == pytest.approx(1.5e-3 / 15e-3)
    assert normalised_error(-6.5e-3, -5e-3, S.e0z, S.kerr_z) == pytest.approx(0.1)


def test_threshold_in_millimetres_at_rest_and_at_full_deflection():
    # At z3_hw = 0 the monitor trips for an error above eps_th * 10 mm = 2.25 mm; at 5.4 mm, above 3.47 mm.
    mon = ConditionMonitor(S)
    assert mon.error(2.2e-3, 0.0) < S.eps_th < mon.error(2.3e-3, 0.0)
    assert mon.error(5.4e-3 + 3.4e-3, 5.4e-3) < S.eps_th < mon.error(5.4e-3 + 3.5e-3, 5.4e-3)


@settings(max_examples=200, deadline=None)
@given(md=st.floats(-0.02, 0.02), hw=st.floats(-0.02, 0.02))
def test_scalar_and_array_forms_agree_bit_for_bit(md, hw):
    mon = ConditionMonitor(S)
    a = mon.error(md, hw)
    b = normalised_error(np.array([md]), np.array([hw]), S.e0z, S.kerr_z)[0]
    assert a == b and a >= 0


def test_streaming_z3_and_offline_z3_agree():
    t = np.arange(2001) / 100
    z_md = 5.4e-3 * np.sin(2 * np.pi * 0.1 * t)
    z_hw = 0.4 * z_md - 1e-3  # a laminate bending 60 % less, with an offset: trips the monitor
    off = evaluate_z3(z_md, z_hw, S, t)
    assert off.fault_index > 0
    mon = ConditionMonitor(S)
    on = [mon.update(tk, a, b) for tk, a, b in zip(t, z_md, z_hw)]
    assert [s.eps for s in on] == off.eps.tolist()
    assert [s.count for s in on] == off.count.tolist()
    assert [s.fault for s in on] == off.fault.tolist()
    assert mon.state.fault_time == off.fault_time
    assert mon.state.max_eps == pytest.approx(off.eps.max())


def test_times_must_increase():
    mon = ConditionMonitor(S)
    mon.update(0.0, 0.0, 0.0)
    with pytest.raises(ValueError, match="must increase"):
        mon.update(0.0, 0.0, 0.0)
    with pytest.raises(ValueError, match="must increase"):
        mon.update_many(np.array([0.01, 0.01]), np.zeros(2), np.zeros(2))
    with pytest.raises(ValueError, match="increase strictly"):
        evaluate(np.zeros(3), S, np.array([0.0, 0.02, 0.01]))


def test_non_finite_samples_hold_the_counter_and_are_counted():
    mon = ConditionMonitor(S)
    mon.update_eps(0.00, 1.0)
    s = mon.update(0.01, math.nan, 1e-3)
    assert not s.valid and s.count == 2
    s = mon.update(0.02, 1e-3, math.inf)
    assert not s.valid and s.count == 2
    assert mon.state.n_invalid == 2 and mon.state.n_samples == 3


def test_empty_and_shape_errors():
    tr = evaluate(np.zeros((3, 0)), S)
    assert tr.count.shape == (3, 0) and not tr.detected.any() and np.all(tr.fault_index == -1)
    with pytest.raises(ValueError, match="time axis"):
        evaluate(np.float64(0.3), S)
    with pytest.raises(ValueError, match="shape"):
        evaluate(np.zeros(4), S, np.arange(3.0))
    mon = ConditionMonitor(S)
    with pytest.raises(ValueError, match="equal length"):
        mon.update_many_eps(np.arange(3.0), np.zeros(4))
