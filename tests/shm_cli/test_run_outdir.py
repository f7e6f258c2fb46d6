"""Nothing a user made is lost (issue 12, point 3) and a run's exit code tells the truth (point 4).

* ``--out`` in use is locked: a second ``shm run`` refuses, naming the running one (pid, start time).
* A finished run is not overwritten without ``--force``; ``--append`` adds a run to its ``usage.db``.
* SIGTERM and Ctrl-C (SIGINT) end a real ``shm run`` subprocess cleanly: status ``interrupted`` in the log, the
  timeline, summary and report written, exit 143 / 130.
* A run whose final verdict is not the scenario's expected one exits 1.
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

from shm_cli.main import main

ROOT = Path(__file__).resolve().parents[2]

TINY = """
[scenario]
name = "tiny"
seed = 1
expect_verdict = "{verdict}"

[rig]
params = "table2"
battery_initial_voltage = {{ value = 3.0, unit = "V" }}

[[phase]]
name = "parked"
kind = "ground"
duration = {{ value = 0.5, unit = "s" }}
"""


def _shm(argv: list[str]) -> int:
    try:
        return int(main(argv) or 0)
    except SystemExit as exc:
        return int(exc.code or 0)


def _tiny(tmp_path: Path, verdict: str = "NONE") -> Path:
    p = tmp_path / f"tiny_{verdict}.toml"
    p.write_text(TINY.format(verdict=verdict))
    return p


def _runs(db: Path) -> list[tuple]:
    con = sqlite3.connect(f"file:{db}?mode=ro", uri=True)
    try:
        return con.execute("SELECT run_id, status, scenario FROM runs ORDER BY run_id").fetchall()
    finally:
        con.close()


def test_a_finished_run_is_kept_unless_force_and_append_adds_a_run(tmp_path: Path, capsys) -> None:
    scn = str(_tiny(tmp_path))
    out = tmp_path / "run"
    assert _shm(["run", "--scenario", scn, "--quiet", "--out", str(out)]) == 0
    first = (out / "summary.json").read_text()
    capsys.readouterr()
    # a second run on the same directory is refused, and nothing of the first one changes
    assert _shm(["run", "--scenario", scn, "--quiet", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "holds an earlier run" in err and "tiny" in err and "--force" in err and "--append" in err
    assert (out / "summary.json").read_text() == first and len(_runs(out / "usage.db")) == 1
    # --append adds a run to the same log
    assert _shm(["run", "--scenario", scn, "--quiet", "--append", "--out", str(out)]) == 0
    assert [r[1] for r in _runs(out / "usage.db")] == ["finished", "finished"]
    # --force replaces everything: a fresh log with one run, no stray file of the earlier runs
    (out / "maintenance.png").write_bytes(b"stale figure of an earlier run")
    assert _shm(["run", "--scenario", scn, "--quiet", "--force", "--out", str(out)]) == 0
    assert len(_runs(out / "usage.db")) == 1
    assert not (out / "maintenance.png").exists() or (out / "maintenance.png").read_bytes()[:4] == b"\x89PNG"


def test_a_verdict_other_than_the_expected_one_exits_1(tmp_path: Path, capsys) -> None:
    out = tmp_path / "run"
    assert _shm(["run", "--scenario", str(_tiny(tmp_path, "PASS")), "--quiet", "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert "not the one scenario 'tiny' expects (expected PASS)" in err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["verdict_as_expected"] is False and summary["status"] == "finished"
    assert "NOT AS EXPECTED" in (out / "timeline.txt").read_text()


def _wait_running(db: Path, proc: subprocess.Popen, limit_s: float = 120.0) -> None:
    end = time.monotonic() + limit_s
    while time.monotonic() < end:
        if proc.poll() is not None:
            raise AssertionError(f"shm run ended early: {proc.communicate()}")
        if db.exists():
            try:
                if any(r[1] == "running" for r in _runs(db)):
                    return
            except sqlite3.DatabaseError:
                pass
        time.sleep(0.1)
    raise AssertionError("shm run did not start")


@pytest.mark.parametrize(("sig", "code", "name", "clock"), [(signal.SIGTERM, 143, "SIGTERM", "realtime"),
                                                           (signal.SIGINT, 130, "SIGINT", "realtime"),
                                                           (signal.SIGTERM, 143, "SIGTERM", "virtual")])
def test_a_signal_ends_a_run_cleanly_and_the_out_dir_is_locked_meanwhile(tmp_path: Path, capsys, sig, code, name,
                                                                         clock) -> None:
    out = tmp_path / "run"
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    # paced on the wall clock, or in virtual time with quiet spans (the stop must end a run of spans too): 400 000 s
    # of board time take well over a minute there (5000 s end in ~3 s, possibly before the signal)
    duration, extra = ("5000", ["--realtime"]) if clock == "realtime" else ("400000", [])
    proc = subprocess.Popen([sys.executable, "-m", "shm_cli.main", "run", "--scenario", "default", "--duration-s",
                             duration, *extra, "--quiet", "--out", str(out)], env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        _wait_running(out / "usage.db", proc)
        # the directory is in use: a second run refuses, naming the first (and touches nothing)
        assert _shm(["run", "--scenario", "maintenance", "--quiet", "--force", "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert "is in use by another running shm run" in err and f"pid {proc.pid}" in err and "started" in err
        proc.send_signal(sig)
        _stdout, stderr = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(10)
    assert proc.returncode == code, stderr
    assert "Traceback" not in stderr
    assert f"interrupted by {name}" in stderr
    assert [r[1] for r in _runs(out / "usage.db")] == ["interrupted"]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "interrupted" and 0 < summary["board_time_s"] < float(duration)
    assert summary["verdict_as_expected"] is None  # a partial run is not judged against the scenario
    assert (out / "report.html").exists() and (out / "trace.npz").exists()
    assert "interrupted by" in (out / "timeline.txt").read_text()
    # the lock went with the process: the directory can be reused (here: refused only for the earlier run)
    assert _shm(["run", "--scenario", "maintenance", "--quiet", "--out", str(out)]) == 2
    assert "holds an earlier run" in capsys.readouterr().err


def test_append_keeps_the_earlier_runs_visit_records(tmp_path: Path, capsys) -> None:
    """Every completed MBIT writes records/visit-NNN_mbit-X.csv; an appended run numbers its visits after the
    earlier ones instead of overwriting the files the earlier run's log links to."""
    out = tmp_path / "run"
    assert _shm(["run", "--scenario", "maintenance", "--quiet", "--out", str(out)]) == 0
    first = {p.name: p.read_bytes() for p in (out / "records").iterdir()}
    assert sorted(first) == ["visit-001_mbit-a.csv", "visit-001_mbit-b.csv"]
    assert _shm(["run", "--scenario", "maintenance", "--quiet", "--append", "--out", str(out)]) == 0
    now = {p.name: p.read_bytes() for p in (out / "records").iterdir()}
    assert sorted(now) == ["visit-001_mbit-a.csv", "visit-001_mbit-b.csv", "visit-002_mbit-a.csv",
                           "visit-002_mbit-b.csv"]
    assert all(now[name] == data for name, data in first.items())
    con = sqlite3.connect(out / "usage.db")
    links = con.execute("SELECT run_id, path FROM mbit_records ORDER BY id").fetchall()
    con.close()
    assert links == [(1, "records/visit-001_mbit-a.csv"), (1, "records/visit-001_mbit-b.csv"),
                     (2, "records/visit-002_mbit-a.csv"), (2, "records/visit-002_mbit-b.csv")]
