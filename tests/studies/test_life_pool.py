"""The life's visits on Dask (studies/board_run/life_pool.py, issues 31 and 33): errors cross as the same error, a
worker killed from outside loses nothing (its visit runs again, said on stderr), a stop ends every worker at once."""

from __future__ import annotations

import os
import signal
import threading
import time

import pytest

from board_config.errors import ConfigError
from studies.board_run.life_pool import LifePool, VisitFailedError, VisitInputError

pytestmark = pytest.mark.slow  # each test starts a local Dask cluster (2-4 s)


def _task(kind: str, seconds: float = 0.0) -> str:
    time.sleep(seconds)
    if kind == "config":
        raise ConfigError("life.toml", "life.law[0].parameter", "no such model parameter 'nosuch'")
    if kind == "bug":
        raise ZeroDivisionError("division by zero")
    return kind


def test_results_in_order_and_errors_as_the_same_line() -> None:
    got: dict[int, str] = {}
    with LifePool(_task, 2) as pool:
        assert pool.run([("a",), ("b",), ("c",)], got.__setitem__) is False
    assert got == {0: "a", 1: "b", 2: "c"}
    with LifePool(_task, 2) as pool, pytest.raises(VisitInputError) as exc:
        pool.run([("a",), ("config",)], lambda i, r: None)
    assert str(exc.value) == "life.toml: key 'life.law[0].parameter': no such model parameter 'nosuch'"
    with LifePool(_task, 1) as pool, pytest.raises(VisitFailedError, match="ZeroDivisionError: division by zero"):
        pool.run([("bug",)], lambda i, r: None)


def test_a_worker_killed_from_outside_loses_nothing(capsys) -> None:
    got: dict[int, str] = {}
    with LifePool(_task, 1) as pool:
        pid = pool.pids[0]
        threading.Timer(1.0, os.kill, (pid, signal.SIGKILL)).start()
        assert pool.run([("a", 3.0), ("b",)], got.__setitem__) is False
        assert pool.workers_lost == 1
    assert got == {0: "a", 1: "b"}
    assert "shm run: 1 worker lost — its visit runs again" in capsys.readouterr().err


def test_a_stop_terminates_every_worker_at_once() -> None:
    pool = LifePool(_task, 2)
    pids = pool.pids
    t0 = time.monotonic()
    stopped = pool.run([("a", 60.0)] * 4, lambda i, r: None, should_stop=lambda: time.monotonic() - t0 > 0.5)
    pool.close()
    assert stopped and time.monotonic() - t0 < 5.0
    deadline = time.monotonic() + 2.0
    while any(_running(pid) for pid in pids) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not [pid for pid in pids if _running(pid)], "a worker outlived the stop"


def _running(pid: int) -> bool:
    """True while ``pid`` exists and has not ended (a zombie has ended: only its exit status waits to be read, and
    which process reads it — ours or multiprocessing's — is not what this test is about)."""
    try:
        state = open(f"/proc/{pid}/stat", encoding="ascii").read().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


def test_dask_makes_no_info_records_while_it_forks_workers() -> None:
    """A forked worker whose parent's thread was writing a Dask info record hung on that stream's lock (a LifePool
    start waited 10 minutes under pytest): the pool's forking process makes no Dask record below WARNING."""
    import logging

    logging.getLogger("distributed").setLevel(logging.INFO)
    with LifePool(_task, 1) as pool:
        assert logging.getLogger("distributed.worker").getEffectiveLevel() >= logging.WARNING
        assert pool.run([("a",)], lambda i, r: None) is False
