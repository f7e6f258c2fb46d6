"""Issue 31, bad inputs to the scale-out options found by an acceptance pass: a --scheduler address checked before
any connection (empty, wrong scheme, no host, no or a bad port), an address where nothing listens said at once, a
cluster without a worker said in words; a batch's or a fleet's --out never written over the user's files or another
command's run; --fleet takes a quoted pattern like the record commands and names what is wrong with a board; a fit
batch's summary carries the fit's numbers."""

from __future__ import annotations

import socket
import time

import pytest

from shm_cli.batch_records import summary_row
from shm_cli.main import main
from studies.batch.runner import SchedulerError, check_scheduler, connect


@pytest.mark.parametrize("address, why", [
    ("", "empty"), ("  ", "empty"), ("http://x:8786", "unknown scheme 'http'"), ("tcp://", "no host"),
    ("tcp://:8786", "no host"), ("tcp://127.0.0.1", "no port"), ("tcp://127.0.0.1:99999", "not a port in 1-65535"),
    ("tcp://127.0.0.1:abc", "no port"), ("tcp://127.0.0.1:8786/x", "no port")])
def test_a_malformed_scheduler_address_is_refused_before_connecting(address, why):
    with pytest.raises(SchedulerError, match=why):
        check_scheduler(address)


def test_well_formed_addresses_pass():
    for address in (None, "local", "synchronous", "tcp://127.0.0.1:8786", "tcp://[::1]:8786", "tls://host:1"):
        assert check_scheduler(address) == address


def _closed_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_nothing_listening_or_an_unknown_host_is_said_in_words():
    """Dask retried both until its timeout and then said 'Timed out'; an unknown host is said at once, a refused
    connection after the timeout (a scheduler started just before may not listen yet)."""
    port = _closed_port()
    t0 = time.perf_counter()
    with pytest.raises(SchedulerError, match=f"nothing listens at 127.0.0.1:{port} \\(connection refused for 1 s"):
        connect(f"tcp://127.0.0.1:{port}", None, 1, timeout_s=1.0)
    assert 0.9 < time.perf_counter() - t0 < 5.0
    t0 = time.perf_counter()
    with pytest.raises(SchedulerError, match=r"unknown host 'nohost\.invalid'"):
        connect("tcp://nohost.invalid:8786", None, 1)
    assert time.perf_counter() - t0 < 5.0


def test_a_scheduler_that_starts_late_is_waited_for(tmp_path):
    """docs/scale-out.md starts 'dask scheduler ... &' and runs shm at once: a refused connection is tried again."""
    import threading

    from studies.batch.runner import probe_scheduler

    port = _closed_port()
    server = socket.socket()

    def listen_later() -> None:
        time.sleep(0.8)
        server.bind(("127.0.0.1", port))
        server.listen()

    thread = threading.Thread(target=listen_later)
    thread.start()
    try:
        probe_scheduler(f"tcp://127.0.0.1:{port}", 5.0)
    finally:
        thread.join()
        server.close()


@pytest.mark.slow
def test_a_cluster_without_a_worker_is_a_clear_input_error():
    """Before: the client connected and the run failed later, exit 1, with Dask's 'No valid workers found'."""
    from distributed import LocalCluster

    with LocalCluster(n_workers=0, processes=False, protocol="tcp://", host="127.0.0.1",
                      dashboard_address=None) as cluster:
        with pytest.raises(SchedulerError, match=r"the cluster has no worker .*dask worker tcp://"):
            connect(cluster.scheduler_address, None, 1, timeout_s=1.0, worker_wait_s=1.0)


def test_bad_scheduler_on_the_command_line_is_one_line_exit_2(tmp_path, capsys):
    (tmp_path / "recs").mkdir()
    (tmp_path / "recs" / "a.csv").write_text("t\n")
    for address in ("", "http://x"):
        code = main(["diagnose", str(tmp_path / "recs"), "--scheduler", address, "--out", str(tmp_path / "o")])
        err = capsys.readouterr().err
        assert code == 2 and err.startswith("shm: error: --scheduler") and err.count("\n") == 1, err
    assert not (tmp_path / "o").exists()


def _records(tmp_path):
    recs = tmp_path / "recs"
    recs.mkdir()
    for name in ("a.csv", "b.csv"):
        (recs / name).write_text("t\n")
    return recs


