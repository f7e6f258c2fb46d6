"""A batch (``shm diagnose FOLDER``) or a fleet (``shm health --fleet``) run again into the same ``--out``: each task's
folder holds what this run wrote — an earlier run's figure or page no longer sits beside the new report — and a file
the user put there is never removed (shm_cli/batch_out.py: the earlier batch's marker lists the files it wrote)."""

from __future__ import annotations

import json

import pytest

from shm_cli.main import main


@pytest.fixture
def fake_tasks(monkeypatch):
    """``run_tasks`` replaced by tasks that return ``files[key]`` (no command runs); ``files`` is set by the test."""
    import studies.batch as batch
    from studies.batch import TaskResult
    from studies.batch.runner import BatchOutcome

    files: dict[str, dict[str, bytes]] = {}

    def run_tasks(tasks, *_a, **_k):
        return BatchOutcome([TaskResult(k, 0, "done", {}, dict(files[k])) for k, _ in tasks], "fake", 1)

    monkeypatch.setattr(batch, "run_tasks", run_tasks)
    return files


def _records(tmp_path):
    recs = tmp_path / "recs"
    recs.mkdir()
    for name in ("a.csv", "b.csv"):
        (recs / name).write_text("t\n")
    return recs


def _tree(folder):
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*") if p.is_file())


def test_a_rerun_batch_leaves_no_earlier_file_in_a_tasks_folder_and_keeps_the_users(tmp_path, fake_tasks, capsys):
    recs, out = _records(tmp_path), tmp_path / "out"
    argv = ["diagnose", str(recs), "--scheduler", "synchronous", "--out", str(out)]
    first = {"diagnosis.json": b'{"run": 1}', "diagnosis.html": b"1", "fit_k3.png": b"1", "figs/frf.png": b"1",
             "log.txt": b"1"}
    fake_tasks.update({"a": first, "b": first})
    assert main(argv) == 0
    assert json.loads((out / "batch.json").read_text())["task_files"]["a"] == sorted(first)
    (out / "a" / "my notes.txt").write_text("mine")  # the user's own file, after the first run
    (out / "a" / "figs" / "mine.png").write_text("mine too")
    capsys.readouterr()
    # the second run writes no fit figure and no figs/ (another candidate won, a task failed ...)
    second = {"diagnosis.json": b'{"run": 2}', "diagnosis.html": b"2", "log.txt": b"2"}
    fake_tasks.update({"a": second, "b": second})
    assert main(argv) == 0
    assert _tree(out / "b") == sorted(second)  # before: fit_k3.png and figs/frf.png of the first run beside it
    assert not (out / "b" / "figs").exists()
    assert _tree(out / "a") == sorted([*second, "figs/mine.png", "my notes.txt"])
    assert (out / "a" / "my notes.txt").read_text() == "mine"
    assert (out / "a" / "diagnosis.json").read_bytes() == b'{"run": 2}'
    err = capsys.readouterr().err
    assert f"{out / 'a'} also holds 2 files this run did not write, left as they are" in err, err
    assert str(out / "b") not in err.replace(str(out / "b") + "/", "")  # nothing to say about b
    assert json.loads((out / "batch.json").read_text())["task_files"] == {"a": sorted(second),
                                                                          "b": sorted(second)}


def test_a_batch_that_kept_no_file_list_has_nothing_removed(tmp_path, fake_tasks, capsys):
    """A batch.json written before the list was kept: its task folders' files are not known to be the tool's."""
    recs, out = _records(tmp_path), tmp_path / "out"
    (out / "a").mkdir(parents=True)
    (out / "batch.json").write_text('{"command": "diagnose"}')
    (out / "a" / "old.png").write_text("old")
    fake_tasks.update({"a": {"log.txt": b"x"}, "b": {"log.txt": b"x"}})
    assert main(["diagnose", str(recs), "--scheduler", "synchronous", "--out", str(out)]) == 0
    assert (out / "a" / "old.png").read_text() == "old"
    assert "also holds 1 file this run did not write, left as they are: old.png" in capsys.readouterr().err


