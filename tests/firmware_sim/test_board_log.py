"""The SQLite usage log: schema, WAL, durability under SIGKILL (a real subprocess), and ``shm log``."""

from __future__ import annotations

import json
import os
import signal
import sqlite3
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from firmware_sim.events import BoardEvent
from firmware_sim.usage_log import (
    APPLICATION_ID,
    LOG_TABLES,
    ForeignLogError,
    UsageLog,
    open_log_readonly,
    read_table,
)

ROOT = Path(__file__).resolve().parents[2]


def test_schema_wal_and_round_trip(tmp_path):
    db = tmp_path / "log.db"
    with UsageLog(db) as log:
        run = log.start_run(scenario="x", seed=3, link_url="sim", params="table2", board_config={"a": 1})
        log.write(BoardEvent("regime_change", 5, 0.05, {"from_regime": "STANDBY_HARVEST", "to_regime": "SENSING",
                                                         "trigger": "wake", "causes": [], "v_battery_V": 2.9}))
        log.write(BoardEvent("incident", 6, 0.06, {"incident": "link_error", "regime": "SENSING", "detail": "x"}))
        assert log.write(BoardEvent("mbit_start", 7, 0.07, {})) is None  # timeline-only kind
    con = sqlite3.connect(db)
    assert con.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
    tables = {r[0] for r in con.execute("SELECT name FROM sqlite_master WHERE type='table'")}
    assert set(LOG_TABLES) | {"meta"} <= tables
    ro = open_log_readonly(db)
    cols, rows = read_table(ro, "regime_changes", run)
    d = dict(zip(cols, rows[0]))
    assert d["to_regime"] == "SENSING" and d["time_s"] == 0.05 and d["causes"] == "[]"
    cols, rows = read_table(ro, "runs")
    assert dict(zip(cols, rows[0]))["status"] == "finished"


def test_foreign_or_missing_database_is_a_clear_error(tmp_path):
    with pytest.raises(FileNotFoundError):
        open_log_readonly(tmp_path / "nope.db")
    bad = tmp_path / "bad.db"
    bad.write_bytes(b"this is not sqlite" * 100)
    with pytest.raises(ValueError, match="not a usage log"):
        open_log_readonly(bad)
    with pytest.raises(ForeignLogError, match=r"bad\.db: not an SQLite database"):
        UsageLog(bad)
    assert bad.read_bytes() == b"this is not sqlite" * 100  # untouched


def test_a_log_is_marked_as_ours_and_a_foreign_database_is_never_touched(tmp_path):
    db = tmp_path / "log.db"
    UsageLog(db).close()
    con = sqlite3.connect(db)
    assert con.execute("PRAGMA application_id").fetchone()[0] == APPLICATION_ID
    assert con.execute("PRAGMA user_version").fetchone()[0] == 1
    con.close()
    UsageLog(db).close()  # ours: reopened for appending
    other = tmp_path / "other.db"
    con = sqlite3.connect(other)
    con.execute("CREATE TABLE invoices(id INTEGER PRIMARY KEY, amount REAL)")
    con.execute("INSERT INTO invoices(amount) VALUES (12.5)")
    con.commit()
    con.close()
    before = other.read_bytes()
    with pytest.raises(ForeignLogError, match=r"other\.db: an SQLite database of another application.*invoices"):
        UsageLog(other)
    assert other.read_bytes() == before
    assert not Path(str(other) + "-wal").exists()
    # another application's id, even with tables named like ours
    con = sqlite3.connect(tmp_path / "app.db")
    con.execute("PRAGMA application_id=1234")
    con.execute("CREATE TABLE meta(key TEXT PRIMARY KEY, value TEXT)")
    con.execute("INSERT INTO meta VALUES ('schema_version', '1')")
    con.commit()
    con.close()
    with pytest.raises(ForeignLogError, match="application_id 0x4d2"):
        UsageLog(tmp_path / "app.db")


def test_a_log_written_before_the_application_id_is_still_ours(tmp_path):
    db = tmp_path / "old.db"
    UsageLog(db).close()
    con = sqlite3.connect(db)
    con.execute("PRAGMA application_id=0")
    con.execute("PRAGMA user_version=0")
    con.commit()
    con.close()
    with UsageLog(db) as log:
        log.start_run(scenario="appended")
    assert len(read_table(open_log_readonly(db), "runs")[1]) == 1


