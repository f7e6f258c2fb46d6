"""Issue 31 (scale out), the fast parts: a folder or glob becomes tasks (a subfolder a named group), the runner
orders results by key whatever the completion order, bad --scheduler input is one clear line (exit 2)."""

from __future__ import annotations

import pytest

from board_config.errors import InputError
from shm_cli.main import main
from studies.batch import TaskResult, expand_inputs, is_batch_input, run_tasks
from studies.batch.runner import check_scheduler
from studies.batch.summary import scalar_columns


def _tree(tmp_path):
    (tmp_path / "recs" / "group").mkdir(parents=True)
    for name in ("recs/b.csv", "recs/a.tdms", "recs/group/x.csv", "recs/group/y.csv", "recs/notes.txt"):
        (tmp_path / name).write_text(name)
    (tmp_path / "recs" / "empty").mkdir()
    return tmp_path / "recs"


def test_a_folder_is_one_task_per_record_and_one_per_named_group(tmp_path):
    recs = _tree(tmp_path)
    tasks = expand_inputs([str(recs)])
    assert [(t.key, [f.name for f in t.files]) for t in tasks] == [
        ("a", ["a.tdms"]), ("b", ["b.csv"]), ("group", ["x.csv", "y.csv"])]
    assert tasks[2].read() == {"x.csv": b"recs/group/x.csv", "y.csv": b"recs/group/y.csv"}
    assert [t.key for t in expand_inputs([str(recs / "*.csv")])] == ["b"]
    assert is_batch_input([str(recs)]) and is_batch_input(["x/*.csv"]) and not is_batch_input([str(recs / "b.csv")])


def test_same_stem_in_two_places_and_missing_inputs(tmp_path):
    recs = _tree(tmp_path)
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "b.csv").write_text("b")
    assert [t.key for t in expand_inputs([str(recs / "b.csv"), str(tmp_path / "other" / "b.csv")])] == [
        "other__b", "recs__b"]
    with pytest.raises(InputError, match="matches no file"):
        expand_inputs([str(tmp_path / "nothing*.csv")])
    with pytest.raises(InputError, match="no record files"):
        expand_inputs([str(recs / "empty")])
    with pytest.raises(InputError, match="tcp://HOST:PORT"):
        check_scheduler("127.0.0.1:8786")


def _slow_first(key, files, shared, options):
    return TaskResult(key, 0, f"{key}:{files['f']!r}:{shared['p']!r}:{options}")


def test_results_are_ordered_by_key_and_see_shared_inputs():
    out = run_tasks([("z", {"f": b"1"}), ("a", {"f": b"2"})], _slow_first, "opt", shared={"p": b"P"},
                    scheduler="synchronous")
    assert [r.message for r in out.results] == ["a:b'2':b'P':opt", "z:b'1':b'P':opt"]


def test_summary_columns_carry_units():
    row = scalar_columns({"verdict": "missing", "held_rms_sigma": 1.5, "n": 3, "wall_s": 2.0, "flag": True},
                         skip=("wall_s",))
    assert row == {"verdict": "missing", "held_rms_sigma": 1.5}


def test_scheduler_with_files_only_is_a_usage_error(tmp_path, capsys):
    rec = tmp_path / "r.csv"
    rec.write_text("t\n")
    assert main(["diagnose", str(rec), "--scheduler", "local", "--out", str(tmp_path / "o")]) == 2
    assert "--scheduler runs one task per record of a folder" in capsys.readouterr().err
    assert main(["compare", str(tmp_path), "--scheduler", "nowhere", "--out", str(tmp_path / "o")]) == 2
    assert "expected local, synchronous or tcp://HOST:PORT" in capsys.readouterr().err