def test_a_batch_leaves_the_users_files_in_out_alone(tmp_path, capsys):
    recs = _records(tmp_path)
    out = tmp_path / "out"
    out.mkdir()
    (out / "summary.csv").write_text("my own table")
    code = main(["diagnose", str(recs), "--scheduler", "synchronous", "--out", str(out)])
    assert code == 2 and "summary.csv is there and no earlier 'shm diagnose' batch wrote it" in capsys.readouterr().err
    assert (out / "summary.csv").read_text() == "my own table"
    (out / "summary.csv").unlink()
    (out / "a").mkdir()
    (out / "a" / "diagnosis.html").write_text("my notes")
    code = main(["diagnose", str(recs), "--scheduler", "synchronous", "--out", str(out)])
    assert code == 2 and f"{out / 'a'} holds files of no earlier 'shm diagnose' batch" in capsys.readouterr().err
    assert (out / "a" / "diagnosis.html").read_text() == "my notes"
    assert sorted(p.name for p in out.iterdir()) == ["a"]


def test_a_batch_refuses_another_commands_run_and_another_commands_batch(tmp_path, capsys):
    recs = _records(tmp_path)
    out = tmp_path / "out"
    out.mkdir()
    (out / "compare.json").write_text("{}")
    assert main(["diagnose", str(recs), "--scheduler", "synchronous", "--out", str(out)]) == 2
    assert "holds a finished shm compare run (compare.json)" in capsys.readouterr().err
    (out / "compare.json").unlink()
    (out / "batch.json").write_text('{"command": "compare"}')
    (out / "summary.csv").write_text("the compare batch's table")
    assert main(["diagnose", str(recs), "--scheduler", "synchronous", "--out", str(out)]) == 2
    assert "holds an earlier 'shm compare' batch (batch.json)" in capsys.readouterr().err
    assert (out / "summary.csv").read_text() == "the compare batch's table"
    # a task's folder holding another command's run (an earlier single shm fit of a.csv) is not written over
    (out / "batch.json").write_text('{"command": "diagnose"}')
    (out / "a").mkdir()
    (out / "a" / "fit.json").write_text("{}")
    assert main(["diagnose", str(recs), "--scheduler", "synchronous", "--out", str(out)]) == 2
    assert "holds shm fit's output (fit.json)" in capsys.readouterr().err


def _fake_board(folder):
    (folder / "records").mkdir(parents=True)
    (folder / "usage.db").write_bytes(b"")
    (folder / "summary.json").write_text("{}")
    (folder / "report.html").write_text("the board's own life report")
    return folder


def test_a_fleet_into_its_boards_parent_does_not_write_over_the_boards_runs(tmp_path, capsys):
    """README's next step is --out fleet/fleet; --out fleet put each board's health report over its own run's
    report.html and log.txt (and its health.json beside its usage.db)."""
    fleet = tmp_path / "fleet"
    for b in ("board000", "board001"):
        _fake_board(fleet / b)
    code = main(["health", "--fleet", str(fleet / "board000"), str(fleet / "board001"), "--scheduler",
                 "synchronous", "--out", str(fleet)])
    err = capsys.readouterr().err
    assert code == 2 and f"{fleet / 'board000'} holds shm run's output" in err and err.count("\n") == 1
    assert (fleet / "board000" / "report.html").read_text() == "the board's own life report"
    assert not (fleet / "board000" / "health.json").exists() and not (fleet / "fleet.csv").exists()


