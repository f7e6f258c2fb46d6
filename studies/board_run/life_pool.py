"""The worker pool of a life run (``shm run`` on a ``[life]`` scenario): visits on local processes, stoppable.

Why not ``concurrent.futures.ProcessPoolExecutor``: an exception that cannot be unpickled in the parent (any error
class with its own ``__init__``) broke the whole pool ("BrokenProcessPool"), and a SIGTERM or Ctrl-C meant either
workers left running (parented to PID 1) or a parent blocked in the executor's queue locks. Here:

* each worker is a plain process with its own pipe: the parent sends a task, the worker sends back
  ``("ok", result)`` or ``("error", kind, message)`` — an error crosses as text, so it always arrives, and an
  :class:`~board_config.errors.InputError` raised inside a visit reaches the user as the same one line (exit 2);
* workers ignore SIGINT (a terminal's Ctrl-C goes to the whole process group; the parent decides) and die with
  their parent (Linux ``PR_SET_PDEATHSIG``), so a killed parent leaves no worker behind;
* ``should_stop()`` is polled at least every 0.2 s; once true, no new visit starts, every worker is terminated
  (SIGTERM, then SIGKILL after 5 s) and joined, and the visits finished so far are what the run returns.
"""

from __future__ import annotations

import contextlib
import ctypes
import multiprocessing as mp
import signal
from collections.abc import Callable, Sequence
from multiprocessing.connection import Connection, wait
from typing import Any

from board_config.errors import InputError

#: how long a terminated worker may take before it is killed (s)
TERMINATE_GRACE_S = 5.0
POLL_S = 0.2


class VisitInputError(InputError):
    """A user's mistake found inside a visit's worker (the message as the worker's InputError said it)."""


class VisitFailedError(RuntimeError):
    """An unexpected error inside a visit's worker (type and message of the original; a bug in mfc-shm)."""


class WorkerDiedError(OSError):
    """A worker process ended without an answer (killed from outside: out of memory, a signal)."""


def _die_with_parent() -> None:
    with contextlib.suppress(OSError, AttributeError):
        libc = ctypes.CDLL("libc.so.6", use_errno=True)
        libc.prctl(1, int(signal.SIGKILL))  # PR_SET_PDEATHSIG


def _worker_main(conn: Connection, fn: Callable[..., Any]) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    _die_with_parent()
    while True:
        try:
            task = conn.recv()
        except (EOFError, OSError):
            return
        if task is None:
            return
        try:
            answer: tuple[Any, ...] = ("ok", fn(*task))
        except InputError as exc:
            answer = ("error", "input", str(exc))
        except OSError as exc:
            answer = ("error", "os", f"{exc}")
        except Exception as exc:  # a bug: its type and message travel as text
            answer = ("error", "bug", f"{type(exc).__name__}: {exc}")
        try:
            conn.send(answer)
        except Exception as exc:  # an unpicklable result is a bug too; say so instead of dying silently
            conn.send(("error", "bug", f"cannot send the visit's result: {type(exc).__name__}: {exc}"))


def _raise_for(kind: str, message: str) -> None:
    if kind == "input":
        raise VisitInputError(message)
    if kind == "os":
        raise OSError(message)
    raise VisitFailedError(message)


class LifePool:
    """``workers`` processes running ``fn(*task)``; see the module docstring."""

    def __init__(self, fn: Callable[..., Any], workers: int) -> None:
        ctx = mp.get_context("fork") if "fork" in mp.get_all_start_methods() else mp.get_context()
        self._workers: list[tuple[Any, Connection]] = []
        for _ in range(max(1, workers)):
            parent_end, child_end = ctx.Pipe(duplex=True)
            proc = ctx.Process(target=_worker_main, args=(child_end, fn), daemon=True)
            proc.start()
            child_end.close()
            self._workers.append((proc, parent_end))

    @property
    def pids(self) -> list[int]:
        return [p.pid for p, _ in self._workers if p.pid is not None]

    def run(self, tasks: Sequence[tuple[Any, ...]], on_result: Callable[[int, Any], None],
            should_stop: Callable[[], bool] = lambda: False) -> bool:
        """Run every task (index i of ``tasks``); ``on_result(i, result)`` in the parent as each ends. Returns
        True when stopped by ``should_stop`` before all ended. The first error ends the pool and is raised."""
        todo = list(range(len(tasks)))
        busy: dict[int, int] = {}  # worker index -> task index
        while todo or busy:
            if should_stop():
                return True
            for w, (_proc, conn) in enumerate(self._workers):
                if w not in busy and todo:
                    i = todo.pop(0)
                    try:
                        conn.send(tasks[i])
                    except OSError:  # the worker is gone (killed from outside)
                        raise WorkerDiedError(self._died(w, i)) from None
                    busy[w] = i
            conns: dict[Any, int] = {self._workers[w][1]: w for w in busy}
            sentinels: dict[Any, int] = {self._workers[w][0].sentinel: w for w in busy}
            ready = wait([*conns, *sentinels], timeout=POLL_S)
            for obj in ready:
                r = conns.get(obj)
                if r is None or r not in busy:
                    continue
                try:
                    answer = self._workers[r][1].recv()
                except (EOFError, OSError):
                    raise WorkerDiedError(self._died(r, busy[r])) from None
                i = busy.pop(r)
                if answer[0] != "ok":
                    _raise_for(answer[1], answer[2])
                on_result(i, answer[1])
            for obj in ready:
                s = sentinels.get(obj)
                if s is not None and s in busy and not self._workers[s][1].poll():
                    raise WorkerDiedError(self._died(s, busy[s]))
        return False

    def _died(self, w: int, task: int) -> str:
        proc = self._workers[w][0]
        proc.join(1.0)
        code = proc.exitcode
        how = f"killed by signal {-code}" if code is not None and code < 0 else f"exit code {code}"
        return (f"the worker process running task {task + 1} (pid {proc.pid}) ended without an answer ({how}; "
                "out of memory, or killed from outside?)")

    def close(self) -> None:
        """Stop every worker (asked to end, terminated if busy, killed if it does not go) and join them."""
        for proc, conn in self._workers:
            with contextlib.suppress(OSError, ValueError):
                if proc.is_alive():
                    proc.terminate()
            with contextlib.suppress(OSError):
                conn.close()
        for proc, _ in self._workers:
            proc.join(TERMINATE_GRACE_S)
            if proc.is_alive():
                proc.kill()
                proc.join(TERMINATE_GRACE_S)
        self._workers.clear()

    def __enter__(self) -> LifePool:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
