"""`shm log` reaches every table of a usage log (issue 27, point 5): the board's own tables, ``meta``, and the tables
``shm run`` adds to the same file — ``mbit_records`` (the link from each MBIT verdict to its record file) and
``life_visits`` (the visits of a life). ``shm log show --tables`` lists them, ``--table NAME`` shows any of them, and
``shm log export`` (JSON and CSV) writes them all.

The log is built with the real writers' schemas (``UsageLog`` and ``studies.health.visit_records.LINK_SCHEMA``), so
a change of either is seen here."""

from __future__ import annotations

import csv
import json
import sqlite3
from pathlib import Path

import pytest

from firmware_sim.events import BoardEvent
from firmware_sim.usage_log import UsageLog, log_tables, open_log_readonly, read_table
from shm_cli.main import main
from studies.health.visit_records import LINK_SCHEMA

RECORD = "records/visit-001_mbit-a.csv"


def _log(path: Path, linked: bool = True) -> Path:
    with UsageLog(path) as log:
        run = log.start_run(scenario="aging", seed=3)
        log.write(BoardEvent("mbit_result", 120, 1.2, {"mbit": "a", "label": "MBIT.a", "verdict": "PASS",
                                                       "max_count": 0, "max_eps": 0.1}))
        log.write(BoardEvent("maintenance_verdict", 130, 1.3, {"verdict": "PASS", "mbits": "MBIT.a", "detail": "ok"}))
    if linked:
        db = sqlite3.connect(str(path), isolation_level=None)
        db.executescript("BEGIN;" + LINK_SCHEMA + "COMMIT;")
        db.execute("INSERT INTO mbit_records(run_id, mbit_result_id, tick, time_s, visit, mbit, verdict, path, "
                   "operating_hours, n_samples, bytes) VALUES (?, 1, 119, 1.19, 1, 'a', 'PASS', ?, 250.0, 2201, "
                   "95000)", (run, RECORD))
        db.execute("INSERT INTO life_visits(run_id, visit, operating_hours, board_time_s, flights_before, verdict, "
                   "truth_json, seed) VALUES (?, 1, 250.0, 900000.0, 40, 'PASS', '{}', 3)", (run,))
        db.close()
    return path


@pytest.fixture
def db(tmp_path: Path) -> Path:
    return _log(tmp_path / "usage.db")


def test_reader_lists_and_reads_every_table(db):
    ro = open_log_readonly(db)
    tables = log_tables(ro)
    assert tables[:2] == ["meta", "runs"] and tables[-2:] == ["mbit_records", "life_visits"]
    cols, rows = read_table(ro, "mbit_records", 1)
    assert dict(zip(cols, rows[0]))["path"] == RECORD
    cols, rows = read_table(ro, "meta", 1)  # no run_id column: the whole table
    assert "schema_version" in [r[0] for r in rows]


def test_show_tables_lists_the_linked_tables(db, capsys):
    assert main(["log", "show", "--db", str(db), "--tables"]) == 0
    out = capsys.readouterr().out
    for t in ("meta", "runs", "mbit_results", "maintenance_verdicts", "mbit_records", "life_visits"):
        assert f"  {t} " in out, t
    line = next(x for x in out.splitlines() if x.strip().startswith("mbit_records"))
    assert "1 / 1" in line and "mbit_result_id" in line and "operating_hours" in line


def test_show_one_linked_table_and_the_timeline(db, capsys):
    assert main(["log", "show", "--db", str(db), "--table", "mbit_records"]) == 0
    out = capsys.readouterr().out
    assert "table mbit_records of run 1: 1 row(s)" in out and RECORD in out
    assert main(["log", "show", "--db", str(db), "--table", "life_visits"]) == 0
    assert "900000" in capsys.readouterr().out
    assert main(["log", "show", "--db", str(db)]) == 0  # the timeline names each MBIT's record file
    assert f"path={RECORD}" in capsys.readouterr().out


def test_export_writes_every_table_json_and_csv(db, tmp_path, capsys):
    assert main(["log", "export", "--db", str(db)]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert {"meta", "runs", "mbit_records", "life_visits"} <= set(doc["tables"])
    assert doc["tables"]["mbit_records"][0]["verdict"] == "PASS"
    assert doc["tables"]["life_visits"][0]["board_time_s"] == 900000.0
    out = tmp_path / "csv"
    assert main(["log", "export", "--db", str(db), "--csv", "--out", str(out)]) == 0
    with (out / "mbit_records.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert rows[0]["path"] == RECORD and {"time_s", "operating_hours", "bytes"} <= set(rows[0])
    with (out / "life_visits.csv").open() as fh:
        header = next(csv.reader(fh))
    assert {"operating_hours", "board_time_s", "flights_before"} <= set(header)
    assert main(["log", "export", "--db", str(db), "--csv", "--table", "life_visits"]) == 0
    assert capsys.readouterr().out.startswith("id,run_id,visit,operating_hours,board_time_s")


def test_a_table_this_log_lacks_is_a_clear_error(tmp_path, capsys):
    db = _log(tmp_path / "plain.db", linked=False)
    assert main(["log", "show", "--db", str(db), "--table", "mbit_records"]) == 2
    err = capsys.readouterr().err
    assert "no such table" in err and "tables in" in err and "Traceback" not in err
    assert main(["log", "export", "--db", str(db), "--table", "invoices"]) == 2
    assert "unknown table" in capsys.readouterr().err
    assert main(["log", "show", "--db", str(db), "--tables", "--table", "runs"]) == 2


def test_a_log_from_before_the_application_id_with_linked_tables_is_ours(db):
    """A log written before the application id was set (id 0) is recognised by its tables: the linked ones too."""
    con = sqlite3.connect(str(db))
    con.execute("PRAGMA application_id=0")
    con.commit()
    con.close()
    with UsageLog(db) as log:  # not refused as another application's database
        log.start_run(scenario="again")
