"""Issue 31 point 4, found by an acceptance pass: a worker SIGKILLed during ``shm health --fleet`` on a real cluster
(3 boards, 2 workers) gave a fleet table in which board002 had board000's forecast. Both boards' inputs went with
the worker and were scattered again as ``client.scatter(files)`` — a dict, which Dask scatters file by file under
the file names as keys: ``usage.db`` and ``records/visit-001_mbit-a.csv`` of two boards were then the same data.
Here the loss is made certain: each task's first run fails as a lost worker's would and its input counts as lost."""

from __future__ import annotations

from pathlib import Path

import pytest

import studies.batch.runner as runner
from studies.batch import TaskResult, run_tasks

pytestmark = pytest.mark.slow


def _board_task(key: str, files: dict[str, bytes], shared: dict[str, bytes], tried: str) -> TaskResult:
    marker = Path(tried) / key
    if not marker.exists():
        marker.write_text("lost once")
        raise RuntimeError("the worker running this task died (simulated)")
    return TaskResult(key, 0, files["usage.db"].decode() + " " + files["records/visit-001.csv"].decode())


def test_tasks_whose_inputs_are_lost_rerun_on_their_own_inputs(tmp_path, monkeypatch):
    from distributed import LocalCluster

    monkeypatch.setenv("MFC_SHM_THREADS", "1")  # the worker plugin sets it in this process (threads, not processes)
    monkeypatch.setattr(runner, "input_lost", lambda future: True)
    boards = [(f"board{i:03d}", {"usage.db": f"db of board{i:03d}".encode(),
                                 "records/visit-001.csv": f"visit of board{i:03d}".encode()}) for i in range(3)]
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=False, protocol="tcp://", host="127.0.0.1",
                      dashboard_address=None) as cluster:
        outcome = run_tasks(boards, _board_task, str(tmp_path), scheduler=cluster.scheduler_address)
    assert [(r.key, r.code, r.message) for r in outcome.results] == [
        (k, 0, f"db of {k} visit of {k}") for k, _ in boards]
    assert outcome.reruns == 3
    assert outcome.bytes_scattered == 2 * sum(len(b) for _, f in boards for b in f.values())


def test_scatter_one_keeps_each_tasks_files_together(tmp_path):
    from distributed import Client, LocalCluster

    with LocalCluster(n_workers=1, processes=False, dashboard_address=None) as cluster, \
            Client(cluster, set_as_default=False) as client:
        a = runner.scatter_one(client, {"usage.db": b"A"})
        b = runner.scatter_one(client, {"usage.db": b"B"})
        assert a.key != b.key and a.result() == {"usage.db": b"A"} and b.result() == {"usage.db": b"B"}


def _die_first(key: str, files: dict[str, bytes], shared: dict[str, bytes], tried: str) -> TaskResult:
    import os
    import signal

    marker = Path(tried) / key
    if not marker.exists():
        marker.write_text("killed my worker once")
        os.kill(os.getpid(), signal.SIGKILL)  # the worker process dies with the task, as under kill -9
    return TaskResult(key, 0, files["usage.db"].decode() + " " + shared["params"].decode())


def test_the_only_workers_death_loses_nothing(tmp_path):
    """A one-worker cluster (or every worker at once): the files every task shares went with it too. Before, they
    were never scattered again and each task came back 'cancelled for reason: lost dependencies' four times: exit 1,
    'lost 4 times with its worker', on a cluster whose nanny had started a new worker at once."""
    import dask
    from distributed import LocalCluster

    runner.quiet_forked_workers()
    boards = [(f"board{i:03d}", {"usage.db": f"db of board{i:03d}".encode()}) for i in range(2)]
    with dask.config.set({"distributed.worker.multiprocessing-method": "fork", "distributed.worker.daemon": False}), \
            LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None,
                         memory_limit=0, silence_logs=50) as cluster:
        outcome = run_tasks(boards, _die_first, str(tmp_path), shared={"params": b"P"},
                            scheduler=cluster.scheduler_address)
    assert [(r.key, r.code, r.message) for r in outcome.results] == [
        (k, 0, f"db of {k} P") for k, _ in boards]
    assert outcome.workers_lost >= 1 and outcome.reruns >= 1


class _FlakyClient:
    """A client whose scheduler's scatter fails while a dead worker is being replaced, then works."""

    def __init__(self, failures: int) -> None:
        self.failures = failures
        self.calls = 0

    def wait_for_workers(self, n: int, timeout: float) -> None:
        pass

    def scatter(self, data: list, broadcast: bool, hash: bool) -> list:
        self.calls += 1
        if self.calls <= self.failures:
            raise OSError("in <TCP (closed) ConnectionPool.scatter local=... remote=...>: Stream is closed")
        return [("future of", data[0])]


def test_a_scatter_while_a_worker_is_replaced_is_tried_again(monkeypatch):
    """Seen on a real cluster after both workers were SIGKILLed: the rescatter hit the dead worker's closed stream
    and the whole command failed ('shm diagnose' failed: ... Stream is closed), the finished task's report lost."""
    monkeypatch.setattr(runner, "POLL_S", 0.01)
    client = _FlakyClient(failures=2)
    assert runner.scatter_one(client, {"usage.db": b"A"}) == ("future of", {"usage.db": b"A"})
    assert client.calls == 3
    monkeypatch.setattr(runner, "RESCATTER_WAIT_S", 0.05)
    with pytest.raises(OSError, match="Stream is closed"):
        runner.scatter_one(_FlakyClient(failures=10**6), {"usage.db": b"A"})
