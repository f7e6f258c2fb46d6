"""The progress and summary lines of a batch, a fleet and a life say "1 worker", "1 task", "1 board" — not
"1 workers" (studies.batch.runner.counted)."""

from __future__ import annotations

import pytest

from shm_cli.main import main
from studies.batch.runner import BatchProgress, counted


def test_counted_agrees_with_its_number():
    assert [counted(n, "worker") for n in (0, 1, 2)] == ["0 workers", "1 worker", "2 workers"]
    assert counted(1, "task") == "1 task" and counted(3, "analysis", "analyses") == "3 analyses"


def test_the_progress_line_with_one_worker_one_lost_one_rerun():
    assert BatchProgress(2, 4, 1, 1, 1).line("shm diagnose") == (
        "shm diagnose: 2/4 tasks done, 1 worker, 1 worker lost — 1 task rerun")
    assert BatchProgress(1, 1, 2, 2, 3).line("shm health --fleet") == (
        "shm health --fleet: 1/1 task done, 2 workers, 2 workers lost — 3 tasks rerun")


@pytest.fixture
def one_worker_tasks(monkeypatch):
    """``run_tasks`` replaced: each task returns a log, the progress is shown once per task with one worker."""
    import studies.batch as batch
    from studies.batch import TaskResult
    from studies.batch.runner import BatchOutcome

    def run_tasks(tasks, *_a, progress=None, **_k):
        for i, _ in enumerate(tasks, start=1):
            progress(BatchProgress(i, len(tasks), 1, 0, 0))
        return BatchOutcome([TaskResult(k, 0, "done", {}, {"log.txt": b"x"}) for k, _ in tasks],
                            "local processes (1 worker)", 1)

    monkeypatch.setattr(batch, "run_tasks", run_tasks)


def test_a_batch_of_one_record_on_one_worker_says_it_in_the_singular(tmp_path, one_worker_tasks, capsys):
    (tmp_path / "recs").mkdir()
    (tmp_path / "recs" / "a.csv").write_text("t\n")
    assert main(["diagnose", str(tmp_path / "recs"), "--scheduler", "synchronous", "--out", str(tmp_path / "o")]) == 0
    err = capsys.readouterr().err
    assert "shm diagnose: 1 task (1 record) on synchronous" in err, err
    assert "shm diagnose: 1/1 task done, 1 worker\n" in err, err
    assert "shm diagnose: 1 of 1 task done in" in err, err
    assert "1 workers" not in err and "1 tasks" not in err and "1 records" not in err, err
    assert "shm diagnose: 1 task</h1>" in (tmp_path / "o" / "summary.html").read_text()


def test_a_fleet_of_one_board_says_it_in_the_singular(tmp_path, one_worker_tasks, capsys):
    board = tmp_path / "board000"
    (board / "records").mkdir(parents=True)
    (board / "usage.db").write_bytes(b"")
    assert main(["health", "--fleet", str(board), "--scheduler", "synchronous", "--out", str(tmp_path / "h")]) == 0
    cap = capsys.readouterr()
    assert "shm health: fleet of 1 board on synchronous" in cap.err, cap.err
    assert "shm health --fleet: 1/1 task done, 1 worker\n" in cap.err, cap.err
    assert "(0.0 s, local processes (1 worker))" in cap.out, cap.out
    assert "1 workers" not in cap.err + cap.out and "1 boards" not in cap.err + cap.out
