"""The power manager: currents per regime, no wake without energy, brown-out declared/cleared and logged."""

from __future__ import annotations

import math

import pytest

from board_config.board import load_board_config
from drivers.link import RigSample
from firmware_sim.board import Board
from firmware_sim.power_manager import PowerBudget, PowerLedger, PowerState, power_step
from firmware_sim.regimes import Regime

CFG = load_board_config()
B = PowerBudget.from_config(CFG)


@pytest.fixture(scope="module")
def nominal_model():
    from plant import PlantModel

    return PlantModel("table2", terminal="amplifier")


def feed(voltages, regime=Regime.STANDBY_HARVEST, state=None):
    st = state or PowerState()
    stats, events = [], []
    for k, v in enumerate(voltages):
        st, s, ev = power_step(st, v, regime, k, B)
        stats.append(s)
        events.extend(ev)
    return st, stats, events


def test_currents_per_regime_come_from_the_config():
    assert B.current(Regime.STANDBY_HARVEST) == CFG.power_current_standby
    assert B.current(Regime.SENSING) == CFG.power_current_sensing
    assert B.current(Regime.MAINTENANCE) == CFG.power_current_maintenance
    assert B.current(Regime.SAFE) == CFG.power_current_safe
    ledger = PowerLedger(B)
    for _ in range(100):
        ledger.add(Regime.SENSING, 3.0)
    ledger.add(Regime.STANDBY_HARVEST, math.nan)  # unknown voltage: counted at the last known one
    ledger.add(Regime.STANDBY_HARVEST, 2.5)
    assert ledger.charge_used == pytest.approx(CFG.tick_period * (100 * CFG.power_current_sensing
                                                                  + 2 * CFG.power_current_standby))
    assert ledger.energy_used == pytest.approx(CFG.tick_period * (300 * CFG.power_current_sensing
                                                                  + 5.5 * CFG.power_current_standby))
    assert (ledger.v_first, ledger.v_last, ledger.v_min) == (3.0, 2.5, 2.5)
    assert ledger.time_by_regime()["SENSING"] == pytest.approx(1.0)


def test_energy_to_wake_threshold():
    _, s, _ = feed([B.wake_min + 1e-6])
    assert s[0].energy_ok
    _, s, _ = feed([B.wake_min - 1e-6])
    assert not s[0].energy_ok


def test_brownout_needs_consecutive_ticks_and_clears_with_hysteresis():
    low = B.brownout - 0.01
    st, s, ev = feed([low] * (B.brownout_ticks - 1) + [3.0])
    assert not any(x.brownout for x in s) and not ev
    st, s, ev = feed([low] * B.brownout_ticks)
    assert s[-1].brownout and not s[-1].energy_ok
    assert [e.data["incident"] for e in ev] == ["brownout"]
    # just above the brown-out voltage but inside the hysteresis: still browned out
    st, s, ev = feed([B.brownout + 0.5 * B.hysteresis] * 10, state=st)
    assert all(x.brownout for x in s) and not ev
    st, s, ev = feed([B.brownout + B.hysteresis + 0.01], state=st)
    assert not s[-1].brownout and [e.data["incident"] for e in ev] == ["brownout_cleared"]
    assert st.brownouts == 1


def test_unknown_voltage_holds_the_brownout_and_refuses_waking():
    st, s, _ = feed([B.brownout - 0.1] * B.brownout_ticks)
    st, s, ev = feed([math.nan] * 20, state=st)
    assert all(x.brownout for x in s) and not ev
    _, s, ev = feed([math.nan, -1.0])
    assert not any(x.energy_ok or x.brownout for x in s) and not ev


def _sample(k, v_batt, z0dd=0.0, hv=False):
    return RigSample(seq=k, t=k * 0.01, z3=0.0, v_patch=0.0, z0dd=z0dd, v_battery=v_batt, hv_present=hv)


def test_board_cannot_wake_without_energy(nominal_model):
    board = Board(CFG, nominal_model=nominal_model)
    events = []
    for k in range(1, 200):
        res = board.tick(_sample(k, 2.6, z0dd=20.0), k)  # strong load, weak battery
        events += res.events
        assert res.regime is Regime.STANDBY_HARVEST
        assert res.command.board_current == CFG.power_current_standby
    assert [e.data["incident"] for e in events if e.kind == "incident"] == ["wake_refused"]
    # the same load with a healthy battery wakes it
    board = Board(CFG, nominal_model=nominal_model)
    regs = [board.tick(_sample(k, 2.95, z0dd=20.0), k).regime for k in range(1, 10)]
    assert Regime.SENSING in regs


def test_brownout_forces_standby_from_sensing_and_is_logged(nominal_model):
    board = Board(CFG, nominal_model=nominal_model)
    for k in range(1, 10):
        board.tick(_sample(k, 2.95, z0dd=20.0), k)
    assert board.regime is Regime.SENSING
    events = []
    for k in range(10, 20):
        events += board.tick(_sample(k, 2.0, z0dd=20.0), k).events
    assert board.regime is Regime.STANDBY_HARVEST
    kinds = [(e.kind, e.data.get("incident") or e.data.get("trigger") or e.data.get("reason")) for e in events]
    assert ("incident", "brownout") in kinds
    assert ("regime_change", "brownout") in kinds
    assert ("usage_summary", "brownout") in kinds  # the open episode is closed and logged


def test_brownout_during_maintenance_goes_safe_and_aborts_the_visit(nominal_model):
    board = Board(CFG, nominal_model=nominal_model)
    k = 0
    for k in range(1, 400):
        board.tick(_sample(k, 2.95, hv=True), k)
    assert board.regime is Regime.MAINTENANCE
    events = []
    k0 = k
    for k in range(k0 + 1, k0 + 10):
        res = board.tick(_sample(k, 2.0, hv=True), k)
        events += res.events
    assert board.regime is Regime.SAFE
    assert res.command.v_ch1 == 0.0 and res.command.v_ch2 == 0.0
    verdicts = [e.data["verdict"] for e in events if e.kind == "maintenance_verdict"]
    assert verdicts == ["INCOMPLETE"]
    assert any(e.data.get("incident") == "mbit_aborted" for e in events)
