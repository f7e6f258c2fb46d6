"""The fault matrix (issue 12, point 1): serial (pty), Modbus TCP and Modbus RTU (pty) against the HIL stub with
seeded wire faults — drop 1 % and 5 %, corrupt 1 %, sample latency 2–5 ms, one 3 s disconnect — and a short
maintenance scenario (MBIT.b only, HV present 16 s), lock-step stub and the board in virtual time: deterministic, and
cheap in CPU.

What is asserted, per link and fault, against the documents (``docs/board.md``, ``docs/real-rig.md``):

* a lost reply costs at most one exchange: failed exchanges <= replies the stub dropped or corrupted (+ the ticks of
  the disconnect and the reconnect back-off);
* SAFE exactly as documented: the board enters SAFE (trigger ``link_lost``) at the ``[tick] link_loss_ticks``-th
  consecutive failed exchange and at no other time, and the supervisor re-arms it after ``[safe] link_recovery``
  (1 s = 100 ticks) of healthy link;
* the visit's MBIT verdicts equal the clean run's wherever no SAFE interrupted them, and the final visit verdict is
  the clean run's (PASS) wherever the fault rate leaves time for a visit to complete.

The measured table (SAFE count, verdicts, failed exchanges) is printed with ``-s``; the real-time variants are slow.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from links_support import maintenance_scenario
from test_links_board import EndpointAway

from drivers import open_link
from hil_stub.faults import FaultPlan, LinkFaults
from hil_stub.service import HilService
from hil_stub.truth import build_truth_rig

pytestmark = pytest.mark.integration

SCENARIO = maintenance_scenario("maintenance-mbit-b",
                                "A short maintenance visit (MBIT.b only) for the link fault matrix.", 16,
                                board='[board.maintenance]\nsequence = ["b"]\n\n')

LINKS = ("serial", "modbus-tcp", "modbus-rtu")
#: fault name -> (LinkFaults, URL timeout s or None for the link's default, links on which the fault rate leaves
#: time for a visit to complete). Lost replies cost a timeout of wall time, so lock-step runs use a short one.
#: Modbus RTU at 115200 baud leaves a rig on a real line 8.5 - 7.8 = 0.7 ms (docs/real-rig.md): a 2-5 ms rig is out
#: of budget there (a pty has no line time).
FAULTS: dict[str, tuple[LinkFaults, float | None, tuple[str, ...]]] = {
    "clean": (LinkFaults(), 0.1, ("serial", "modbus-tcp", "modbus-rtu")),
    "drop 1 %": (LinkFaults(drop=0.01), 0.1, ("serial", "modbus-tcp", "modbus-rtu")),
    "drop 5 %": (LinkFaults(drop=0.05), 0.1, ()),
    "corrupt 1 %": (LinkFaults(corrupt=0.01), 0.1, ("serial", "modbus-tcp", "modbus-rtu")),
    # the link's real reply budget: whether a reply is late depends on the machine's load, so only the SAFE rule
    # is asserted here; measured on a quiet machine in docs/real-rig.md
    "latency 2-5 ms": (LinkFaults(latency_s=0.002, jitter_s=0.003), None, ()),
    "disconnect 3 s": (LinkFaults(), 0.1, ("serial", "modbus-tcp", "modbus-rtu")),
}
DISCONNECT = (350, 649)  # exchanges: 3 s away from 3.5 s (MBIT.b running), then back under the same name / port
FAST = {("serial", "drop 5 %"), ("modbus-tcp", "drop 1 %"), ("modbus-tcp", "disconnect 3 s"),
        ("modbus-rtu", "corrupt 1 %")}


def load(tmp_path: Path):
    from board_config.scenario import load_scenario

    path = tmp_path / "maintenance-mbit-b.toml"
    path.write_text(SCENARIO)
    return load_scenario(path)


def run(scen, link, realtime: bool = False):
    from board_config.board import load_board_config
    from firmware_sim.board import Board
    from firmware_sim.runner import BoardRunner
    from firmware_sim.scheduler import Scheduler, VirtualClock, WallClock

    cfg = load_board_config(None, overrides=scen.board_overrides, overrides_source=scen.source)
    board = Board(cfg, nominal=scen.rig.params)
    runner = BoardRunner(board, link, scheduler=Scheduler(cfg.tick_rate, WallClock() if realtime else VirtualClock()))
    link.open()
    try:
        return runner.run(scen.duration), cfg
    finally:
        link.close()


def run_case(scen, kind: str, fault: str, realtime: bool = False):
    faults, timeout, _ = FAULTS[fault]
    with HilService(build_truth_rig(scen, seed=1), mode="realtime" if realtime else "lockstep",
                    plan=FaultPlan(link=faults, seed=3)) as hil:
        srv = {"serial": lambda: hil.add_serial("pty"), "modbus-tcp": lambda: hil.add_modbus_tcp("127.0.0.1:0"),
               "modbus-rtu": lambda: hil.add_modbus_rtu("pty")}[kind]()
        url = srv.board_url
        if timeout is not None and not realtime:
            url += ("&" if "?" in url else "?") + f"timeout={timeout}"
        link = open_link(url)
        if fault.startswith("disconnect"):
            link = EndpointAway(link, srv, *DISCONNECT)
        result, cfg = run(scen, link, realtime)
        lost = srv.faulter.dropped + srv.faulter.corrupted
        stats = getattr(link, "link", link).stats
        # replies that came after their exchange gave up (a lock-step plant step outlasting the timeout on a loaded
        # machine): seen when they arrive — skipped as stale, flushed, or refused as the wrong reply
        late = sum(stats[k] for k in ("stale_or_unexpected", "stale_skipped", "flushed_reads", "bad_reply"))
    return result, cfg, lost, late


def failure_runs(ok: np.ndarray) -> list[tuple[int, int]]:
    """(first row, length) of every run of failed exchanges in the trace's link_ok column."""
    down = np.flatnonzero(ok == 0)
    if down.size == 0:
        return []
    runs = np.split(down, np.flatnonzero(np.diff(down) > 1) + 1)
    return [(int(r[0]), len(r)) for r in runs]


