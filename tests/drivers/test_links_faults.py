"""Fault-injection building blocks: spec parsing with clear errors, seeded reply faults, sensor noise and stuck
channels, the rig host's refusals and its realtime pacing statistics."""

from __future__ import annotations

import math

import pytest
from links_support import FakeRig, wait_for

from drivers.link import FLAG_LIMIT_REFUSED, ActuatorCommand
from hil_stub.faults import (
    FaultPlan,
    LinkFaults,
    ReplyFaulter,
    SensorFaultRig,
    SensorFaults,
    TruthChanges,
    parse_assignments,
    parse_stuck,
)
from hil_stub.rig_host import Delivery, RigHost, check_command


def test_spec_parsing_and_errors():
    assert parse_assignments("--noise", ["z3=2e-6,v_patch=0.1", "z0dd=0.5"]) == {"z3": 2e-6, "v_patch": 0.1,
                                                                               "z0dd": 0.5}
    assert parse_stuck(["z3@12.5", "seq"]) == {"z3": 12.5, "seq": 0.0}
    with pytest.raises(ValueError, match="--noise 'z3': expected NAME=VALUE"):
        parse_assignments("--noise", ["z3"])
    with pytest.raises(ValueError, match="'abc' is not a number"):
        parse_assignments("--deviation", ["k3=abc"])
    with pytest.raises(ValueError, match="unknown channel"):
        SensorFaults(noise={"temperature": 1.0})
    with pytest.raises(ValueError, match="allowed \\[0, 1\\]"):
        LinkFaults(drop=1.5)
    with pytest.raises(ValueError, match="exceeds 1"):
        LinkFaults(drop=0.6, corrupt=0.6)
    with pytest.raises(ValueError, match=r"--deviation k3=-1\.0: .*outside the allowed range \[-0\.95, 5\]"):
        TruthChanges(deviations={"k3": -1.0})
    plan = FaultPlan(link=LinkFaults(drop=0.1, latency_s=0.002, disconnect_at_s=5.0), seed=4,
                     sensors=SensorFaults(noise={"z3": 1e-6}, stuck={"z3": 3.0}),
                     truth=TruthChanges(deviations={"k3": -0.3}, effects=("piezo_creep",)))
    text = "; ".join(plan.describe())
    for part in ("drop 10 %", "latency 2 ms", "disconnect at rig t = 5 s", "noise on z3", "z3 stuck from",
                 "truth k3 × 0.7", "added effect piezo_creep"):
        assert part in text


def test_reply_faults_are_seeded_and_hit_their_fractions():
    def draws(seed):
        f = ReplyFaulter(LinkFaults(drop=0.2, corrupt=0.1), seed, stream=1)
        return [f.draw_action() for _ in range(5000)]

    a, b = draws(7), draws(7)
    assert a == b and draws(8) != a
    assert a.count("drop") / 5000 == pytest.approx(0.2, abs=0.02)
    assert a.count("corrupt") / 5000 == pytest.approx(0.1, abs=0.015)
    f = ReplyFaulter(LinkFaults(latency_s=0.003, jitter_s=0.002), 1, 1)
    delays = [f.draw_delay() for _ in range(200)]
    assert min(delays) >= 0.003 and max(delays) <= 0.005
    data = bytes(20)
    flipped = f.flip_bit(data, 2)
    assert sum(bin(x ^ y).count("1") for x, y in zip(data, flipped)) == 1 and flipped[:2] == data[:2]


def test_sensor_noise_and_stuck_channels():
    rig = SensorFaultRig(FakeRig(), SensorFaults(noise={"z0dd": 0.5}, stuck={"z3": 0.05, "seq": 0.1}), seed=3)
    rig.apply(ActuatorCommand(1, 200.0, 0.0))
    seen = []
    for _ in range(20):
        rig.advance(0.01)
        s = rig.sample()
        assert rig.sample() == s  # repeated reads of one tick agree
        seen.append(s)
    z0 = [s.z0dd for s in seen]
    assert len(set(z0)) == 20 and 0.2 < (sum(v * v for v in z0) / 20) ** 0.5 < 1.0
    frozen_z3 = {s.z3 for s in seen if s.t >= 0.05 - 1e-12}
    assert len(frozen_z3) == 1 and seen[0].z3 not in frozen_z3
    assert {s.seq for s in seen if s.t >= 0.1 - 1e-12} == {10}
    assert rig.link_down() is False  # extras of the wrapped rig stay reachable


