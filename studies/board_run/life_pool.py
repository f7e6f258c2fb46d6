"""The visits of a life run (``shm run`` on a ``[life]`` scenario) on Dask: a ``distributed.LocalCluster`` of
single-thread worker processes by default, or an existing cluster (``scheduler="tcp://host:port"``), stoppable.

What the life needs from its workers, and how it holds on Dask:

* an error crosses as text: each visit runs inside :func:`_answer`, which returns ``("ok", result)`` or
  ``("error", kind, message)`` — an exception class that cannot be unpickled never reaches the parent, and an
  :class:`~board_config.errors.InputError` raised inside a visit reaches the user as the same one line (exit 2);
* a worker lost mid-visit (killed from outside) loses nothing: Dask runs its visit again on a worker (the local
  cluster's nanny starts a new worker process); said once on stderr. A visit whose workers die
  ``distributed.scheduler.allowed-failures`` + 1 times is :class:`WorkerDiedError`;
* local workers are forked from the parent (they start with its compiled kernels), ignore SIGINT (a terminal's
  Ctrl-C goes to the whole process group; the parent decides), die on SIGTERM and end when their parent ends (Dask's
  worker processes watch their parent);
* ``should_stop()`` is polled at least every 0.2 s; once true, no new visit starts, the visits are cancelled, the
  local cluster is closed and any worker process still alive after :data:`TERMINATE_GRACE_S` is killed, and the
  visits finished so far are what the run returns.

Why not ``concurrent.futures.ProcessPoolExecutor``: an exception that could not be unpickled broke the whole pool,
and a SIGTERM or Ctrl-C left workers running or the parent blocked in the executor's locks.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import signal
import sys
import time
import uuid
from collections.abc import Callable, Sequence
from typing import Any

from board_config.errors import InputError

#: how long the local cluster may take to close before its worker processes are killed (s)
TERMINATE_GRACE_S = 3.0
POLL_S = 0.2


class VisitInputError(InputError):
    """A user's mistake found inside a visit's worker (the message as the worker's InputError said it)."""


class VisitFailedError(RuntimeError):
    """An unexpected error inside a visit's worker (type and message of the original; a bug in mfc-shm)."""


class WorkerDiedError(OSError):
    """A visit's worker process ended without an answer each time it was tried (killed from outside, out of
    memory)."""


def _answer(fn: Callable[..., Any], *task: Any) -> tuple[Any, ...]:
    """``fn(*task)`` on the worker, its outcome as data: an error travels as its kind and text."""
    try:
        return ("ok", fn(*task))
    except InputError as exc:
        return ("error", "input", str(exc))
    except OSError as exc:
        return ("error", "os", f"{exc}")
    except Exception as exc:  # a bug: its type and message travel as text
        return ("error", "bug", f"{type(exc).__name__}: {exc}")


def _raise_for(kind: str, message: str) -> None:
    if kind == "input":
        raise VisitInputError(message)
    if kind == "os":
        raise OSError(message)
    raise VisitFailedError(message)


def _worker_signals() -> None:
    """On a local worker: Ctrl-C is the parent's to decide (it stops the life and closes the cluster); SIGTERM ends
    the worker (a forked worker inherited the parent's handler, which would only note a stop request)."""
    with contextlib.suppress(ValueError):  # not the main thread: nothing to do
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_DFL)


def _still_my_child(pid: int) -> bool:
    """True when ``pid`` is a running (not zombie) child of this process (Linux ``/proc``)."""
    try:
        fields = open(f"/proc/{pid}/stat", encoding="ascii").read().rsplit(")", 1)[1].split()
    except OSError:
        return False
    return fields[0] != "Z" and int(fields[1]) == os.getpid()


