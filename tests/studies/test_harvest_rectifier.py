"""The full-bridge rectifier: ideal and with a diode drop; the closed-form charging current obeys Kirchhoff."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from plant.rectifier import FullBridge


def test_output_voltage_ideal_and_with_drop():
    v = np.array([-5.0, -0.5, 0.0, 0.2, 3.0])
    assert np.allclose(FullBridge().output_voltage(v), np.abs(v))
    assert np.allclose(FullBridge(0.3).output_voltage(v), [4.4, 0.0, 0.0, 0.0, 2.4])
    assert FullBridge().ideal and not FullBridge(0.3).ideal
    assert FullBridge(0.3).loss(2e-3) == pytest.approx(2 * 0.3 * 2e-3)


@pytest.mark.parametrize("vd", [-0.1, 6.0, float("nan")])
def test_bad_diode_drop_names_value_and_range(vd):
    with pytest.raises(ValueError, match=r"diode forward drop .* V outside the allowed range \[0, 5\] V"):
        FullBridge(vd)


@settings(max_examples=200, deadline=None)
@given(v_src=st.floats(-20, 20), r_src=st.floats(0, 2000), v_oc=st.floats(2.0, 3.1), r_int=st.floats(0.01, 100),
       v_d=st.floats(0, 0.7), i_board=st.floats(0, 5e-3))
def test_closed_form_satisfies_the_circuit(v_src, r_src, v_oc, r_int, v_d, i_board):
    bridge = FullBridge(v_d)
    i = float(bridge.charging_current(v_src, r_src, v_oc, r_int, i_board))
    assert i >= 0.0
    v_term = v_oc + r_int * (i - i_board)  # cell terminal voltage
    v_in = abs(float(bridge.terminal_voltage(v_src, r_src, i)))  # bridge input
    if i > 0:  # conducting: KVL around source, two diodes and the cell
        assert v_in - 2 * v_d == pytest.approx(v_term, abs=1e-9 * (1 + abs(v_src)))
    else:  # blocking: the bridge output cannot beat the cell's terminal voltage
        assert abs(v_src) - 2 * v_d <= v_term + 1e-12


@pytest.mark.parametrize("amp,v_d,i_board", [(3.5, 0.0, 0.0), (3.5, 0.3, 0.0), (2.5, 0.0, 2e-3), (12.0, 0.4, 1e-3),
                                             (1.9, 0.0, 0.0)])
def test_cycle_mean_current_matches_quadrature(amp, v_d, i_board):
    bridge = FullBridge(v_d)
    phi = np.linspace(0.0, 2 * np.pi, 200001)
    i = bridge.charging_current(amp * np.sin(phi), 500.0, 2.6, 1.0, i_board)
    numeric = float(np.trapezoid(i, phi) / (2 * np.pi))
    assert bridge.mean_charging_current(amp, 500.0, 2.6, 1.0, i_board) == pytest.approx(numeric, rel=1e-5,
                                                                                         abs=1e-12)
