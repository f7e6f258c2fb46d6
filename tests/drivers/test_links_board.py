"""The board firmware over real links: one URL swaps the rig.

* Same seeded rig, same board: the MBIT verdicts over serial (pty), Modbus TCP and Modbus RTU (pty) equal the
  in-process verdicts — for a healthy laminate (PASS) and a degraded one (FAULT). The stub runs lock-step, the board
  in virtual time (the real-time pairing is what ``shm hil serve`` + ``shm run --realtime`` do; its latency figures
  come from ``bench/bench_links.py``).
* Link loss in the middle of MBIT.a — a scheduled outage (deterministic, compared tick for tick with the in-process
  link) and a vanishing endpoint (the pty is closed, the Modbus server goes away): the board's demand is zero within
  3 ticks of the first failed exchange, every incident is logged, the board recovers when the link returns, and the
  stub keeps serving. (Real-time pacing under load is measured by ``bench/bench_links.py``, not asserted here.)
* ``shm hil serve`` end to end as a subprocess.

The scenario is the shipped ``maintenance`` one with its parked and disconnected phases trimmed (same rig, same
MBITs, 29.5 s instead of 60 s of board time) to keep the suite fast.
"""

from __future__ import annotations

import signal
import subprocess
import sys

import numpy as np
import pytest
from board_run_support import run_board, scenario, verdicts
from links_support import LinkWrapper, wait_for

from drivers import open_link
from drivers.sim_link import InProcessLink
from hil_stub.service import HilService
from hil_stub.truth import build_truth_rig

pytestmark = pytest.mark.integration



def in_process(scen):
    return run_board(scen, InProcessLink(build_truth_rig(scen, seed=1)))


def over_link(scen, kind: str):
    with HilService(build_truth_rig(scen, seed=1), mode="lockstep") as hil:
        srv = {"serial": lambda: hil.add_serial("pty"), "modbus-tcp": lambda: hil.add_modbus_tcp("127.0.0.1:0"),
               "modbus-rtu": lambda: hil.add_modbus_rtu("pty")}[kind]()
        url = srv.board_url + ("&" if "?" in srv.board_url else "?") + "timeout=2"  # lock-step: no tick deadline
        result = run_board(scen, open_link(url))
        return result, hil.summary()


def assert_same_verdicts(ref, got, kind):
    (m_ref, v_ref), (m_got, v_got) = verdicts(ref), verdicts(got)
    assert v_got == v_ref, f"{kind}: maintenance verdict {v_got} != in-process {v_ref}"
    assert [m[:4] for m in m_got] == [m[:4] for m in m_ref], f"{kind}: MBIT results differ"
    # float32 on the wire: the monitor's worst normalised error agrees to ~1e-6, not bit for bit
    for a, b in zip(m_got, m_ref):
        assert a[4] == pytest.approx(b[4], rel=1e-4)


def test_healthy_laminate_same_verdicts_over_every_link(tmp_path):
    scen = scenario(tmp_path)
    ref = in_process(scen)
    mbits, final = verdicts(ref)
    assert final == ["PASS"] and [m[0] for m in mbits] == ["MBIT.a", "MBIT.b"]
    for kind in ("serial", "modbus-tcp", "modbus-rtu"):
        got, summary = over_link(scen, kind)
        assert_same_verdicts(ref, got, kind)
        assert summary["commands"] == ref.ticks + 1 and summary["refused"] == 0  # + the closing zero demand
        assert not [e for e in got.events if e.kind == "incident"], f"{kind}: unexpected incidents"


def test_degraded_laminate_is_caught_over_a_link_as_in_process(tmp_path):
    scen = scenario(tmp_path, degraded=True)
    ref = in_process(scen)
    assert verdicts(ref)[1] == ["FAULT"]
    got, _ = over_link(scen, "modbus-tcp")
    assert_same_verdicts(ref, got, "modbus-tcp")


# --------------------------------------------------------------------------------------------- link loss