def test_a_marker_edited_to_name_files_outside_the_task_removes_nothing(tmp_path, fake_tasks, capsys):
    recs, out = _records(tmp_path), tmp_path / "out"
    out.mkdir()
    (tmp_path / "precious.txt").write_text("keep")
    (out / "summary.csv").write_text("t")
    (out / "batch.json").write_text(json.dumps({"command": "diagnose", "task_files": {
        "a": ["../../precious.txt", "../summary.csv", str(tmp_path / "precious.txt")]}}))
    fake_tasks.update({"a": {"log.txt": b"x"}, "b": {"log.txt": b"x"}})
    assert main(["diagnose", str(recs), "--scheduler", "synchronous", "--out", str(out)]) == 0
    assert (tmp_path / "precious.txt").read_text() == "keep"


def test_an_earlier_task_this_run_did_not_run_is_left_and_said(tmp_path, fake_tasks, capsys):
    recs, out = _records(tmp_path), tmp_path / "out"
    argv = ["diagnose", str(recs), "--scheduler", "synchronous", "--out", str(out)]
    fake_tasks.update({"a": {"log.txt": b"1"}, "b": {"log.txt": b"1"}})
    assert main(argv) == 0
    (recs / "b.csv").unlink()
    capsys.readouterr()
    assert main(argv) == 0
    assert (out / "b" / "log.txt").is_file()
    assert f"{out / 'b'} is a task of an earlier batch, not of this one" in capsys.readouterr().err
    assert json.loads((out / "batch.json").read_text())["task_files"]["b"] == ["log.txt"]


def _fake_board(folder):
    (folder / "records").mkdir(parents=True)
    (folder / "usage.db").write_bytes(b"")
    return folder


def test_a_rerun_fleet_leaves_no_earlier_file_in_a_boards_folder(tmp_path, fake_tasks, capsys):
    fleet, out = tmp_path / "fleet", tmp_path / "health"
    for b in ("board000", "board001"):
        _fake_board(fleet / b)
    argv = ["health", "--fleet", str(fleet / "board000"), str(fleet / "board001"), "--scheduler", "synchronous",
            "--out", str(out)]
    first = {"health.json": b"{}", "report.html": b"1", "forecast.png": b"1", "log.txt": b"1"}
    fake_tasks.update({"board000": first, "board001": first})
    assert main(argv) == 0
    (out / "board001" / "mine.txt").write_text("mine")
    second = {"health.json": b"{}", "report.html": b"2", "log.txt": b"2"}
    fake_tasks.update({"board000": second, "board001": second})
    assert main(argv) == 0
    assert _tree(out / "board000") == sorted(second)  # before: the first run's forecast.png beside it
    assert _tree(out / "board001") == sorted([*second, "mine.txt"])
    assert json.loads((out / "fleet.json").read_text())["task_files"]["board001"] == sorted(second)


def test_a_tasks_folder_gets_no_lock_file_from_its_command(tmp_path, capsys):
    """The task's command took the --out lock of its temporary folder; its empty .shm-run.lock was copied into every
    task's folder (and would be listed as the batch's). A real task, in this process: a record that fails to read."""
    from shm_cli.run_lock import LOCK_NAME

    recs, out = tmp_path / "recs", tmp_path / "out"
    recs.mkdir()
    (recs / "broken.csv").write_text("garbage,1\n")
    assert main(["diagnose", str(recs), "--scheduler", "synchronous", "--out", str(out)]) == 1
    assert _tree(out / "broken") == ["log.txt"]
    assert not (out / "broken" / LOCK_NAME).exists()
    assert json.loads((out / "batch.json").read_text())["task_files"] == {"broken": ["log.txt"]}
    (out / "broken" / LOCK_NAME).write_text("")  # left by an earlier batch: never removed (it may be held), not named
    capsys.readouterr()
    assert main(["diagnose", str(recs), "--scheduler", "synchronous", "--out", str(out)]) == 1
    assert (out / "broken" / LOCK_NAME).exists() and "note:" not in capsys.readouterr().err
