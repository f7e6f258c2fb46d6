"""The bad-input corpus (issue 12, point 10): every command and file type given what a lab gets wrong.

Each case runs ``shm`` in-process and must end with the expected exit code (2: bad input; 1: an unreachable peer),
one ``error:`` line naming the file/key/option or value and the reason, and no traceback. The cases and files are
in ``tests/bad_inputs_corpus.py``; all fail during validation, so the whole corpus takes seconds. A few real
subprocesses check what only a process shows (a closed pipe).
"""

from __future__ import annotations

import os
import sqlite3
import subprocess
import sys
from pathlib import Path

import pytest
from bad_inputs_corpus import all_cases, write_corpus_files
from bad_inputs_support import no_leftover_log_handlers, run_shm, run_to_one_clear_line, written_corpus  # noqa: F401 (autouse fixture)

CASES = all_cases()
ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def corpus(tmp_path_factory) -> Path:
    return written_corpus(tmp_path_factory, "bad_inputs", write_corpus_files)


def test_the_corpus_is_large_and_covers_every_command() -> None:
    assert len(CASES) >= 200
    commands = {c.argv[0] for c in CASES if c.argv}
    assert commands >= {"run", "log", "synth", "model", "harvest", "campaign", "campaign-roc", "hil", "compare",
                        "diagnose", "fit", "health", "calibrate", "discover"}


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_bad_input_is_one_clear_line(case, corpus: Path, capsys, monkeypatch) -> None:
    run_to_one_clear_line(case, corpus, capsys, monkeypatch)


def test_a_closed_pipe_is_quiet(tmp_path: Path) -> None:
    """`shm log show ... | head`: the reader goes away; no traceback, no 'Exception ignored'."""
    from firmware_sim.events import BoardEvent
    from firmware_sim.usage_log import UsageLog

    db = tmp_path / "usage.db"
    with UsageLog(db) as log:
        log.start_run(scenario="pipe")
        for k in range(3000):
            log.write(BoardEvent("telemetry", k, k * 0.01, {"regime": "SENSING", "v_battery_V": 3.0,
                                                             "monitor_count": 0, "charge_used_C": 0.0,
                                                             "incidents_total": 0}))
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    for argv in (["log", "show", "--db", str(db), "--telemetry"], ["log", "export", "--db", str(db)]):
        proc = subprocess.Popen([sys.executable, "-m", "shm_cli.main", *argv], stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, env=env, cwd=tmp_path)
        assert proc.stdout is not None and proc.stderr is not None
        proc.stdout.readline()
        proc.stdout.close()  # like `head -1`
        err = proc.stderr.read().decode()
        rc = proc.wait(60)
        assert "Traceback" not in err and "Exception ignored" not in err and "BrokenPipe" not in err, err
        assert rc in (0, 1), (rc, err)


def test_a_foreign_database_is_left_untouched_by_run_append(corpus: Path, tmp_path: Path, capsys) -> None:
    out = tmp_path / "run"
    out.mkdir()
    con = sqlite3.connect(out / "usage.db")
    con.execute("CREATE TABLE invoices(id INTEGER PRIMARY KEY, amount REAL)")
    con.commit()
    con.close()
    before = (out / "usage.db").read_bytes()
    assert run_shm(["run", "--quiet", "--append", "--out", str(out)]) == 2
    assert "another application" in capsys.readouterr().err
    assert (out / "usage.db").read_bytes() == before
    assert sorted(p.name for p in out.iterdir()) == [".shm-run.lock", "usage.db"]


@pytest.mark.parametrize("argv", [
    ["model", "frf", "--out", "{ro}/sub"],
    ["harvest", "--out", "{ro}"],
    ["run", "--quiet", "--out", "{ro}/run"],
    ["synth", "--test", "step", "--out", "{ro}/x.csv"],
    ["compare", "{good}", "--out", "{ro}"],
    ["log", "export", "--db", "{db}", "--csv", "--out", "{ro}/csv"],
])
def test_a_read_only_out_is_one_line_exit_2(argv, corpus: Path, tmp_path: Path, capsys, monkeypatch) -> None:
    """A directory the user may not write into (as root every directory is writable, so permission is simulated
    where the checks ask the system for it)."""
    ro = tmp_path / "read_only"
    ro.mkdir()
    db = tmp_path / "usage.db"
    from firmware_sim.usage_log import UsageLog

    UsageLog(db).close()
    real_access = os.access
    monkeypatch.setattr(os, "access", lambda p, mode, *a, **k: False if Path(p) == ro else real_access(p, mode))
    code = run_shm([a.format(ro=ro, good=corpus / "good.csv", db=db) for a in argv])
    err = capsys.readouterr().err
    assert code == 2 and "Traceback" not in err
    assert "read_only" in err and "not writable" in err, err
