"""The HIL rig after its scenario (issue 27, point 9).

A lockstep stub (`shm hil serve --clock lockstep`) starts its rig again from t = 0 for every new board run — seen as
the board's command counter (its tick) starting again below the last one, while a link that reconnects inside a run
keeps counting up — so two consecutive board runs against one served stub both meet the scenario's maintenance visit
and get their verdict (before, the second run saw no high voltage, got no verdict and exited 1 without a word). A
real-time rig plays its scenario once and says so when a new board run starts.

The host's rule is checked with a fake rig (fast); the whole path — `shm hil serve` and two `shm run` processes over
a real loopback TCP socket — in the slow test."""

from __future__ import annotations

import json
import logging
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from links_support import SHORT_MAINTENANCE_SCENARIO, FakeRig

from drivers import ActuatorCommand
from hil_stub.rig_host import RigHost
from hil_stub.service import HilService

ROOT = Path(__file__).resolve().parents[2]


def _cmd(seq: int) -> ActuatorCommand:
    return ActuatorCommand(seq, 100.0, -100.0, 0.001)


def _lockstep_host() -> tuple[RigHost, list[FakeRig]]:
    built: list[FakeRig] = []

    def build() -> FakeRig:
        built.append(FakeRig())
        return built[-1]

    return RigHost(build(), mode="lockstep", restart=build), built


def test_a_new_board_run_starts_the_lockstep_rig_again():
    host, built = _lockstep_host()
    for k in range(0, 50):
        host.submit(_cmd(k))
    assert host.snapshot.tick == 50 and host.snapshot.sample.t == pytest.approx(0.5)
    for k in range(0, 3):  # a second board run: its counter starts again
        host.submit(_cmd(k))
    assert len(built) == 2 and host.restarts == 1 and host.board_runs == 2
    assert host.snapshot.tick == 3 and host.snapshot.sample.t == pytest.approx(0.03)
    assert host.endpoint is built[1] and [c.seq for c in built[1].applied] == [0, 1, 2]
    assert host.snapshot.cmd_seq_applied == 2


def test_a_reconnect_inside_a_run_does_not_restart():
    host, built = _lockstep_host()
    for k in (1, 2, 3, 3, 7, 8):  # a command sent twice, ticks given up while the link was down: still one run
        host.submit(_cmd(k))
    assert len(built) == 1 and host.restarts == 0 and host.board_runs == 1 and host.snapshot.tick == 6
    host.submit(_cmd(0xFFFFFFFF))
    host.submit(_cmd(0))  # the counter wrapping is not a new run
    assert host.restarts == 0 and host.board_runs == 1


def test_without_a_factory_or_in_real_time_the_rig_plays_on_and_says_so(caplog):
    host = RigHost(FakeRig(), mode="lockstep")
    for k in (5, 6, 1):
        host.submit(_cmd(k))
    assert host.board_runs == 2 and host.restarts == 0 and host.snapshot.tick == 3
    rt = RigHost(FakeRig(), mode="realtime", restart=FakeRig)
    with caplog.at_level(logging.WARNING, logger="hil_stub.rig"):
        rt.submit(_cmd(9))
        rt.tick()
        rt.submit(_cmd(0))
    assert rt.restarts == 0 and rt.board_runs == 2
    assert any("plays its scenario on" in m and "--clock lockstep" in m for m in rt.incidents)


def test_the_service_hands_out_a_prebuilt_rig_with_fresh_sensor_faults():
    from hil_stub.faults import FaultPlan, SensorFaults

    plan = FaultPlan(sensors=SensorFaults(noise={"z3": 1e-6}), seed=4)
    with HilService(FakeRig(), mode="lockstep", plan=plan, restart=FakeRig) as hil:
        first = [hil.host.submit(_cmd(k)) and hil.host.snapshot.sample.z3 for k in range(5)]
        again = [hil.host.submit(_cmd(k)) and hil.host.snapshot.sample.z3 for k in range(5)]
        assert hil.host.restarts == 1 and first == again  # same rig, same noise stream: the same run
        assert hil.summary()["board_runs"] == 2 and hil.summary()["rig_restarts"] == 1




@pytest.mark.slow
@pytest.mark.integration
def test_two_board_runs_against_one_served_lockstep_stub_both_get_their_verdict(tmp_path):
    scen = tmp_path / "maintenance-short.toml"
    scen.write_text(SHORT_MAINTENANCE_SCENARIO)
    summary = tmp_path / "hil.json"
    serve = subprocess.Popen(
        [sys.executable, "-m", "shm_cli.main", "hil", "serve", "--modbus-tcp", "127.0.0.1:0", "--clock", "lockstep",
         "--scenario", str(scen), "--duration", "600", "--summary", str(summary), "--status-every", "0"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT)
    try:
        assert serve.stdout is not None
        url = None
        for _ in range(20):  # bounded: the banner and the endpoint lines
            line = serve.stdout.readline()
            if "board: --link " in line:
                url = line.split("board: --link ", 1)[1].strip()
                break
        assert url, "the stub printed no --link URL"
        url += ("&" if "?" in url else "?") + "timeout=2"  # lock-step: no tick deadline
        runs = []
        for k in (1, 2):
            out = tmp_path / f"run{k}"
            r = subprocess.run([sys.executable, "-m", "shm_cli.main", "run", "--scenario", str(scen), "--link", url,
                                "--virtual", "--quiet", "--json", "--out", str(out)],
                               capture_output=True, text=True, cwd=ROOT, timeout=400)
            assert r.returncode == 0, f"board run {k}: exit {r.returncode}: {r.stderr[-1500:]}"
            runs.append(json.loads(r.stdout))
    finally:
        serve.send_signal(signal.SIGINT)
        _, err = serve.communicate(timeout=60)
    assert serve.returncode == 0, err
    for k, s in enumerate(runs, start=1):
        assert s["verdict_as_expected"] is True, f"run {k}: {s}"
        assert [m["label"] for m in s["mbit_results"]] == ["MBIT.a", "MBIT.b"], f"run {k}: {s['mbit_results']}"
    # the same rig from t = 0 for both: the same run, number for number
    assert runs[1]["mbit_results"] == runs[0]["mbit_results"]
    assert runs[1]["ticks"] == runs[0]["ticks"] and runs[1]["regime_changes"] == runs[0]["regime_changes"]
    hil = json.loads(summary.read_text())
    assert hil["board_runs"] == 2 and hil["rig_restarts"] == 1
