"""Harvesting terminals and the power audit: the books close in the coupled circuit, Eq. 8 creates energy.

Short horizons (seconds) keep the suite fast; the closure is a property of every interval, not of long runs.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from board_config.battery import load_battery
from plant import G0, PlantModel, PlantStepper
from plant.battery import TheveninBattery, battery_state, initial_state, set_board_current
from studies.harvest import (
    HarvestSetup,
    eq8_required_amplitude,
    eq8_time_to_full,
    project_time_to_full,
    run_harvest,
)
from studies.harvest.reference import ReferenceCell, harvest_rhs

WHATIF = str(Path(__file__).parents[1] / "data" / "harvest_whatif.toml")


def _closure_vs_harvest(run) -> float:
    """Residual relative to what the bridge drew: the harvesting part of the books, not drowned by damping."""
    drawn = run.audit.row("memo: drawn by the bridge from the patch terminals").energy_J
    return abs(run.audit.residual_J) / drawn


@pytest.mark.parametrize("setup", [
    HarvestSetup(params=WHATIF, accel=0.1 * G0, freq=5.8, duration=6.0),
    HarvestSetup(params=WHATIF, accel=0.8 * G0, freq=12.3, v_diode=0.3, i_board=1e-4, v_start=2.4, duration=4.0),
    HarvestSetup(params=WHATIF, accel=0.3 * G0, freq=5.0, r_int=20.0, v_start=2.0, duration=5.0),
    HarvestSetup(params=WHATIF, accel=0.4 * G0, freq=5.8, duration=4.0, hysteresis=False),
    HarvestSetup(params="table2", accel=0.1 * G0, freq=17.07, duration=4.0),
], ids=["whatif-5.8Hz", "whatif-12Hz-diodes-board", "whatif-5Hz-Rint20", "whatif-linear", "table2-17Hz"])
def test_coupled_books_close_within_1_percent(setup):
    run = run_harvest(setup, project=False)
    a = run.audit
    assert a.closes(0.01), a.table()
    assert abs(a.relative_residual) < 1e-4  # in fact to integration accuracy
    # the cell's chemical energy accumulator agrees with the OCV-curve state function
    assert abs(a.battery_crosscheck_J) <= 1e-6 * max(abs(a.row("chemical energy into the cell").energy_J), 1e-12)
    if "table2" not in str(setup.params):
        assert run.q_d_end < run.q_d_start  # it charged
        assert _closure_vs_harvest(run) < 1e-3
    if not setup.hysteresis:
        e_in = a.row("base excitation power in (relative frame)").energy_J
        assert abs(a.row("Bouc-Wen hysteresis work on the laminate").energy_J) < 1e-12 * e_in  # round-off only
        # a passive piezo cannot put more into the cell than the base puts into the beam
        assert a.row("chemical energy into the cell").energy_J < e_in


def test_paper_mode_creates_energy_and_the_audit_shows_how_much():
    run = run_harvest(HarvestSetup(params=WHATIF, coupling="paper", duration=4.0), project=False)
    a = run.audit
    e_in = a.row("base excitation power in (relative frame)").energy_J
    assert not a.closes(0.01)
    assert a.energy_from_nowhere_J > 100 * e_in  # amps from a beam that absorbs about a milliwatt
    # the residual is exactly the energy the bridge took from patches that never delivered it
    assert a.residual_J == pytest.approx(-a.energy_from_nowhere_J, rel=1e-4)
    assert run.q_d_start - run.q_d_end > 0.2  # tenths of coulombs in seconds, from a milliwatt beam


def test_paper_mode_does_not_load_the_beam_but_coupled_mode_damps_it():
    base = dict(params=WHATIF, accel=0.1 * G0, freq=5.8, duration=6.0)
    paper = run_harvest(HarvestSetup(coupling="paper", **base), project=False)
    coupled = run_harvest(HarvestSetup(coupling="coupled", **base), project=False)
    open_circuit = PlantModel(WHATIF, terminal="open_circuit")
    t_tail = paper.tail["t_s"]
    res = open_circuit.simulate(HarvestSetup(**base).inputs(0.0, 6.0), t_out=np.concatenate([[0.0], t_tail]),
                                h_max=1e-3)
    z_open_trace = res["z3"][0][1:]
    z_open = np.max(np.abs(z_open_trace))
    assert np.max(np.abs(paper.tail["z3_m"] - z_open_trace)) < 1e-4 * z_open  # the very same beam motion
    assert np.max(np.abs(coupled.tail["z3_m"])) < 0.9 * z_open
    # and the loaded terminal voltage is clamped near the cell voltage
    assert coupled.chunks["va_peak_V"][-1] < paper.chunks["va_peak_V"][-1]


def test_compiled_terminals_equal_the_plain_python_statement():
    rng = np.random.default_rng(3)
    cell_spec = TheveninBattery("ML2032", r_int=1.0)
    for coupling, terminal in (("coupled", "harvest_coupled"), ("paper", "harvest_paper")):
        ep = {**cell_spec.effect_params(), "V_diode": 0.2, "i_board": 3e-4}
        m = PlantModel(WHATIF, terminal=terminal, effect_params=ep)
        prm = dict(zip(m.param_names, m.p_nominal))
        ref_cell = ReferenceCell(prm["bat_q_max"], prm["bat_taper"],
                                 np.array([prm[f"bat_ocv_{k:02d}"] for k in range(25)]))
        for _ in range(25):
            x = np.zeros(m.n_states)
            x[0:3] = rng.normal(0, 3e-3, 3)
            x[3:6] = rng.normal(0, 0.1, 3)
            x[6:9] = rng.normal(0, 5e-5, 3)
            x[9:12] = rng.normal(0, 5e-5, 3)
            x[12] = rng.uniform(-1.0, 240.0)
            u = np.array([0.0, 0.0, rng.normal(0, 2.0)])
            dx = m.rhs(0.0, x, u)
            ref = harvest_rhs(0.0, x, u, prm, ref_cell, coupling)
            scale = np.maximum(np.abs(ref), 1e-12)
            assert np.all(np.abs(dx[:25] - ref[:25]) <= 1e-9 * scale + 1e-15), (coupling, dx - ref[:25])


def test_no_charging_past_full():
    """Paper mode charges in amps: start at 99 % and let the charge controller stop it at full."""
    cell = TheveninBattery("ML2032")
    v0 = float(cell.ocv(0.01 * cell.capacity))
    run = run_harvest(HarvestSetup(params=WHATIF, coupling="paper", accel=0.3 * G0, v_start=v0, duration=10.0),
                      stop_when_full=False, project=False)
    assert run.reached_full and run.t_full_s is not None and run.t_full_s < 10.0
    assert run.q_d_end >= -1e-9  # never past full
    assert np.max(run.soc) <= 1.0 + 1e-9
    assert run.audit.row("charge controller (no charging past full)").energy_J > 0


def test_discharge_below_cutoff_is_reported():
    setup = HarvestSetup(params="table2", accel=0.1 * G0, freq=5.8, i_board=2e-3, duration=3.0)
    run = run_harvest(setup, project=False)
    assert run.q_below_cutoff == pytest.approx(2e-3 * 3.0, rel=1e-4)
    assert run.audit.closes()
    assert run.audit.row("board load").energy_J == pytest.approx(-run.audit.row(
        "chemical energy into the cell").energy_J - run.audit.row("cell internal resistance R_bint").energy_J,
        rel=1e-6)


def test_projection_agrees_with_a_run_to_full():
    """A small cell (1/10 of the ML2032 capacity) in paper mode: projected from 3 s vs measured by running on."""
    spec = load_battery("ML2032")
    small = dataclasses.replace(spec, capacity=spec.capacity / 10, q_d=spec.q_d / 10, name="ML2032/10")
    base = dict(params=WHATIF, coupling="paper", battery=small, v_start=2.3)
    full = run_harvest(HarvestSetup(duration=300.0, **base), project=False)
    assert full.reached_full and full.t_full_s is not None
    short = run_harvest(HarvestSetup(duration=3.0, **base))
    assert not short.reached_full and short.projection is not None
    assert short.projection.t_full_s == pytest.approx(full.t_full_s, rel=0.05)
    assert short.summary()["time_to_full_is_projection"] is True


def test_projection_reports_a_stall_when_the_source_never_beats_the_cell():
    setup = HarvestSetup(params="table2", duration=2.0)
    proj = project_time_to_full(setup, 234.0, 2.0)
    assert math.isinf(proj.t_full_s) and proj.stall_voltage_V == pytest.approx(2.0, abs=1e-6)


def test_eq8_required_amplitude_inverts_the_time_to_full():
    cell = TheveninBattery("ML2032", r_int=1.0)
    a = eq8_required_amplitude(cell, 2.0, 600.0)
    assert eq8_time_to_full(a, cell, 2.0) == pytest.approx(600.0, rel=1e-4)
    assert a > cell.v_nodes[0]
    assert math.isinf(eq8_time_to_full(3.0, cell, 2.0))  # below the full voltage it never gets there


def test_board_api_on_a_stepper():
    """What the power manager (issue 5) uses: a stepper, a board load current, the cell state."""
    cell = TheveninBattery("ML2032", r_int=1.0)
    m = PlantModel("table2", terminal="harvest_coupled", effect_params=cell.effect_params())
    st = PlantStepper(m, x0=initial_state(m, cell, 2.8))
    s0 = battery_state(m, st.x[0], st.p[0], st.t)
    assert s0.v_oc == pytest.approx(2.8, abs=1e-9) and not s0.full and not s0.below_cutoff
    set_board_current(st, 5e-3)
    u = np.zeros((11, 3))
    for _ in range(10):
        st.advance(u, 0.1)
    s1 = battery_state(m, st.x[0], st.p[0], st.t)
    assert s1.q_d - s0.q_d == pytest.approx(5e-3 * 1.0, rel=1e-6)
    assert s1.i_bat == pytest.approx(-5e-3) and s1.i_board == 5e-3
    assert s1.v_terminal == pytest.approx(s1.v_oc - 1.0 * 5e-3)
    assert s1.charge == pytest.approx(s1.capacity - s1.q_d) and s1.soc < s0.soc
    with pytest.raises(ValueError, match=r"board load current -0\.001 A outside the allowed range \[0, 10\] A"):
        set_board_current(st, -1e-3)
    with pytest.raises(ValueError, match="no harvesting terminal"):
        battery_state(PlantModel("table2"), np.zeros(12))


@pytest.mark.parametrize("field,value,match", [
    ("r_int", 0.0, r"internal resistance R_bint = 0\.0 ohm outside the allowed range \(0, 1e\+06\] ohm"),
    ("r_int", -2.0, r"R_bint = -2\.0 ohm outside"),
    ("accel", -0.1 * G0, r"base acceleration amplitude = -0\.1 g outside the allowed range \(0, 50\] g"),
    ("accel", float("nan"), r"base acceleration amplitude = nan g outside"),
    ("accel", 80 * G0, r"= 80\.0 g outside the allowed range \(0, 50\] g"),
    ("freq", 0.0, r"excitation frequency = 0\.0 Hz outside the allowed range \(0, 500\] Hz"),
    ("v_start", 3.4, r"start voltage 3\.4 V outside the ML2032 open-circuit-voltage table \[2, 3\.1\] V"),
    ("v_diode", -0.2, r"diode forward drop = -0\.2 V outside the allowed range \[0, 5\] V"),
    ("i_board", -1e-3, r"board load current = -0\.001 A outside the allowed range \[0, 1\] A"),
    ("duration", 0.0, r"duration = 0\.0 s outside"),
    ("coupling", "both", r"coupling 'both' unknown \(allowed: coupled, paper\)"),
    ("battery", "CR2032", r"unknown battery \(known: ML2032\)"),
])
def test_bad_setups_name_value_and_range(field, value, match):
    with pytest.raises(ValueError, match=match):
        dataclasses.replace(HarvestSetup(), **{field: value}).validate()
