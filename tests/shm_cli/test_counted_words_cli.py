"""A count in a message of ``shm run`` agrees with its noun (``studies.batch.runner.counted``): a life stopped by a
signal keeps '1 finished visit' / '2 finished visits' (was 'finished visit(s)'), and an ``--out`` whose usage.db
has no summary.json beside it holds '1 run' / '2 runs in usage.db' (was 'run(s) in usage.db')."""

from __future__ import annotations

import signal
from pathlib import Path
from types import SimpleNamespace

import pytest
from bad_inputs_newer_life_health import LIFE
from bad_inputs_support import run_shm

import shm_cli.life_cmd as life_cmd
import studies.health.life as life
from shm_cli.stop_signal import StopOnSignal

TINY = """
[scenario]
name = "tiny"
seed = 1

[rig]
params = "table2"
battery_initial_voltage = { value = 3.0, unit = "V" }

[[phase]]
name = "parked"
kind = "ground"
duration = { value = 0.5, unit = "s" }
"""


class _StoppedBySigterm(StopOnSignal):
    """A SIGTERM already received (no handler installed: nothing is sent to the test's process)."""

    def __enter__(self) -> StopOnSignal:
        self.signal = signal.SIGTERM
        return self


@pytest.mark.parametrize(("n", "words"), [(1, "1 finished visit in"), (2, "2 finished visits in")])
def test_a_stopped_life_counts_its_finished_visits_in_words(tmp_path: Path, monkeypatch, capsys, n, words) -> None:
    toml = tmp_path / "life.toml"
    toml.write_text(LIFE, encoding="utf-8")
    out = tmp_path / "out"
    visits = [SimpleNamespace(visit=i + 1) for i in range(n)]
    monkeypatch.setattr(life_cmd, "StopOnSignal", _StoppedBySigterm)
    monkeypatch.setattr(life, "run_life", lambda *a, **k: SimpleNamespace(interrupted=True, visits=visits, planned=3))
    monkeypatch.setattr(life_cmd, "_write_life", lambda *a, **k: ({}, {}))
    code = run_shm(["run", "--scenario", str(toml), "--scheduler", "synchronous", "--quiet", "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 143, err
    assert f"shm run: interrupted by SIGTERM; status 'interrupted' recorded in {out / 'usage.db'}, {words} {out}/" \
        in err, err
    assert "(s)" not in err


def _tiny_run(tmp_path: Path) -> tuple[Path, Path]:
    """A tiny ``shm run`` into ``tmp_path/run``: (its scenario file, its --out)."""
    scn = tmp_path / "tiny.toml"
    scn.write_text(TINY, encoding="utf-8")
    out = tmp_path / "run"
    assert run_shm(["run", "--scenario", str(scn), "--quiet", "--out", str(out)]) == 0
    return scn, out


def test_an_earlier_run_without_its_summary_counts_the_runs_of_its_usage_db(tmp_path: Path, capsys) -> None:
    scn, out = _tiny_run(tmp_path)
    (out / "summary.json").unlink()  # the earlier run is told from its usage.db
    capsys.readouterr()
    assert run_shm(["run", "--scenario", str(scn), "--quiet", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "holds an earlier run (1 run in usage.db, the last started " in err, err
    assert run_shm(["run", "--scenario", str(scn), "--quiet", "--append", "--out", str(out)]) == 0
    (out / "summary.json").unlink()
    capsys.readouterr()
    assert run_shm(["run", "--scenario", str(scn), "--quiet", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "holds an earlier run (2 runs in usage.db, the last started " in err, err
    assert "(s)" not in err


def test_shm_log_counts_the_runs_of_a_usage_db_in_words(tmp_path: Path, capsys) -> None:
    _, out = _tiny_run(tmp_path)
    capsys.readouterr()
    assert run_shm(["log", "show", "--db", str(out / "usage.db")]) == 0
    assert ": 1 run\n" in capsys.readouterr().out
