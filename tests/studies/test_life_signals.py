"""SIGTERM / Ctrl-C on a life run (issue 33): real signals to a real ``shm run`` subprocess on a small life.

The life's visits run on Dask worker processes (a local cluster). A signal must stop it cleanly: exit 143 (SIGTERM)
or 130 (SIGINT), the visits already finished kept in --out (usage.db with status ``interrupted``, their records,
summary.json), no worker process left behind (checked by PID), and with ``--force`` over an earlier life, the
earlier one kept whole until the new one has a finished visit to replace it with.
"""

from __future__ import annotations

import json
import os
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import pytest
from scenario_text_support import life_scenario

ROOT = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.slow

#: 12 short visits (each ~1-5 s wall): a signal lands while visits are running on both workers
LIFE = life_scenario("signal-life", 12, 50)


def _children(pid: int) -> list[int]:
    out = subprocess.run(["ps", "-o", "pid=", "--ppid", str(pid)], capture_output=True, text=True).stdout
    return [int(x) for x in out.split()]


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    stat = Path(f"/proc/{pid}/stat")
    return not (stat.exists() and stat.read_text().split()[2] == "Z")


def _start(tmp_path: Path, out: Path, *extra: str) -> subprocess.Popen:
    toml = tmp_path / "life.toml"
    toml.write_text(LIFE)
    env = dict(os.environ, PYTHONPATH=str(ROOT), MPLBACKEND="Agg")
    return subprocess.Popen([sys.executable, "-m", "shm_cli.main", "run", "--scenario", str(toml), "--out", str(out),
                             *extra], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
                            start_new_session=True)


def _signal_after_visits(proc: subprocess.Popen, n: int, sig: int) -> tuple[list[int], str, str]:
    """Wait until ``n`` visit lines were printed, note the workers, send ``sig``; returns (workers, out, err)."""
    assert proc.stdout is not None
    lines: list[str] = []
    deadline = time.monotonic() + 240
    while sum(ln.startswith("visit ") for ln in lines) < n:
        assert time.monotonic() < deadline, lines
        ln = proc.stdout.readline()
        assert ln, f"the run ended early: {lines} {proc.stderr.read() if proc.stderr else ''}"
        lines.append(ln)
    workers = _children(proc.pid)
    assert workers, "the life runs its visits on worker processes"
    proc.send_signal(sig)
    out, err = proc.communicate(timeout=60)
    return workers, "".join(lines) + out, err


def _check_kept(out: Path, at_least: int) -> dict:
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "interrupted"
    kept = [v["visit"] for v in summary["visits"]]
    assert len(kept) >= at_least and len(kept) < 12
    db = sqlite3.connect(out / "usage.db")
    assert db.execute("SELECT status FROM runs").fetchall() == [("interrupted",)]
    assert sorted(r[0] for r in db.execute("SELECT visit FROM life_visits")) == kept
    db.close()
    for v in kept:
        assert (out / "records" / f"visit-{v:03d}_mbit-a.csv").exists()
    assert not (out / ".shm-life-new").exists()
    assert "<b>interrupted</b>" in (out / "report.html").read_text()
    return summary


@pytest.mark.parametrize("sig, code", [(signal.SIGTERM, 143), (signal.SIGINT, 130)])
def test_a_signal_stops_a_life_cleanly_and_keeps_the_finished_visits(tmp_path: Path, sig: int, code: int) -> None:
    out = tmp_path / "life"
    proc = _start(tmp_path, out)
    workers, _stdout, err = _signal_after_visits(proc, 2, sig)
    assert proc.returncode == code, err
    assert "Traceback" not in err and "internal error" not in err, err
    assert "interrupted" in err
    _check_kept(out, 2)
    time.sleep(0.5)
    assert not [w for w in workers if _alive(w)], "a worker process survived the stop"
    # nothing left running in the run's process group either (an exited helper not yet reaped by init, such as
    # multiprocessing's resource tracker that ends with the run, is a zombie, not a process left behind)
    group = subprocess.run(["ps", "-o", "stat=", "-g", str(proc.pid)], capture_output=True, text=True).stdout.split()
    assert not [s for s in group if not s.startswith("Z")], group


def test_force_keeps_the_earlier_life_until_the_new_one_has_a_visit(tmp_path: Path) -> None:
    out = tmp_path / "life"
    first = _start(tmp_path, out)
    _signal_after_visits(first, 3, signal.SIGTERM)
    before = json.loads((out / "summary.json").read_text())
    records_before = sorted(p.name for p in (out / "records").iterdir())
    # a second life with --force, stopped before any visit finished: the earlier one stays whole
    second = _start(tmp_path, out, "--force")
    assert second.stdout is not None
    assert second.stdout.readline().startswith("shm run: life scenario")  # the visits are starting
    second.send_signal(signal.SIGTERM)
    _, err = second.communicate(timeout=60)
    assert second.returncode == 143, err
    assert "before any visit finished" in err and "left as it was" in err
    assert json.loads((out / "summary.json").read_text()) == before
    assert sorted(p.name for p in (out / "records").iterdir()) == records_before
    # a third, stopped after two visits: it replaces the earlier life
    third = _start(tmp_path, out, "--force")
    _signal_after_visits(third, 2, signal.SIGTERM)
    assert third.returncode == 143
    after = _check_kept(out, 2)
    assert after["run_uid"] != before["run_uid"]