class LifePool:
    """``workers`` Dask worker processes (or the cluster at ``scheduler``) running ``fn(*task)``; see the module
    docstring. ``fn`` must be a module-level function (sent by reference) whose arguments and result pickle."""

    def __init__(self, fn: Callable[..., Any], workers: int, scheduler: str | None = None) -> None:
        from studies.batch.runner import connect

        self._fn = fn
        # local workers forked from the life's parent: they start with the plant's kernels the parent's checks
        # compiled (spawned, each loaded or compiled them again: a 6-visit life took 2-4x the pool's time)
        self._client, self._cluster, self.description = connect(scheduler, max(1, workers), max(1, workers),
                                                                fork=True)
        try:
            from studies.batch.warm import WarmPlugin

            self._client.register_plugin(WarmPlugin(None), name=WarmPlugin.name)  # one thread per visit
            if self._cluster is not None:
                self._client.run(_worker_signals)
        except BaseException:
            self.close()
            raise
        self.workers_lost = 0

    @property
    def pids(self) -> list[int]:
        """The local cluster's worker processes (none for a remote cluster)."""
        if self._cluster is None:
            return []
        return [int(w.process.pid) for w in self._cluster.workers.values()
                if getattr(w, "process", None) is not None and w.process.pid is not None]

    def run(self, tasks: Sequence[tuple[Any, ...]], on_result: Callable[[int, Any], None],
            should_stop: Callable[[], bool] = lambda: False) -> bool:
        """Run every task (index i of ``tasks``, submitted in order); ``on_result(i, result)`` in the parent as
        each ends. Returns True when stopped by ``should_stop`` before all ended. The first error is raised."""
        run_id = uuid.uuid4().hex[:8]
        pending = {self._client.submit(_answer, self._fn, *task, pure=False, key=f"visit-{i:04d}-{run_id}"): i
                   for i, task in enumerate(tasks)}
        seen = set(self._client.scheduler_info()["workers"])
        next_look = time.monotonic() + 0.5
        try:
            while pending:
                if should_stop():
                    return True
                done = sorted((f for f in pending if f.done()), key=pending.__getitem__)
                if time.monotonic() >= next_look:
                    next_look = time.monotonic() + 0.5
                    seen = self._look_for_lost(seen)
                if not done:
                    time.sleep(min(0.05, POLL_S))
                    continue
                for fut in done:
                    i = pending.pop(fut)
                    try:
                        answer = fut.result()
                    except Exception as exc:  # KilledWorker: its worker died on every try
                        raise WorkerDiedError(f"visit {i + 1}: its worker process ended without an answer on every "
                                              f"try ({type(exc).__name__}: {exc}; out of memory, or killed from "
                                              "outside?)") from None
                    if answer[0] != "ok":
                        _raise_for(answer[1], answer[2])
                    on_result(i, answer[1])
        finally:
            for fut in pending:
                fut.cancel()
        return False

    def _look_for_lost(self, seen: set[str]) -> set[str]:
        from studies.batch.runner import counted

        now = set(self._client.scheduler_info()["workers"])
        lost = len(seen - now)
        if lost:
            self.workers_lost += lost
            whose = "its visit runs" if self.workers_lost == 1 else "their visits run"
            print(f"shm run: {counted(self.workers_lost, 'worker')} lost — {whose} again",
                  file=sys.stderr, flush=True)
        return now

    def close(self) -> None:
        """Close the client and the local cluster; a worker process still alive after the grace time is killed."""
        pids = self.pids
        with contextlib.suppress(Exception):
            self._client.close(timeout=TERMINATE_GRACE_S)
        if self._cluster is not None:
            with contextlib.suppress(Exception):
                self._cluster.close(timeout=TERMINATE_GRACE_S)
            for pid in pids:
                if _still_my_child(pid):  # never a pid the system gave to another process since
                    with contextlib.suppress(ProcessLookupError, PermissionError):
                        os.kill(pid, signal.SIGKILL)
            deadline = time.monotonic() + TERMINATE_GRACE_S
            while any(_still_my_child(p) for p in pids) and time.monotonic() < deadline:
                time.sleep(0.05)
            multiprocessing.active_children()  # reaps the killed workers through their Process objects

    def __enter__(self) -> LifePool:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
