"""``shm run --scenario S --boards N --force`` over an earlier fleet replaces only what that fleet wrote: its
``boards.json`` lists each board's files (``task_files``), those go (a longer life's later visits, a larger fleet's
last boards), and a file of the user's in a board's folder stays, said in one line. Before, every board folder was
removed whole (``shutil.rmtree``): a user's notes or plot in ``board000/`` went with it. A fleet written before the
list was kept: only the files a board's life writes are replaced. ``shm health --fleet 'DIR/board[0-9]*'`` skips a
board folder that holds no run (one line) instead of refusing the whole fleet."""

from __future__ import annotations

import json
import sqlite3

import pytest

from shm_cli.main import main


def _tree(folder):
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*") if p.is_file())


@pytest.fixture
def fake_boards(monkeypatch):
    """``run_tasks`` replaced by boards whose life has ``visits[0]`` visits (no life is run); set by the test."""
    import studies.batch as batch
    from studies.batch import TaskResult
    from studies.batch.runner import BatchOutcome

    visits = [2]

    def run_tasks(tasks, *_a, **_k):
        def files(key):
            recs = {f"records/visit-{v:03d}_mbit-{m}.csv": f"{key} visit {v}".encode()
                    for v in range(1, visits[0] + 1) for m in "ab"}
            return {"usage.db": f"db of {visits[0]} visits".encode(), "life.json": b"{}", "report.html": b"<p>",
                    "life.png": b"png", "summary.json": b"{}", "timeline.txt": b"t", "log.txt": b"", **recs}
        return BatchOutcome([TaskResult(k, 0, "done", {}, files(k)) for k, _ in tasks], "fake", 1)

    monkeypatch.setattr(batch, "run_tasks", run_tasks)
    return visits


def _boards(out, n, *extra):
    return main(["run", "--scenario", "aging", "--boards", str(n), "--seed", "3", "--out", str(out), *extra])


def test_force_keeps_the_users_files_in_a_board_and_replaces_the_fleets_own(tmp_path, fake_boards, capsys):
    out = tmp_path / "fleet"
    fake_boards[0] = 3
    assert _boards(out, 2) == 0
    assert json.loads((out / "boards.json").read_text())["task_files"]["board000"] == _tree(out / "board000")
    (out / "board000" / "notes.txt").write_text("my notes")
    (out / "board000" / "plots").mkdir()
    (out / "board000" / "plots" / "mine.png").write_text("my plot")
    (out / "board000" / "records" / "my_record.csv").write_text("t,z3\n")
    capsys.readouterr()
    fake_boards[0] = 1  # a shorter life: visits 2 and 3 of the earlier one must not stay beside it
    assert _boards(out, 2, "--force") == 0
    assert (out / "board000" / "notes.txt").read_text() == "my notes"  # before: gone with the folder
    assert (out / "board000" / "plots" / "mine.png").read_text() == "my plot"
    assert (out / "board000" / "records" / "my_record.csv").read_text() == "t,z3\n"
    assert (out / "board000" / "usage.db").read_bytes() == b"db of 1 visits"
    assert sorted(p.name for p in (out / "board000" / "records").iterdir()) == [
        "my_record.csv", "visit-001_mbit-a.csv", "visit-001_mbit-b.csv"]
    assert _tree(out / "board001") == json.loads((out / "boards.json").read_text())["task_files"]["board001"]
    err = capsys.readouterr().err
    said = [line for line in err.splitlines() if "kept" in line]
    assert said == [f"shm run --boards: --force kept 3 files that no fleet wrote, as they were: {out / 'board000'} "
                    "(notes.txt, plots/mine.png, ...)"], err
    # kept again by the next --force (they are still not the fleet's)
    assert _boards(out, 2, "--force") == 0
    assert (out / "board000" / "notes.txt").read_text() == "my notes"


def test_a_smaller_fleet_leaves_no_run_in_the_earlier_fleets_last_boards(tmp_path, fake_boards, capsys):
    out = tmp_path / "fleet"
    assert _boards(out, 4) == 0
    (out / "board003" / "notes.txt").write_text("board 3 went to the lab")
    assert _boards(out, 2, "--force") == 0
    assert not (out / "board002").exists()  # nothing of the user's in it: the folder goes too
    assert _tree(out / "board003") == ["notes.txt"]  # no usage.db, no life.json, no records: not a run any more
    err = capsys.readouterr().err
    assert f"{out / 'board003'} (notes.txt; no run in it now: shm health --fleet skips it)" in err, err
    assert json.loads((out / "boards.json").read_text())["task_files"]["board003"] == []
    assert len(json.loads((out / "boards.json").read_text())["boards"]) == 2
    # a later --force knows board003 as the fleet's folder (kept for the user's file), not a stranger's
    assert _boards(out, 4, "--force") == 0
    assert (out / "board003" / "notes.txt").read_text() == "board 3 went to the lab"
    assert (out / "board003" / "usage.db").is_file()