def check_safe_and_recovery(result, outage_from_s: float, min_lost: int) -> None:
    """The board's trace around the longest run of failed exchanges: SAFE and zero demand within 3 ticks of the
    first failure, zero demand throughout, back out of SAFE after the link returns, incidents logged."""
    from firmware_sim.regimes import REGIME_CODES, Regime

    tr = result.trace.columns()
    ok = tr["link_ok"]
    down = np.flatnonzero(ok == 0)
    assert down.size >= 2, "the outage did not reach the board"
    runs = np.split(down, np.flatnonzero(np.diff(down) > 1) + 1)  # a stray slow reply elsewhere is a run of one
    lost = max(runs, key=len)
    k0, last_lost = int(lost[0]), int(lost[-1])
    assert abs(tr["time_s"][k0] - outage_from_s) < 0.05 and lost.size >= min_lost
    # row k holds the command sent at tick k + 1 (decided at tick k); demand = |v_ch1| + |v_ch2|
    demand = np.abs(tr["v_ch1_V"]) + np.abs(tr["v_ch2_V"])
    assert demand[k0 - 5:k0].max() > 1.0, "the loss should hit while MBIT.a is driving the laminate"
    first_zero = k0 + int(np.flatnonzero(demand[k0:] == 0.0)[0])
    assert first_zero - k0 <= 3, f"demand still non-zero {first_zero - k0} ticks after the link was lost"
    safe = REGIME_CODES[Regime.SAFE]
    assert (tr["regime_code"][k0:k0 + 4] == safe).any()
    assert np.all(demand[first_zero:last_lost + 1] == 0.0)  # zero demand for as long as the link is down
    # recovered: healthy link afterwards and the board leaves SAFE (link_recovery: 1 s of healthy link)
    assert ok[last_lost + 1:].size > 100 and ok[last_lost + 1:].mean() > 0.95
    assert (tr["regime_code"][last_lost + 1:] != safe).any()
    incidents = [e.data["incident"] for e in result.events if e.kind == "incident"]
    assert {"link_error", "link_lost"} & set(incidents) and "link_restored" in incidents
    to_safe = [e for e in result.events if e.kind == "regime_change" and e.data["to_regime"] == Regime.SAFE.value
               and e.tick > k0]
    first_failed_tick = k0 + 1  # trace row k is board tick k + 1
    assert to_safe and to_safe[0].tick <= first_failed_tick + 2  # SAFE within 3 ticks


@pytest.mark.parametrize("kind", ["serial", "modbus-tcp", "modbus-rtu"])
def test_scheduled_outage_mid_mbit_goes_safe_within_3_ticks_and_recovers(tmp_path, kind):
    """Lock-step, virtual time, deterministic: the rig's scenario schedules a 0.3 s link outage at 8 s (in MBIT.a);
    the stub answers nothing during it, exactly like the in-process link."""
    outage = ('\n[[event]]\nkind = "link_outage"\nat = { value = 8.0, unit = "s" }\n'
              'duration = { value = 0.3, unit = "s" }\n')
    scen = scenario(tmp_path, extra=outage)
    with HilService(build_truth_rig(scen, seed=1), mode="lockstep") as hil:
        srv = {"serial": lambda: hil.add_serial("pty"), "modbus-tcp": lambda: hil.add_modbus_tcp("127.0.0.1:0"),
               "modbus-rtu": lambda: hil.add_modbus_rtu("pty")}[kind]()
        url = srv.board_url + ("&" if "?" in srv.board_url else "?") + "timeout=0.15"
        result = run_board(scen, open_link(url), duration=12.0)
        # every command and PING during the 30 ticks goes unanswered (a serial link that reopens its port after 25
        # timeouts PINGs instead of sending a command: fewer commands reach the rig, as many requests are withheld)
        assert hil.host.undelivered <= 30 and srv.stats["replies_withheld_link_down"] >= 30
    check_safe_and_recovery(result, 8.0, 30)
    ref = run_board(scen, InProcessLink(build_truth_rig(scen, seed=1)), duration=12.0)
    assert list(result.trace.columns()["link_ok"]) == list(ref.trace.columns()["link_ok"])  # the same ticks fail


class EndpointAway(LinkWrapper):
    """A Link wrapper for the test: the server's endpoint goes away before exchange ``first`` and comes back before
    exchange ``last + 1`` (synchronously, counted in board ticks, so the run is the same on any machine)."""

    def __init__(self, link, server, first: int, last: int) -> None:
        super().__init__(link)
        self.server, self.first, self.last = server, first, last

    def before_exchange(self, command) -> None:
        if self.n == self.first:
            self.server.go_down()
        elif self.n == self.last + 1:
            self.server.come_back()


