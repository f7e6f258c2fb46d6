"""The simulated rig and the in-process link: amplifier checks, watchdog, terminals, lookahead, seeding, URLs."""

from __future__ import annotations

import math

import numpy as np
import pytest

from board_config.scenario import parse_scenario
from drivers.link import FLAG_LIMIT_REFUSED, ActuatorCommand, LinkError, RigEndpoint, open_link
from drivers.sim_link import InProcessLink
from hil_stub.rig import SimulatedRig

FLIGHT = {
    "scenario": {"name": "t", "seed": 4},
    "phase": [
        {"kind": "flight", "duration": {"value": 4.0, "unit": "s"}, "vibration_rms": {"value": 0.8, "unit": "m/s^2"},
         "tone_frequency": {"value": 17.0, "unit": "Hz"}, "tone_amplitude": {"value": 0.5, "unit": "m/s^2"}},
        {"kind": "maintenance", "duration": {"value": 3.0, "unit": "s"}},
    ],
    "event": [{"kind": "gust", "at": {"value": 1.0, "unit": "s"}, "peak": {"value": 12.0, "unit": "m/s^2"},
               "duration": {"value": 0.5, "unit": "s"}},
              {"kind": "link_outage", "at": {"value": 2.0, "unit": "s"}, "duration": {"value": 0.05, "unit": "s"}},
              {"kind": "sensor_fault", "mode": "frozen_seq", "at": {"value": 2.5, "unit": "s"},
               "duration": {"value": 0.1, "unit": "s"}}],
}


def scenario():
    return parse_scenario(FLIGHT, "<test>")


def drive(rig, n, cmd=lambda k: ActuatorCommand(k, 0.0, 0.0, 1e-3)):
    link = InProcessLink(rig)
    link.open()
    out = []
    for k in range(n):
        try:
            out.append(link.exchange(cmd(k)))
        except LinkError:
            out.append(None)
    return out


def test_rig_is_a_rig_endpoint_and_time_advances_one_tick_per_exchange():
    rig = SimulatedRig(scenario())
    assert isinstance(rig, RigEndpoint)
    s = drive(rig, 10)
    assert [x.seq for x in s] == list(range(1, 11))
    assert s[-1].t == pytest.approx(0.1)
    assert rig.sample() == s[-1]  # repeatable: sample() does not advance
    assert rig.sample() == s[-1]


def test_same_seed_same_run_and_a_different_seed_differs():
    a = drive(SimulatedRig(scenario()), 300)
    b = drive(SimulatedRig(scenario()), 300)
    c = drive(SimulatedRig(scenario(), seed=5), 300)
    assert a == b
    assert [x.z3 for x in a if x] != [x.z3 for x in c if x]


def test_lookahead_blocks_match_tick_by_tick_stepping():
    """Serving samples from 50-tick blocks gives the same truth as stepping every tick (integrator tolerance)."""
    sc = scenario().with_rig(z3_noise=0.0, accel_noise=0.0, v_patch_noise=0.0)
    a = drive(SimulatedRig(sc, lookahead_ticks=50), 350)
    b = drive(SimulatedRig(sc, lookahead_ticks=1), 350)
    za = np.array([x.z3 for x in a if x is not None])
    zb = np.array([x.z3 for x in b if x is not None])
    assert np.max(np.abs(za)) > 5e-4  # the gust moved the tip
    assert np.max(np.abs(za - zb)) < 1e-3 * np.max(np.abs(za))


def test_out_of_limit_commands_are_refused_and_flagged():
    rig = SimulatedRig(None, hv_present=True)
    link = InProcessLink(rig)
    link.open()
    link.exchange(ActuatorCommand(0, 200.0, -200.0, 1e-3))
    for bad in (ActuatorCommand(1, 1600.0, 0.0, 0.0), ActuatorCommand(2, 0.0, -600.0, 0.0),
                ActuatorCommand(3, math.nan, 0.0, 0.0), ActuatorCommand(4, 0.0, 0.0, -1.0)):
        s = link.exchange(bad)
        assert s.flags & FLAG_LIMIT_REFUSED
        assert rig.truth()["v_ch1_V"] == 200.0 and rig.truth()["v_ch2_V"] == -200.0  # last valid output kept
    s = link.exchange(ActuatorCommand(5, 0.0, 0.0, 1e-3))
    assert not s.flags & FLAG_LIMIT_REFUSED
    assert rig.refused_commands == 4