def test_a_fleet_written_before_the_file_list_has_only_a_board_runs_files_replaced(tmp_path, fake_boards, capsys):
    out = tmp_path / "fleet"
    for b in ("board000", "board001", "board002"):
        (out / b / "records").mkdir(parents=True)
        for name in ("usage.db", "life.json", "life.png", "report.html", "summary.json", "timeline.txt", "log.txt"):
            (out / b / name).write_text("old")
        (out / b / "records" / "visit-009_mbit-a.csv").write_text("old visit")
    (out / "boards.csv").write_text("board\n")
    (out / "board000" / "notes.txt").write_text("mine")
    (out / "board000" / "records" / "mine.csv").write_text("mine too")
    (out / "board002" / "analysis.py").write_text("print(1)")
    assert _boards(out, 2, "--force") == 0
    assert _tree(out / "board000") == sorted([*json.loads((out / "boards.json").read_text())["task_files"][
        "board000"], "notes.txt", "records/mine.csv"])
    assert not (out / "board000" / "records" / "visit-009_mbit-a.csv").exists()
    assert _tree(out / "board002") == ["analysis.py"]
    err = capsys.readouterr().err
    assert "kept 3 files that no fleet wrote (the earlier fleet kept no list: a board run writes none of them)" in err


def test_a_board_folder_that_is_a_link_or_a_file_is_refused_and_left(tmp_path, fake_boards, capsys):
    """Before: a linked board holding a run passed the check, the new fleet ran, and rmtree refused the link
    (OSError after the run); now refused before any task, the linked folder untouched."""
    out, elsewhere = tmp_path / "fleet", tmp_path / "my_board"
    assert _boards(out, 2) == 0
    (elsewhere / "records").mkdir(parents=True)
    (elsewhere / "usage.db").write_text("my own board")
    (out / "board001").rename(tmp_path / "was_board001")
    (out / "board001").symlink_to(elsewhere)
    capsys.readouterr()
    assert _boards(out, 2, "--force") == 2
    assert f"{out / 'board001'} is not a board of an earlier fleet (a symbolic link)" in capsys.readouterr().err
    assert (elsewhere / "usage.db").read_text() == "my own board" and _tree(elsewhere) == ["usage.db"]
    (out / "board001").unlink()
    (out / "board001").write_text("a file")
    assert _boards(out, 2, "--force") == 2 and "(a file)" in capsys.readouterr().err
    assert (out / "board001").read_text() == "a file"


def _health_tasks(monkeypatch, seen):
    import studies.batch as batch
    from studies.batch import TaskResult
    from studies.batch.runner import BatchOutcome

    def run_tasks(tasks, *_a, **_k):
        seen.extend(k for k, _ in tasks)
        return BatchOutcome([TaskResult(k, 0, "done", {}, {"health.json": b"{}"}) for k, _ in tasks], "fake", 1)

    monkeypatch.setattr(batch, "run_tasks", run_tasks)


def test_fleet_health_over_a_pattern_skips_a_board_folder_without_a_run(tmp_path, fake_boards, monkeypatch, capsys):
    out = tmp_path / "fleet"
    assert _boards(out, 3) == 0
    (out / "board002" / "notes.txt").write_text("mine")
    assert _boards(out, 2, "--force") == 0
    capsys.readouterr()
    seen: list[str] = []
    _health_tasks(monkeypatch, seen)
    code = main(["health", "--fleet", f"{out}/board[0-9]*", "--scheduler", "synchronous", "--out",
                 str(tmp_path / "health")])
    err = capsys.readouterr().err
    assert code == 0 and seen == ["board000", "board001"], err  # before: exit 2, 'board002 is not a shm run output'
    assert f"skipped 1 match of a pattern without a run (no usage.db in it): {out / 'board002'}" in err
    assert sum("skipped" in line for line in err.splitlines()) == 1
    # a board folder named on its own is still an error, and a pattern that matches no run too
    assert main(["health", "--fleet", str(out / "board002"), "--out", str(tmp_path / "h2")]) == 2
    assert "no usage.db in it" in capsys.readouterr().err
    assert main(["health", "--fleet", f"{out}/board00[2-9]", "--out", str(tmp_path / "h3")]) == 2
    assert "matches no board's run (1 match, none with a usage.db in it" in capsys.readouterr().err


@pytest.mark.slow
def test_force_on_real_boards_keeps_the_users_file_and_leaves_no_run_in_a_dropped_board(tmp_path, capsys):
    """End to end, real lives (the aging scenario cut to one visit, in this process): 3 boards, then 2 with
    --force and another seed."""
    from board_config.scenario import load_scenario

    text = open(load_scenario("aging").source, encoding="utf-8").read()
    short = text.replace('visits = { value = 24, unit = "1" }', 'visits = { value = 1, unit = "1" }')
    assert short != text
    (tmp_path / "short.toml").write_text(short)
    out = tmp_path / "fleet"
    argv = ["run", "--scenario", str(tmp_path / "short.toml"), "--scheduler", "synchronous", "--out", str(out)]
    assert main([*argv, "--boards", "3", "--seed", "3"]) == 0
    first = (out / "board000" / "life.json").read_bytes()
    (out / "board000" / "notes.txt").write_text("my notes")
    assert main([*argv, "--boards", "2", "--seed", "11", "--force"]) == 0
    assert (out / "board000" / "notes.txt").read_text() == "my notes"
    assert (out / "board000" / "life.json").read_bytes() != first
    assert json.loads((out / "board000" / "life.json").read_text())["seed"] == 11
    listed = json.loads((out / "boards.json").read_text())["task_files"]
    assert sorted(listed) == ["board000", "board001"]
    assert _tree(out / "board000") == sorted([*listed["board000"], "notes.txt"])
    assert not (out / "board002").exists()
    with sqlite3.connect(out / "board000" / "usage.db") as db:
        assert db.execute("SELECT count(*) FROM life_visits").fetchone() == (1,)