def test_fleet_sources_a_quoted_pattern_a_file_a_missing_folder_a_duplicate(tmp_path, capsys, monkeypatch):
    import shm_cli.fleet_cmd as fleet_cmd

    fleet = tmp_path / "fleet"
    for b in ("board000", "board001"):
        _fake_board(fleet / b)
    (fleet / "boards.csv").write_text("board\n")
    assert [p.name for p in fleet_cmd.board_folders([f"{fleet}/board[0-9]*"])] == ["board000", "board001"]
    cases = {f"{tmp_path}/nowhere/board*": "the pattern '.*/nowhere/board\\*' matches no board folder",
             str(fleet / "boards.csv"): "boards.csv is a file; each board is a 'shm run' output folder",
             str(fleet / "board999"): "board999: no such board folder"}
    import re

    for source, why in cases.items():
        assert main(["health", "--fleet", source, "--out", str(tmp_path / "o")]) == 2
        err = capsys.readouterr().err
        assert re.search(why, err) and err.count("\n") == 1, err
    assert main(["health", "--fleet", str(fleet / "board000"), str(fleet / "board000"),
                 "--out", str(tmp_path / "o")]) == 2
    assert f"same folder name ({fleet / 'board000'})" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_a_fit_batch_summary_carries_the_fits_numbers():
    doc = {"held_rms_sigma": {"before": 1.4, "after": 0.9}, "train_rms_sigma": {"before": 1.5, "after": 1.0},
           "model_explains_record": True, "wall_s": 0.4,
           "estimates": [{"name": "k3", "unit": "N/m", "value": 21.3, "stderr": 0.002},
                         {"name": "alpha_h", "unit": "1", "value": 0.6, "stderr": 1e-5}]}
    row = summary_row("fit", doc)
    assert row == {"held_rms_before_sigma": 1.4, "held_rms_after_sigma": 0.9, "train_rms_before_sigma": 1.5,
                   "train_rms_after_sigma": 1.0, "model_explains_record": True, "k3_N_per_m": 21.3,
                   "k3_stderr_N_per_m": 0.002, "alpha_h_1": 0.6, "alpha_h_stderr_1": 1e-5}


def test_a_life_on_a_cluster_sends_its_files_by_absolute_path(tmp_path, monkeypatch):
    """docs/scale-out.md: 'shm run --scenario my-life.toml --scheduler tcp://...' — a worker started in another
    folder looked for the relative 'my-life.toml' in its own ('key '-': file not found'); in this process and on
    local workers the path stays as given."""
    import studies.board_run.life_pool as life_pool
    from board_config.scenario import load_scenario
    from studies.health.life import run_life

    text = open(load_scenario("aging").source, encoding="utf-8").read()
    (tmp_path / "my-life.toml").write_text(text.replace('visits = { value = 24, unit = "1" }',
                                                        'visits = { value = 2, unit = "1" }'))
    (tmp_path / "mine.toml").write_text("")
    monkeypatch.chdir(tmp_path)
    sent = []

    class Pool:
        def __init__(self, fn, workers, scheduler):
            pass

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            return False

        def run(self, args, finished, should_stop):
            sent.extend(args)
            return True

    monkeypatch.setattr(life_pool, "LifePool", Pool)
    run_life(load_scenario("my-life.toml"), seed=1, params="mine.toml", scheduler="tcp://127.0.0.1:8786")
    assert {(a[0], a[5], a[6]) for a in sent} == {(str(tmp_path / "my-life.toml"), str(tmp_path / "mine.toml"), None)}
    sent.clear()
    run_life(load_scenario("my-life.toml"), seed=1, params="table2", workers=2)
    assert {(a[0], a[5]) for a in sent} == {("my-life.toml", "table2")}


def _fake_fleet_tasks(monkeypatch):
    """``shm run --boards``' tasks replaced by boards of two visits each (no life is run)."""
    import studies.batch as batch
    from studies.batch import TaskResult
    from studies.batch.runner import BatchOutcome

    def run_tasks(tasks, *_a, **_k):
        files = {"usage.db": b"db", "life.json": b"{}", "records/visit-001_mbit-a.csv": b"1",
                 "records/visit-002_mbit-a.csv": b"2"}
        return BatchOutcome([TaskResult(k, 0, "done", {}, dict(files)) for k, _ in tasks], "fake", 1)

    monkeypatch.setattr(batch, "run_tasks", run_tasks)


