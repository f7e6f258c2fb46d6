"""The ML2032 table, its loader, and the Thevenin cell the harvesting terminals use (Eq. 6-10)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from board_config import ConfigError
from board_config.battery import MAH, available_batteries, load_battery, read_ocv_table
from plant.battery import TheveninBattery


@pytest.fixture(scope="module")
def spec():
    return load_battery("ML2032")


@pytest.fixture(scope="module")
def cell():
    return TheveninBattery("ML2032", r_int=1.0)


def test_ml2032_table_matches_its_ratings_and_says_it_is_an_approximation(spec):
    assert "ML2032" in available_batteries()
    assert spec.capacity == pytest.approx(65 * MAH)
    assert spec.voltage_range == (pytest.approx(2.0), pytest.approx(3.1))
    assert np.all(np.diff(spec.q_d) > 0) and np.all(np.diff(spec.v_oc) < 0)
    assert "APPROXIMATION" in spec.provenance and "not a digitisation" in spec.provenance
    # anchor points the header names: 2.8 V at 10 % depth of discharge, about 2.5 V mid-discharge
    assert float(spec.ocv(0.1 * spec.capacity)) == pytest.approx(2.8, abs=0.01)
    assert float(spec.ocv(0.5 * spec.capacity)) == pytest.approx(2.5, abs=0.05)
    # a full cell holds roughly 234 C x ~2.55 V of chemical energy
    assert 550.0 < float(spec.stored_energy(0.0)) < 650.0


def test_cb_eq6_is_positive_and_finite_over_the_table(spec, cell):
    v = np.linspace(2.0, 3.1, 45)
    cb = spec.capacitance(v)
    assert np.all(np.isfinite(cb)) and np.all(cb > 0)
    # the plant's resampled curve (25 nodes) gives the same C_b to within the resampling error
    cb_plant = cell.capacitance(v[2:-2])
    assert np.all(cb_plant > 0)
    assert np.median(np.abs(cb_plant / cb[2:-2] - 1)) < 0.1


def test_plant_curve_follows_the_table_within_5_mV(spec, cell):
    q = np.linspace(0.0, spec.capacity, 2001)
    assert np.max(np.abs(cell.ocv(q) - spec.ocv(q))) < 5e-3
    # through every table point
    assert np.max(np.abs(cell.ocv(spec.q_d) - spec.v_oc)) < 5e-3
    assert np.all(np.diff(cell.ocv(q)) < 0)


def test_eq10_denominator_changes_sign_on_the_ml2032_curve(cell):
    """Eq. 9-10 use q_b = C_b v_b; its curvature term flips the sign of the 'capacitance' over the upper half."""
    v = np.linspace(2.05, 3.05, 41)
    ratio = cell.eq10_denominator(v) / cell.spec.capacitance(v)
    assert np.min(ratio) < 0 < np.max(ratio)


@settings(max_examples=60, deadline=None)
@given(st.floats(2.0, 3.1))
def test_discharged_capacity_inverts_ocv(v):
    cell = TheveninBattery("ML2032")
    q = cell.discharged_capacity(v)
    assert 0.0 <= q <= cell.capacity
    assert float(cell.ocv(q)) == pytest.approx(v, abs=1e-9)


@settings(max_examples=40, deadline=None)
@given(st.floats(0.0, 234.0), st.floats(0.0, 234.0), st.floats(0.0, 234.0))
def test_chemical_energy_is_a_state_function(a, b, c):
    cell = TheveninBattery("ML2032")
    assert cell.chemical_energy(a, b) + cell.chemical_energy(b, c) == pytest.approx(cell.chemical_energy(a, c),
                                                                                   abs=1e-9)
    assert cell.chemical_energy(a, b) == pytest.approx(-cell.chemical_energy(b, a), abs=1e-12)


def test_chemical_energy_matches_quadrature(cell, spec):
    from scipy.integrate import quad

    e_full = cell.energy_to_full(cell.capacity)
    ref, _ = quad(lambda q: float(cell.ocv(q)), 0.0, cell.capacity, limit=200, points=list(cell.q_nodes[1:-1]))
    assert e_full == pytest.approx(ref, rel=1e-9)
    assert e_full == pytest.approx(float(spec.stored_energy(0.0)), rel=5e-3)


def test_unknown_battery_is_named_with_the_known_ones():
    with pytest.raises(ConfigError, match=r"unknown battery.*known: ML2032"):
        load_battery("CR2032")
    with pytest.raises(ConfigError, match="unknown battery"):
        TheveninBattery("LIR2032")


@pytest.mark.parametrize("v", [1.5, 3.5, float("nan")])
def test_start_voltage_outside_the_table_names_value_and_range(cell, v):
    with pytest.raises(ValueError, match=r"start voltage .* outside .*\[2, 3\.1\] V"):
        cell.discharged_capacity(v, "start voltage")


@pytest.mark.parametrize("r", [0.0, -1.0, float("inf")])
def test_internal_resistance_must_be_positive(r):
    with pytest.raises(ValueError, match=r"R_bint = .* ohm outside the allowed range \(0, 1e\+06\] ohm"):
        TheveninBattery("ML2032", r_int=r)


def _write_table(tmp_path: Path, rows: str, header: str = "# test table\n") -> Path:
    p = tmp_path / "cell.csv"
    p.write_text(header + "discharged_capacity_mAh,open_circuit_voltage_V\n" + rows)
    return p


def test_table_errors_name_file_row_and_column(tmp_path):
    p = _write_table(tmp_path, "0,3.1\n10,2.9\n20,2.95\n30,2.0\n")
    with pytest.raises(ConfigError, match=r"cell\.csv: key 'row 3, column open_circuit_voltage_V'.*decrease"):
        read_ocv_table(p)
    p = _write_table(tmp_path, "0,3.1\n10,abc\n20,2.0\n")
    with pytest.raises(ConfigError, match=r"row 2, column open_circuit_voltage_V.*not a number: 'abc'"):
        read_ocv_table(p)
    p = _write_table(tmp_path, "0,3.1\n10,2.5\n10,2.0\n")
    with pytest.raises(ConfigError, match=r"row 3, column discharged_capacity_mAh.*increase"):
        read_ocv_table(p)
    p = _write_table(tmp_path, "0,3.1\n10,2.5\n20,2.0\n", header="")
    with pytest.raises(ConfigError, match="provenance header"):
        read_ocv_table(p)
    p = tmp_path / "cols.csv"
    p.write_text("# x\ncapacity,volts\n0,3\n1,2\n2,1\n")
    with pytest.raises(ConfigError, match="columns must be"):
        read_ocv_table(p)


def test_ratings_that_disagree_with_the_table_are_refused(tmp_path):
    table = _write_table(tmp_path, "0,3.1\n30,2.5\n60,2.0\n")
    toml = tmp_path / "cells.toml"
    toml.write_text(
        '[X]\ndescription = "x"\nocv_table = "cell.csv"\n[X.ratings]\n'
        'nominal_voltage = { value = 3.0, unit = "V" }\ncapacity = { value = 234.0, unit = "C" }\n'
        'cutoff_voltage = { value = 2.0, unit = "V" }\nfull_voltage = { value = 3.1, unit = "V" }\n'
        'charge_voltage_max = { value = 3.3, unit = "V" }\n')
    assert table.exists()
    with pytest.raises(ConfigError, match=r"X\.ratings\.capacity.*disagrees"):
        load_battery("X", toml)
    toml.write_text(toml.read_text().replace('capacity = { value = 234.0, unit = "C" }',
                                             'capacity = { value = 216.0, unit = "mAh" }'))
    with pytest.raises(ConfigError, match=r"X\.ratings\.capacity\.unit.*expected unit 'C'"):
        load_battery("X", toml)
    toml.write_text(toml.read_text().replace('{ value = 216.0, unit = "mAh" }', '{ value = 216.0, unit = "C" }'))
    assert load_battery("X", toml).capacity == pytest.approx(216.0)


def test_monotone_cubic_equals_scipy_pchip(spec):
    """board_config keeps its own PCHIP (no scipy import on load); it must be scipy's, value, slope and integral."""
    from scipy.interpolate import PchipInterpolator

    from board_config.battery import MonotoneCubic

    rng = np.random.default_rng(7)
    for x, y in ((spec.q_d, spec.v_oc), (np.cumsum(rng.uniform(0.1, 2.0, 12)), rng.normal(size=12))):
        mine, ref = MonotoneCubic(x, y), PchipInterpolator(x, y)
        xq = np.linspace(x[0], x[-1], 3001)
        for order in (0, 1, 2):
            assert np.allclose(mine(xq[1:-1], order), ref.derivative(order)(xq[1:-1]) if order else ref(xq[1:-1]),
                               rtol=1e-10, atol=1e-10)
        assert mine.integral(x[1], x[-2]) == pytest.approx(ref.integrate(x[1], x[-2]), rel=1e-12)