def test_watchdog_zeroes_the_demand_without_commands():
    rig = SimulatedRig(None, hv_present=True)
    rig.apply(ActuatorCommand(0, 300.0, -300.0, 1e-3))
    for _ in range(5):
        rig.advance(0.01)
    assert rig.truth()["v_ch1_V"] == 300.0
    for _ in range(20):  # 0.2 s without a command (watchdog 0.1 s)
        rig.advance(0.01)
    assert rig.truth()["v_ch1_V"] == 0.0 and rig.watchdog_trips == 1


def test_actuation_only_with_hv_equipment_and_terminal_switch():
    rig = SimulatedRig(scenario())
    assert rig.truth()["terminal"] == "harvest_coupled"
    s = drive(rig, 390, lambda k: ActuatorCommand(k, 300.0, -300.0, 1e-3))  # HV absent until 4 s
    idle = drive(SimulatedRig(scenario()), 390)
    assert s == idle  # no amplifier connected: the demand does nothing
    s = drive(rig, 110, lambda k: ActuatorCommand(k, 300.0, -300.0, 1e-3))
    s = drive(rig, 200, lambda k: ActuatorCommand(k, 300.0, -300.0, 1e-3))
    assert rig.truth()["terminal"] == "amplifier" and s[-1].hv_present
    assert s[-1].z3 == pytest.approx(2.65e-3, rel=0.1)  # a 300 V step: ~2.65 mm (table2)


def test_outages_and_frozen_sequence_from_the_scenario():
    s = drive(SimulatedRig(scenario()), 300)
    lost = [i for i, x in enumerate(s) if x is None]
    assert lost == list(range(200, 205))  # the exchanges starting inside [2.00, 2.05) s fail
    seqs = [x.seq for x in s[240:270] if x is not None]
    assert len(set(seqs)) < len(seqs)  # frozen counter between 2.5 and 2.6 s


def test_battery_discharges_with_the_declared_current():
    rig = SimulatedRig(None, battery_initial_voltage=2.9)
    q0 = rig.battery_discharged
    drive(rig, 100, lambda k: ActuatorCommand(k, 0.0, 0.0, 0.05))
    assert rig.battery_discharged - q0 == pytest.approx(0.05 * 1.0, rel=0.02)  # 50 mA for 1 s, nothing harvested
    assert rig.sample().v_battery < 2.9 - 0.04  # ohmic drop of 50 mA across 1 ohm, plus the discharge


def test_bad_rig_inputs_are_clear_errors():
    from board_config import ConfigError

    with pytest.raises(ConfigError, match="alpha_h"):
        SimulatedRig(None, deviations={"alpha_h": 1.0})  # 0.605 * 2 > 1
    with pytest.raises(ConfigError, match="no such model parameter"):
        SimulatedRig(None, deviations={"k9": 0.1})
    with pytest.raises(ConfigError, match="battery_initial_voltage"):
        SimulatedRig(None, battery_initial_voltage=3.6)
    with pytest.raises(ValueError, match="positive"):
        SimulatedRig(None).advance(0.0)


def test_sim_urls():
    link = open_link("sim:maintenance?seed=2")
    assert isinstance(link, InProcessLink) and link.rig.seed == 2 and link.rig.scenario.name == "maintenance"
    link = open_link("sim://?scenario=degraded&params=table2")
    assert link.rig.deviations["k3"] == -0.35
    link = open_link("sim")
    assert link.rig.scenario is None
    with pytest.raises(ValueError, match="unknown option"):
        open_link("sim://?bogus=1")
    with pytest.raises(LinkError, match="not open"):
        InProcessLink(SimulatedRig(None)).exchange(ActuatorCommand(0))
