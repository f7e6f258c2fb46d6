"""A challenge's or a bench's case loop on the scale-out runner (issue 31 point 3): each case one task, keyed by its
position in the case list (``case00000``, ``case00001`` ...), run on ``--scheduler`` (local worker processes,
``tcp://host:port`` or ``synchronous``) by :func:`studies.batch.runner.run_tasks` — the case scattered once, the
workers warmed before their first case, a lost worker's case rerun.

``fn(*case)`` must be a module-level function (sent to the workers by reference) whose arguments and result pickle.
Results come back in case order, whatever order the workers finish them in, and ``on_result`` sees each one in case
order as soon as every earlier case is in (the same order a ``ProcessPoolExecutor.map`` loop gave): a progress log
written from it reads as before. A case that raises stops the run with :class:`CaseFailed` naming the case, as the
loop's exception did.
"""

from __future__ import annotations

import os
import pickle
import sys
import time
import traceback
from collections.abc import Callable, Sequence
from typing import Any

from studies.batch.runner import BatchOutcome, BatchProgress, TaskResult, run_tasks

CASE_FILE = "case.pkl"
RESULT_FILE = "result.pkl"


class CaseFailed(RuntimeError):
    """A case raised (on its worker): the case key, its exception and the worker's traceback."""


def case_key(index: int) -> str:
    """The task key of case ``index``: zero-padded, so the runner's key order is the case order."""
    return f"case{index:05d}"


def run_case_task(key: str, files: dict[str, bytes], shared: dict[str, bytes], fn: Callable[..., Any]) -> TaskResult:
    """One case on a worker: ``fn(*case)``; its result pickled back, an exception a result with code 1."""
    t0, c0 = time.perf_counter(), time.process_time()
    case = pickle.loads(files[CASE_FILE])
    try:
        code, message, out = 0, "done", {RESULT_FILE: pickle.dumps(fn(*case))}
    except Exception as exc:  # reported in the parent, named by the case
        code, message, out = 1, f"{type(exc).__name__}: {exc}", {"traceback.txt": traceback.format_exc().encode()}
    return TaskResult(key, code, message, files=out, wall_s=time.perf_counter() - t0, cpu_s=time.process_time() - c0,
                      worker=f"{os.uname().nodename}:{os.getpid()}")


def warm_kernels() -> None:
    """The nominal model's compiled kernel loaded on a worker before its first case (a 0.2 s MBIT.b record)."""
    from workbench.simulation import synth_record, synth_test, truth_model

    synth_record(synth_test("mbit-b", duration_s=0.2, t_step_s=0.05), truth_model("table2", [], {}))


def _failed(r: TaskResult) -> CaseFailed:
    trace = r.files.get("traceback.txt", b"").decode("utf-8", "replace").strip()
    return CaseFailed(f"{r.key} failed: {r.message}" + (f"\n{trace}" if trace else ""))


def _lost_workers_line(what: str) -> Callable[[BatchProgress], None]:
    """Prints the runner's progress line to stderr when a worker is lost (the per-case lines are the caller's)."""
    seen = [0]

    def show(p: BatchProgress) -> None:
        if p.workers_lost > seen[0]:
            seen[0] = p.workers_lost
            print(p.line(what), file=sys.stderr, flush=True)
    return show


def run_cases(fn: Callable[..., Any], cases: Sequence[tuple[Any, ...]], *, scheduler: str | None = None,
              workers: int | None = None, on_result: Callable[[Any], None] | None = None,
              warm: Callable[[], None] | None = warm_kernels, what: str = "cases") -> tuple[list[Any], BatchOutcome]:
    """``[fn(*case) for case in cases]`` as one task per case on ``scheduler`` (default: ``workers`` local
    processes); the results in case order and what the run cost."""
    from studies.batch.runner import check_scheduler

    scheduler = check_scheduler(scheduler)
    keys = [case_key(i) for i in range(len(cases))]
    tasks = [(k, {CASE_FILE: pickle.dumps(tuple(c))}) for k, c in zip(keys, cases, strict=True)]
    arrived: dict[str, TaskResult] = {}
    released = [0]

    def in_order(r: TaskResult) -> None:
        arrived[r.key] = r
        while released[0] < len(keys) and keys[released[0]] in arrived:
            head = arrived[keys[released[0]]]
            if head.code:
                raise _failed(head)
            if on_result is not None:
                on_result(pickle.loads(head.files[RESULT_FILE]))
            released[0] += 1

    outcome = run_tasks(tasks, run_case_task, fn, scheduler=scheduler, workers=workers, warm=warm,
                        progress=_lost_workers_line(what), on_result=in_order)
    return [pickle.loads(r.files[RESULT_FILE]) for r in outcome.results], outcome
