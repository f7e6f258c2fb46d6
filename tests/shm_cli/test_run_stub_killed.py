"""The stub SIGKILLed in the middle of a maintenance visit (issue 29, point 1): `shm hil serve` and `shm run --link`
as two processes over a loopback Modbus TCP socket; the stub is killed once MBIT.b has started. The board run ends
on its own: exit 1 (the visit is INCOMPLETE, not the scenario's PASS) and never 2, with summary.json (the lost
exchanges counted), usage.db (run finished, the verdict logged) and MBIT.a's record, which completed before."""

from __future__ import annotations

import json
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import pytest
from links_support import SHORT_MAINTENANCE_SCENARIO, link_url_printed_by

ROOT = Path(__file__).resolve().parents[2]



def _serve(scen: Path) -> tuple[subprocess.Popen, str]:
    serve = subprocess.Popen(
        [sys.executable, "-m", "shm_cli.main", "hil", "serve", "--modbus-tcp", "127.0.0.1:0", "--clock", "lockstep",
         "--scenario", str(scen), "--duration", "600", "--status-every", "0"],
        stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, cwd=ROOT)
    return serve, link_url_printed_by(serve, 20)


@pytest.mark.slow
@pytest.mark.integration
def test_the_stub_killed_mid_visit_leaves_a_complete_failed_run(tmp_path):
    scen = tmp_path / "maintenance-short.toml"
    scen.write_text(SHORT_MAINTENANCE_SCENARIO)
    serve, url = _serve(scen)
    out = tmp_path / "run"
    url += ("&" if "?" in url else "?") + "timeout=2"  # lock-step: no tick deadline
    board = subprocess.Popen([sys.executable, "-m", "shm_cli.main", "run", "--scenario", str(scen), "--link", url,
                              "--virtual", "--json", "--timeline-every-s", "0", "--out", str(out)],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT)
    killed_at = None
    try:
        assert board.stderr is not None
        t_end = time.monotonic() + 300
        while time.monotonic() < t_end:
            line = board.stderr.readline()
            if not line:
                break
            if "MBIT.b started" in line:
                serve.send_signal(signal.SIGKILL)
                killed_at = line.strip()
                break
        assert killed_at, "the board never started MBIT.b"
        stdout, stderr = board.communicate(timeout=300)
    finally:
        serve.kill()
        serve.wait(timeout=30)
        if board.poll() is None:
            board.kill()
    assert board.returncode == 1, f"exit {board.returncode}: {stderr[-2000:]}"
    summary = json.loads(stdout)
    assert summary == json.loads((out / "summary.json").read_text())
    assert summary["status"] == "finished" and summary["link_stats"]["lost_exchanges"] > 50
    assert summary["maintenance_verdicts"][-1]["verdict"] == "INCOMPLETE"
    assert [m["label"] for m in summary["mbit_results"]] == ["MBIT.a"]
    assert (out / "records" / "visit-001_mbit-a.csv").exists() and (out / "report.html").exists()
    con = sqlite3.connect(out / "usage.db")
    try:
        assert con.execute("SELECT status FROM runs").fetchall() == [("finished",)]
        assert con.execute("SELECT count(*) FROM mbit_records").fetchone() == (1,)
    finally:
        con.close()