WRITER = textwrap.dedent("""
    import sys
    from firmware_sim.events import BoardEvent
    from firmware_sim.usage_log import UsageLog
    log = UsageLog(sys.argv[1], synchronous=sys.argv[2])
    log.start_run(scenario="kill-test")
    k = 0
    while True:
        k += 1
        rid = log.write(BoardEvent("telemetry", k, k * 0.01, {"regime": "SENSING", "v_battery_V": 2.9,
                                                               "monitor_count": k, "charge_used_C": 0.0,
                                                               "incidents_total": 0}))
        print(rid, k, flush=True)      # acknowledged only after the commit returned
""")


@pytest.mark.integration
@pytest.mark.parametrize("sync", ["NORMAL", "FULL"])
def test_sigkill_mid_run_loses_no_committed_record(tmp_path, sync):
    db = tmp_path / "kill.db"
    script = tmp_path / "writer.py"
    script.write_text(WRITER)
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.Popen([sys.executable, str(script), str(db), sync], stdout=subprocess.PIPE, text=True, env=env,
                            cwd=ROOT)
    acked: list[int] = []
    deadline = time.monotonic() + 60
    assert proc.stdout is not None
    while len(acked) < 300 and time.monotonic() < deadline:
        line = proc.stdout.readline()
        if not line:
            break
        acked.append(int(line.split()[1]))
    os.kill(proc.pid, signal.SIGKILL)  # mid-write: the writer never stops on its own
    proc.wait(timeout=30)
    assert proc.returncode == -signal.SIGKILL
    assert len(acked) >= 300, "the writer did not acknowledge enough records"
    con = sqlite3.connect(db)  # reopening replays the WAL
    assert con.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
    stored = {r[0] for r in con.execute("SELECT monitor_count FROM telemetry")}
    missing = set(acked) - stored
    assert not missing, f"committed records lost: {sorted(missing)[:10]}"
    status = con.execute("SELECT status FROM runs").fetchone()[0]
    assert status == "running"  # the run never finished: visible as such


def _cli(*args: str) -> subprocess.CompletedProcess:
    code = "import sys; from shm_cli.main import main; sys.exit(main(sys.argv[1:]))"
    return subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True, cwd=ROOT,
                          env=dict(os.environ, PYTHONPATH=str(ROOT)), timeout=300)


def test_log_show_and_export(tmp_path):
    db = tmp_path / "log.db"
    with UsageLog(db) as log:
        log.start_run(scenario="demo", seed=1)
        log.write(BoardEvent("regime_change", 5, 0.05, {"from_regime": "STANDBY_HARVEST", "to_regime": "SENSING",
                                                         "trigger": "wake", "causes": [], "v_battery_V": 2.9}))
        log.write(BoardEvent("maintenance_verdict", 9, 0.09, {"verdict": "PASS", "mbits": "MBIT.a", "detail": "ok"}))
    r = _cli("log", "show", "--db", str(db))
    assert r.returncode == 0, r.stderr
    assert "scenario demo" in r.stdout and "SENSING" in r.stdout and "verdict=PASS" in r.stdout
    r = _cli("log", "export", "--db", str(db))
    assert r.returncode == 0, r.stderr
    data = json.loads(r.stdout)
    assert data["tables"]["maintenance_verdicts"][0]["verdict"] == "PASS"
    out = tmp_path / "csv"
    r = _cli("log", "export", "--db", str(db), "--csv", "--out", str(out))
    assert r.returncode == 0, r.stderr
    text = (out / "regime_changes.csv").read_text().splitlines()
    assert text[0].startswith("id,run_id,tick,time_s,from_regime") and "wake" in text[1]
    r = _cli("log", "export", "--db", str(db), "--csv", "--table", "incidents")
    assert r.returncode == 0 and r.stdout.startswith("id,run_id,tick,time_s,incident")
    # bad input: exit 2 with a message naming it
    r = _cli("log", "show", "--db", str(tmp_path / "missing.db"))
    assert r.returncode == 2 and "missing.db" in r.stderr
    r = _cli("log", "export", "--db", str(db), "--table", "nope")
    assert r.returncode == 2 and "unknown table" in r.stderr
    r = _cli("log", "show", "--db", str(db), "--run", "7")
    assert r.returncode == 2 and "no such run" in r.stderr