def test_boards_leave_the_users_table_alone_and_force_replaces_an_earlier_fleet_whole(tmp_path, monkeypatch, capsys):
    _fake_fleet_tasks(monkeypatch)
    out = tmp_path / "fleet"
    out.mkdir()
    (out / "boards.csv").write_text("my inventory of boards")
    argv = ["run", "--scenario", "aging", "--boards", "2", "--seed", "3", "--out", str(out)]
    assert main(argv) == 2 and "boards.csv is there and no earlier fleet's boards" in capsys.readouterr().err
    assert (out / "boards.csv").read_text() == "my inventory of boards"
    (out / "boards.csv").unlink()
    # an earlier fleet of three boards with longer lives: --force leaves none of its files
    for b in ("board000", "board001", "board002"):
        (out / b / "records").mkdir(parents=True)
        (out / b / "usage.db").write_bytes(b"old")
        (out / b / "records" / "visit-009_mbit-a.csv").write_text("old visit")
    assert main(argv) == 2 and "holds an earlier fleet" in capsys.readouterr().err
    assert main([*argv, "--force"]) == 0
    assert sorted(p.name for p in out.glob("board[0-9]*")) == ["board000", "board001"]
    assert sorted(p.name for p in (out / "board000" / "records").iterdir()) == [
        "visit-001_mbit-a.csv", "visit-002_mbit-a.csv"]
    assert (out / "board000" / "usage.db").read_bytes() == b"db"
    # a board-named folder that is not a board is the user's, --force or not
    (out / "board007").mkdir()
    (out / "board007" / "notes.txt").write_text("mine")
    assert main([*argv, "--force"]) == 2 and "board007 is not a board of an earlier fleet" in capsys.readouterr().err
    assert (out / "board007" / "notes.txt").read_text() == "mine" and (out / "board001").is_dir()


def test_a_failed_tasks_message_names_the_record_not_the_workers_temporary_folder(tmp_path, capsys):
    """Before: 'broken: exit 2: /tmp/shm-task-mj4etngj/in/broken.csv, line 2: ...' — a path the user never had,
    and a different one each run (the summary was not the same twice)."""
    recs = tmp_path / "recs"
    recs.mkdir()
    (recs / "broken.csv").write_text("garbage,1\n")
    assert main(["diagnose", str(recs), "--scheduler", "synchronous", "--out", str(tmp_path / "o")]) == 1
    err = capsys.readouterr().err
    assert "broken: exit 2: broken.csv, line 2: no data rows" in err and "shm-task-" not in err, err
    summary = (tmp_path / "o" / "summary.csv").read_text()
    assert "broken.csv, line 2" in summary and "shm-task-" not in summary


def test_scheduler_where_it_would_be_ignored_is_refused(tmp_path, capsys):
    """The record commands refuse --scheduler with files only; shm health without --fleet and shm run of a scenario
    without [life] and without --boards ran in this process and said nothing of the cluster asked for."""
    board = _fake_board(tmp_path / "board000")
    code = main(["health", str(board), "--scheduler", "tcp://127.0.0.1:8786", "--out", str(tmp_path / "h")])
    err = capsys.readouterr().err
    assert code == 2 and "--scheduler runs one task per board with --fleet" in err and err.count("\n") == 1, err
    code = main(["run", "--scenario", "maintenance", "--scheduler", "tcp://127.0.0.1:8786", "--out",
                 str(tmp_path / "r")])
    err = capsys.readouterr().err
    assert code == 2 and "has no [life] section and one run is one process" in err and err.count("\n") == 1, err
    assert not (tmp_path / "h").exists() and not (tmp_path / "r").exists()


def test_an_unreachable_scheduler_is_one_line_and_leaves_no_out(tmp_path, capsys, monkeypatch):
    """Before: 'shm diagnose: 1 tasks ... on tcp://...' then the error (two lines), and an empty --out was made."""
    import studies.batch.runner as runner

    monkeypatch.setattr(runner, "probe_scheduler", _refused)
    recs = _records(tmp_path)
    board = _fake_board(tmp_path / "board000")
    for argv in (["diagnose", str(recs)], ["health", "--fleet", str(board)],
                 ["run", "--scenario", "aging", "--boards", "2"]):
        code = main([*argv, "--scheduler", "tcp://127.0.0.1:1", "--out", str(tmp_path / "o")])
        err = capsys.readouterr().err
        assert code == 2 and err.count("\n") == 1 and "nothing listens at 127.0.0.1:1" in err, (argv, err)
        assert not (tmp_path / "o").exists(), argv


def _refused(address: str, timeout_s: float) -> None:
    raise SchedulerError(f"--scheduler {address}: nothing listens at 127.0.0.1:1 (connection refused for 0 s)")