def summarise(result) -> dict:
    ev = result.events
    return {
        "safe": sum(1 for e in ev if e.kind == "regime_change" and e.data["to_regime"] == "SAFE"),
        "mbits": [(e.data["label"], e.data["verdict"]) for e in ev if e.kind == "mbit_result"],
        "verdicts": [e.data["verdict"] for e in ev if e.kind == "maintenance_verdict"],
        "failed": int((result.trace.columns()["link_ok"] == 0).sum()),
        "misses": result.stats.deadline_misses,
        "max_eps": max((e.data["max_eps"] for e in ev if e.kind == "mbit_result"), default=float("nan")),
    }


def check_safe_as_documented(result, cfg) -> None:
    """SAFE(link_lost) at the link_loss_ticks-th consecutive failure and only then; re-armed after link_recovery."""
    tr = result.trace.columns()
    ok, regime = tr["link_ok"], tr["regime_code"]
    n_loss = cfg.tick_link_loss_ticks
    recovery = round(cfg.safe_link_recovery * cfg.tick_rate)
    entries = [e for e in result.events if e.kind == "regime_change" and e.data["to_regime"] == "SAFE"]
    # link loss, or (paced on a loaded machine) [tick] overrun_ticks missed deadlines in a row — nothing else
    assert all(e.data["trigger"] in ("link_lost", "overrun") for e in entries), [e.data for e in entries]
    entries = [e for e in entries if e.data["trigger"] == "link_lost"]
    expected = []
    for first, length in failure_runs(ok):
        if length >= n_loss and (first == 0 or regime[first - 1] != 3):  # (row -1 would wrap to the last row)
            expected.append(first + n_loss - 1)  # trace row k is board tick k + 1
    assert [e.tick - 1 for e in entries] == expected
    for e in (e for e in result.events if e.kind == "regime_change" and e.data["trigger"] == "link_recovered"):
        row = e.tick - 1
        assert np.all(ok[row - recovery + 1: row + 1] == 1) and ok[row - recovery] == 0