@pytest.mark.parametrize("kind", ["serial", "modbus-tcp"])
def test_vanishing_endpoint_mid_mbit(tmp_path, kind):
    """At board tick 500 (5 s, in MBIT.a) the pty is closed and its link removed / the Modbus server is shut down;
    it comes back under the same name / port 40 ticks later. Lock-step stub, board in virtual time."""
    scen = scenario(tmp_path)
    with HilService(build_truth_rig(scen, seed=1), mode="lockstep") as hil:
        srv = hil.add_serial("pty") if kind == "serial" else hil.add_modbus_tcp("127.0.0.1:0")
        url = srv.board_url + ("&" if "?" in srv.board_url else "?") + "timeout=0.15"
        link = EndpointAway(open_link(url), srv, 500, 539)
        result = run_board(scen, link, duration=12.0)
        assert hil.host.incident_count >= 1
    # 40 ticks away, then at most one back-off period (<= 64 exchanges) until the link reopens
    check_safe_and_recovery(result, 5.0, 40)
    lost = np.flatnonzero(result.trace.columns()["link_ok"] == 0)
    assert lost.size <= 40 + 64
    stats = link.link.stats
    assert stats["link_down"] >= 1 and (stats["reopened"] or stats["reconnected"]) >= 1


# --------------------------------------------------------------------------------------------- the CLI


def test_shm_hil_serve_end_to_end(tmp_path):
    summary = tmp_path / "hil.json"
    proc = subprocess.Popen(
        [sys.executable, "-m", "shm_cli.main", "hil", "serve", "--serial", "pty", "--modbus-tcp", "127.0.0.1:0",
         "--clock", "lockstep", "--noise", "z3=1e-6", "--seed", "5", "--duration", "60", "--summary", str(summary),
         "--status-every", "0"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    urls = []
    try:
        assert proc.stdout is not None
        for _ in range(20):  # bounded: banner, endpoint lines
            line = proc.stdout.readline()
            if "board: --link " in line:
                urls.append(line.split("board: --link ", 1)[1].strip())
            if len(urls) == 2:
                break
        assert len(urls) == 2, "the stub did not print both --link URLs"
        for url in urls:
            from drivers import ActuatorCommand

            with open_link(url + ("&" if "?" in url else "?") + "timeout=2") as link:
                samples = [link.exchange(ActuatorCommand(k, 100.0, -100.0, 0.001)) for k in range(1, 11)]
            assert samples[-1].seq > samples[0].seq and samples[-1].hv_present
    finally:
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=30)
    assert proc.returncode == 0, err
    assert "shm hil: stopped." in out
    assert wait_for(summary.exists, timeout=1)
    import json

    s = json.loads(summary.read_text())
    assert s["commands"] == 20 and "noise on z3: sigma 1e-06 m" in s["faults"]
    # the second link's commands count from 1 again: a new board run, for which the lockstep rig starts again
    assert s["board_runs"] == 2 and s["rig_restarts"] == 1 and s["rig_ticks"] == 10


def test_shm_hil_serve_rejects_bad_input():
    from shm_cli.main import main

    assert main(["hil", "serve"]) == 2
    assert main(["hil", "serve", "--modbus-tcp", "127.0.0.1:0", "--drop", "1.5", "--duration", "1"]) == 2
    assert main(["hil", "serve", "--serial", "pty", "--stuck", "temperature@1", "--duration", "1"]) == 2


def test_shm_hil_serve_names_an_endpoint_it_cannot_open(tmp_path, capsys):
    import socket

    from shm_cli.main import main

    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        assert main(["hil", "serve", "--modbus-tcp", f"127.0.0.1:{port}", "--duration", "1"]) == 2
    assert main(["hil", "serve", "--serial", str(tmp_path / "no-such-tty"), "--duration", "1"]) == 2
    err = capsys.readouterr().err
    assert f"Modbus TCP on 127.0.0.1:{port}" in err and "no-such-tty" in err
