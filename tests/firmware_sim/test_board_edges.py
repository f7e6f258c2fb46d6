"""The board at the edges of a run (issue 12, points 5 and 8), in virtual time against the in-process rig:

* a persisting condition (a frozen rig sample counter) is one ``sensor_fault`` incident when it starts and one
  ``sensor_fault_cleared`` when it ends, with its count — not one per tick;
* a finished maintenance verdict stands through a later outage: the re-arm does not restart the visit while HV
  stays present;
* every exit of the run loop — the end, an exception, a ``KeyboardInterrupt`` raised mid-tick — sends a zero
  demand through the link before the caller closes it;
* a virtual-time board against a real-time rig is detected and said (``clock_mismatch``).
"""

from __future__ import annotations

from pathlib import Path

import pytest
from board_run_support import run_board, scenario, scenario_text, verdicts
from links_support import FakeRig, LinkWrapper

from drivers.link import LinkError
from drivers.sim_link import InProcessLink
from hil_stub.faults import SensorFaultRig, SensorFaults
from hil_stub.truth import build_truth_rig


class Recorder(LinkWrapper):
    """A Link wrapper: records every command; fails exchanges in ``fail`` (1-based exchange numbers) and raises
    ``interrupt`` at exchange ``interrupt_at``."""

    def __init__(self, link, fail: range = range(0), interrupt_at: int = 0,
                 interrupt: type[BaseException] = KeyboardInterrupt) -> None:
        super().__init__(link)
        self.fail, self.interrupt_at, self.interrupt = fail, interrupt_at, interrupt
        self.sent = []

    def before_exchange(self, command) -> None:
        if self.n == self.interrupt_at:
            raise self.interrupt()
        self.sent.append(command)
        if self.n in self.fail:
            raise LinkError("test: reply lost")


def incidents(result, kind: str) -> list:
    return [e for e in result.events if e.kind == "incident" and e.data["incident"] == kind]


def test_frozen_rig_counter_is_one_incident_with_its_end_and_count(tmp_path: Path):
    scen = scenario(tmp_path)
    rig = SensorFaultRig(build_truth_rig(scen, seed=1), SensorFaults(stuck={"seq": 0.5}), seed=1)
    link = Recorder(InProcessLink(rig), fail=range(301, 302))  # one lost reply: the frozen counter reads on after it
    result = run_board(scen, link, duration=4.0)
    faults = incidents(result, "sensor_fault")
    assert len(faults) == 1 and "rig_seq frozen" in faults[0].data["detail"]
    assert len(incidents(result, "sensor_fault_cleared")) == 0  # still frozen at the end
    frozen_ticks = int((result.trace.columns()["regime_code"] == 3).sum())
    assert frozen_ticks > 300  # SAFE (sensor fault) for the ~3.5 s the counter stays frozen ...
    assert len([e for e in result.events if e.kind == "incident"]) < 10  # ... and a handful of records, not 350


def test_sensor_fault_that_ends_is_closed_with_its_duration(tmp_path: Path):
    from drivers.link import RigSample
    from firmware_sim.board import Board

    board = Board()
    ok = RigSample(0, 0.0, 0.0, 0.0, 0.0, 3.0)
    board.tick(ok, 1)
    events = []
    for k in range(2, 102):  # 100 ticks of an out-of-range z3 whose value changes every tick
        events += board.tick(RigSample(k, k * 0.01, 0.06 + 1e-4 * k, 0.0, 0.0, 3.0), k).events
    events += board.tick(RigSample(200, 2.0, 0.0, 0.0, 0.0, 3.0), 102).events
    kinds = [e.data["incident"] for e in events if e.kind == "incident"]
    assert kinds.count("sensor_fault") == 1 and kinds.count("sensor_fault_cleared") == 1
    cleared = next(e for e in events if e.kind == "incident" and e.data["incident"] == "sensor_fault_cleared")
    assert "100 tick(s)" in cleared.data["detail"] and "1.00 s" in cleared.data["detail"]