def check_case(kind: str, fault: str, result, cfg, lost: int, late: int, clean: dict) -> dict:
    s = summarise(result)
    check_safe_as_documented(result, cfg)
    budget = lost + late
    if fault.startswith("disconnect"):
        budget += DISCONNECT[1] - DISCONNECT[0] + 1 + 64  # the ticks away and at most one back-off period
    if fault != "latency 2-5 ms":  # (latency: no reply is lost; failures there are late replies)
        assert s["failed"] <= budget, f"{kind}/{fault}: {s['failed']} failed exchanges for {lost} lost + {late} late"
    if s["safe"] == 0 and fault != "latency 2-5 ms":
        assert s["mbits"] == clean["mbits"] and s["verdicts"] == clean["verdicts"]
    if kind in FAULTS[fault][2]:
        assert s["verdicts"][-1:] == clean["verdicts"], f"{kind}/{fault}: no visit completed ({s})"
    assert all(v == "PASS" for _, v in s["mbits"]), f"{kind}/{fault}: a link fault became an MBIT FAULT ({s})"
    return s


@pytest.fixture(scope="module")
def scen(tmp_path_factory):
    return load(tmp_path_factory.mktemp("matrix"))


@pytest.fixture(scope="module")
def clean_verdicts(scen):
    from drivers.sim_link import InProcessLink

    result, _ = run(scen, InProcessLink(build_truth_rig(scen, seed=1)))
    s = summarise(result)
    assert s["verdicts"] == ["PASS"] and s["mbits"] == [("MBIT.b", "PASS")]
    return s


CASES = [pytest.param(k, f, marks=() if (k, f) in FAST else pytest.mark.slow, id=f"{k}-{f}")
         for k in LINKS for f in FAULTS if f != "clean"]


@pytest.mark.parametrize(("kind", "fault"), CASES)
def test_fault_matrix_lockstep(scen, clean_verdicts, kind: str, fault: str):
    result, cfg, lost, late = run_case(scen, kind, fault)
    s = check_case(kind, fault, result, cfg, lost, late, clean_verdicts)
    if os.environ.get("SHM_MATRIX_PRINT"):
        print(f"\nMATRIX lockstep {kind:10s} {fault:15s} lost {lost:3d} late {late:3d} failed {s['failed']:4d} "
              f"SAFE {s['safe']} "
              f"mbits {s['mbits']} verdicts {s['verdicts']} max_eps {s['max_eps']:.4f}")


@pytest.mark.slow
@pytest.mark.realtime
@pytest.mark.parametrize("kind", LINKS)
@pytest.mark.parametrize("fault", ["clean", "drop 1 %", "drop 5 %", "corrupt 1 %", "latency 2-5 ms"])
def test_fault_matrix_realtime(scen, clean_verdicts, kind: str, fault: str):
    """The same in real time (stub paced at 100 Hz, board on the wall clock). Always: the documented SAFE rule, and
    the clean MBIT verdicts when no SAFE interrupted them. When the run has what a rig run is documented to need —
    real-time priority (``chrt -f 10``) and a machine not busier than its cores (docs/real-rig.md) — also what the
    quiet-machine tables show run after run: the visit ends with the clean verdict wherever the fault rate leaves
    time for it (a rig answering in 2-5 ms included), and lost replies cost about one exchange each (the pty paths
    add a few stalls of their own from run to run: 26 lost -> 26 to 30 failed on serial)."""
    from firmware_sim.scheduler import running_real_time

    quiet_rt = running_real_time() and os.getloadavg()[0] < (os.cpu_count() or 1)
    result, cfg, lost, _late = run_case(scen, kind, fault, realtime=True)
    s = summarise(result)
    line = (f"MATRIX realtime {kind:10s} {fault:15s} lost {lost:3d} failed {s['failed']:4d} SAFE {s['safe']} "
            f"misses {s['misses']} mbits {s['mbits']} verdicts {s['verdicts']} max_eps {s['max_eps']:.4f}")
    print("\n" + line)
    if os.environ.get("SHM_MATRIX_OUT"):  # the table from a -n 2 run (xdist workers' -s output is not shown)
        with open(os.environ["SHM_MATRIX_OUT"], "a", encoding="utf-8") as out:
            out.write(f"{line} load {os.getloadavg()[0]:.1f} {'rt' if quiet_rt else ''}\n")
    check_safe_as_documented(result, cfg)
    if s["safe"] == 0:
        assert s["mbits"] == clean_verdicts["mbits"]
    if quiet_rt:
        if kind in FAULTS[fault][2] or fault == "latency 2-5 ms":
            assert s["verdicts"][-1:] == clean_verdicts["verdicts"], f"{kind}/{fault}: no visit completed ({s})"
        assert s["failed"] <= 1.25 * lost + 20, f"{kind}/{fault}: {s['failed']} failed exchanges for {lost} lost"