def test_check_command_names_the_value_and_the_limit():
    from board_config import load_mfc_limits

    lim = load_mfc_limits()
    assert check_command(ActuatorCommand(1, 1500.0, -500.0, 0.0), lim) is None
    assert "v_ch2=-500.5 V outside the MFC limits [-500, 1500] V" in check_command(
        ActuatorCommand(1, 0.0, -500.5, 0.0), lim)
    assert "v_ch1=nan" in check_command(ActuatorCommand(1, math.nan, 0.0, 0.0), lim)
    assert "board_current" in check_command(ActuatorCommand(1, 0.0, 0.0, -1e-3), lim)


def test_host_lockstep_refusal_keeps_output_and_still_advances():
    rig = FakeRig(outages=[(0.05, 0.08)])
    host = RigHost(rig, mode="lockstep")
    assert host.submit(ActuatorCommand(1, 100.0, 0.0)) is Delivery.ACCEPTED
    assert host.submit(ActuatorCommand(2, 9999.0, 0.0)) is Delivery.REFUSED
    snap = host.snapshot
    assert snap.sample.flags & FLAG_LIMIT_REFUSED and snap.sample.v_patch == 50.0 and snap.tick == 2
    assert snap.cmd_seq_applied == 1 and host.refused_count == 1 and host.incidents
    results = [host.submit(ActuatorCommand(k, 0.0, 0.0)) for k in range(3, 10)]
    # rig time 0.02 .. 0.08: the scheduled outage [0.05, 0.08) swallows three commands, time still advances
    assert results.count(Delivery.UNDELIVERED) == 3 and host.snapshot.tick == 9
    assert [c.seq for c in rig.applied] == [1, 3, 4, 5, 9]


def test_host_realtime_paces_at_100_hz_and_waits_for_the_first_command():
    host = RigHost(FakeRig(), mode="realtime", keep_lateness=True)
    host.start()
    try:
        assert not wait_for(lambda: host.pacing.ticks > 0, timeout=0.1)  # stands still until a command
        host.submit(ActuatorCommand(1, 10.0, 0.0))
        assert wait_for(lambda: host.pacing.ticks >= 30, timeout=5)
    finally:
        host.stop()
    s = host.pacing.summary()
    assert s["ticks"] >= 30 and host.snapshot.sample.t == pytest.approx(0.01 * host.snapshot.tick)
    assert len(host.pacing.lateness_samples) == s["ticks"]


def test_truth_rig_takes_the_plan_deviations_on_top_of_the_scenario():
    from board_config.scenario import load_scenario
    from hil_stub.truth import build_truth_rig

    scen = load_scenario("degraded")  # k3 -0.35, alpha_h +0.35, beta_h -0.35
    rig = build_truth_rig(scen, seed=2, truth=TruthChanges(deviations={"k3": -0.1, "k1": 0.05}))
    d = rig.describe()
    assert d["deviations"] == {"k3": -0.1, "alpha_h": 0.35, "beta_h": -0.35, "k1": 0.05} and d["seed"] == 2
    bench = build_truth_rig(None)
    assert bench.hv_present and bench.describe()["scenario"] is None  # a bench rig: amplifier connected
    with pytest.raises(ValueError, match="no such model parameter"):
        build_truth_rig(None, truth=TruthChanges(deviations={"k99": 0.1}))


def test_truth_rig_adds_the_plan_effects_after_the_scenario_ones(monkeypatch):
    import hil_stub.truth as truth

    seen = {}

    class Recorder:
        def __init__(self, scenario, **kw):
            seen.update(kw, scenario=scenario)

        def _model(self, terminal):
            seen["preloaded"] = terminal

    monkeypatch.setattr(truth, "SimulatedRig", Recorder)
    truth.build_truth_rig(None, truth=TruthChanges(effects=("air_damping", "mypkg.effects:Creep")), params="table2")
    assert seen["effects"] == ["air_damping", "mypkg.effects:Creep"] and seen["params"] == "table2"
    assert seen["hv_present"] is True and seen["preloaded"] == "amplifier"


def test_a_nan_from_the_plant_never_reaches_a_register_or_the_wire():
    from drivers.link import FLAG_SENSOR_FAULT
    from drivers.modbus_registers import decode_input_block, encode_input_block

    class NanRig(FakeRig):
        def sample(self):
            s = super().sample()
            return type(s)(s.seq, s.t, math.nan, math.inf, s.z0dd, s.v_battery, s.hv_present, s.flags)

    host = RigHost(NanRig(), mode="lockstep")
    host.submit(ActuatorCommand(1, 10.0, 0.0))
    s = host.snapshot.sample
    assert s.z3 == 0.0 and s.v_patch == 0.0 and s.flags & FLAG_SENSOR_FAULT
    words = encode_input_block(s)
    assert decode_input_block(words).sample.flags & FLAG_SENSOR_FAULT and words[6:10] == [0, 0, 0, 0]