def test_a_finished_verdict_stands_through_a_later_outage(tmp_path: Path):
    from board_config.scenario import load_scenario

    path = tmp_path / "degraded-long.toml"  # the degraded laminate, HV present 3 s longer than the visit needs
    path.write_text(scenario_text("FAULT", "{ k3 = -0.35, alpha_h = 0.35, beta_h = -0.35 }", maintenance_s=31))
    scen = load_scenario(path)
    ref = run_board(scen, InProcessLink(build_truth_rig(scen, seed=1)))
    assert verdicts(ref)[1] == ["FAULT"]
    done = next(e.tick for e in ref.events if e.kind == "maintenance_verdict")
    assert done + 150 < ref.ticks, "the visit must finish well before the end of the scenario for this test"
    # a 0.5 s outage 0.2 s after the verdict, HV present throughout: SAFE, re-arm, and the FAULT stands
    out_from = done + 20
    link = Recorder(InProcessLink(build_truth_rig(scen, seed=1)), fail=range(out_from, out_from + 50))
    got = run_board(scen, link)
    to_safe = [e for e in got.events if e.kind == "regime_change" and e.data["to_regime"] == "SAFE"]
    back = [e for e in got.events if e.kind == "regime_change" and e.data["from_regime"] == "SAFE"]
    assert to_safe and back, "the outage must put the board in SAFE and the link's return re-arm it"
    assert [e.data["verdict"] for e in got.events if e.kind == "maintenance_verdict"] == ["FAULT"]
    assert [e.data["label"] for e in got.events if e.kind == "mbit_start"] == ["MBIT.a", "MBIT.b"]  # not restarted
    assert incidents(got, "visit_kept")
    # the re-armed board demands nothing: the visit is over
    assert all(c.v_ch1 == 0.0 and c.v_ch2 == 0.0 for c in link.sent[out_from + 50:])


@pytest.mark.parametrize("stop", ["end", "interrupt", "system_exit"])
def test_every_exit_commands_zero_before_the_link_closes(tmp_path: Path, stop: str):
    scen = scenario(tmp_path)
    ref_link = Recorder(InProcessLink(build_truth_rig(scen, seed=1)))
    ref = run_board(scen, ref_link, duration=9.0)  # ends in the middle of MBIT.a
    k_driving = max(i for i, c in enumerate(ref_link.sent[:-1]) if abs(c.v_ch1) > 1.0)
    assert k_driving > len(ref_link.sent) - 5, "the run should end while MBIT.a drives the laminate"
    if stop == "end":
        link = ref_link
    else:
        link = Recorder(InProcessLink(build_truth_rig(scen, seed=1)), interrupt_at=800,
                        interrupt=KeyboardInterrupt if stop == "interrupt" else SystemExit)
        with pytest.raises(KeyboardInterrupt if stop == "interrupt" else SystemExit):
            run_board(scen, link, duration=9.0)
        assert any(abs(c.v_ch1) > 1.0 for c in link.sent[-10:-1])  # interrupted while driving
    last = link.sent[-1]
    assert (last.v_ch1, last.v_ch2) == (0.0, 0.0)
    if stop == "end":
        assert ref.ticks == 900 and len(link.sent) == 901  # every tick's command plus the closing zero


def test_virtual_board_against_a_realtime_rig_is_detected(tmp_path: Path):
    from board_config.board import load_board_config
    from drivers import open_link
    from firmware_sim.board import Board
    from firmware_sim.runner import BoardRunner
    from hil_stub.service import HilService

    with HilService(FakeRig(), mode="realtime") as hil:
        srv = hil.add_serial("pty")
        link = open_link(srv.board_url + "?timeout=0.05")
        runner = BoardRunner(Board(load_board_config()), link)
        link.open()
        try:
            result = runner.run(4.0)
        finally:
            link.close()
    found = incidents(result, "clock_mismatch")
    assert len(found) == 1 and "virtual time against a real-time rig" in found[0].data["detail"]
