"""Run many tasks on Dask: local processes (default), a cluster (``tcp://host:port``) or in this process
(``synchronous``, for debugging) — the same task function, the same results, ordered by task key.

Data moves once: every task's input files are scattered to the workers once (one future each, the task refers to
it), the shared inputs (a parameter set's file ...) are broadcast once to every worker; compiled kernels are warmed
on each worker by a worker plugin before its first task (and on a worker that joins later). A task function catches
its own errors (a record that fails is a result with a non-zero code), so an exception from a future is the
infrastructure: a worker died or its data was lost. Such a task is resubmitted (its input scattered again when it
was lost with the worker) up to :data:`MAX_ATTEMPTS` times; the progress line counts lost workers and reruns.
"""

from __future__ import annotations

import asyncio
import contextlib
import os
import time
import uuid
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from board_config.errors import InputError

#: a task: fn(key, files by name, shared files by name, options) -> TaskResult
TaskFn = Callable[[str, dict[str, bytes], dict[str, bytes], Any], "TaskResult"]
ProgressFn = Callable[["BatchProgress"], None]
#: sees each task's result as it arrives (completion order; a lost task's final failure too)
ResultFn = Callable[["TaskResult"], None]
#: submissions of one task before it is reported failed (a worker lost each time)
MAX_ATTEMPTS = 4
#: seconds between looks at the cluster's workers while no result arrives (a result is taken the moment it is done)
POLL_S = 0.5
#: seconds a lost task's input waits for a worker to be scattered to again (a nanny restarts a killed worker)
RESCATTER_WAIT_S = 60.0


def counted(n: int, noun: str, plural: str | None = None) -> str:
    """``"1 worker"``, ``"2 workers"``, ``"0 workers"``: a count and its noun as a progress line says it."""
    return f"{n} {noun if n == 1 else (plural or noun + 's')}"


class SchedulerError(InputError):
    """The scheduler cannot be reached or started."""


@dataclass
class TaskResult:
    """What one task did: its exit code, a one-line message, its JSON document and the files it wrote."""

    key: str
    code: int
    message: str
    doc: dict[str, Any] = field(default_factory=dict)
    files: dict[str, bytes] = field(default_factory=dict)
    wall_s: float = 0.0
    cpu_s: float = 0.0
    worker: str = ""
    #: CPU of the task's own thread (s; ``cpu_s`` is the whole worker process's: its Dask threads too) and when the
    #: task started (epoch s, the worker's clock): the per-task record of the run's cost
    thread_cpu_s: float = 0.0
    started: float = 0.0


@dataclass
class BatchProgress:
    done: int
    total: int
    workers: int
    workers_lost: int
    reruns: int

    def line(self, what: str) -> str:
        text = f"{what}: {self.done}/{counted(self.total, 'task')} done, {counted(self.workers, 'worker')}"
        if self.workers_lost:
            text += f", {counted(self.workers_lost, 'worker')} lost — {counted(self.reruns, 'task')} rerun"
        return text


@dataclass
class BatchOutcome:
    """All results (ordered by key) and what the run cost."""

    results: list[TaskResult]
    scheduler: str
    n_workers: int
    workers_lost: int = 0
    reruns: int = 0
    wall_s: float = 0.0
    warm_s: dict[str, float] = field(default_factory=dict)
    bytes_scattered: int = 0
    bytes_returned: int = 0
    #: where the run's wall time went (s): connect, warm (the workers' warm-up, waited for), scatter, tasks (first
    #: submission to last result; first_task_extra of it: a worker's first task beyond the others' median)
    phases_s: dict[str, float] = field(default_factory=dict)

    def cost(self) -> dict[str, Any]:
        task_wall = sum(r.wall_s for r in self.results)
        t0 = min((r.started for r in self.results if r.started), default=0.0)
        per_task = [{"key": r.key, "worker": r.worker, "start_s": r.started - t0 if r.started else None,
                     "wall_s": r.wall_s, "cpu_s": r.cpu_s, "thread_cpu_s": r.thread_cpu_s} for r in self.results]
        return {"scheduler": self.scheduler, "workers": self.n_workers, "workers_lost": self.workers_lost,
                "reruns": self.reruns, "wall_s": self.wall_s, "task_wall_s": task_wall,
                "task_cpu_s": sum(r.cpu_s for r in self.results), "warm_s": self.warm_s,
                "bytes_scattered": self.bytes_scattered, "bytes_returned": self.bytes_returned,
                "task_thread_cpu_s": sum(r.thread_cpu_s for r in self.results),
                "phases_s": self.phases_s, "tasks": per_task}


# --- connecting --------------------------------------------------------------------------------------------------
def connect(scheduler: str | None, workers: int | None, n_tasks: int, timeout_s: float = 10.0, *,
            fork: bool = False, worker_wait_s: float = 30.0) -> tuple[Any, Any, str]:
    """(client, local cluster or None, description): a LocalCluster of ``min(workers or CPUs, n_tasks)``
    single-thread worker processes for ``local``/None, else the cluster at ``scheduler``. ``fork``: the local
    workers are forked from this process (they inherit its imported modules and compiled kernels) instead of
    spawned (a fresh interpreter each, which imports mfc-shm and loads or compiles every kernel again). A remote
    cluster gets ``worker_wait_s`` for its first worker to join (a cluster without one is an input error)."""
    try:
        from distributed import Client, LocalCluster

        from studies.batch.warm import TICK_MS
    except ImportError:
        raise SchedulerError("--scheduler needs Dask: pip install 'mfc-shm[cluster]'") from None
    if scheduler in (None, "", "local"):
        n = max(1, min(workers or os.cpu_count() or 1, n_tasks))
        import dask

        # non-daemon workers: a task may run its own process pool (a board's life, a health fit)
        method = "fork" if fork else dask.config.get("distributed.worker.multiprocessing-method")
        if fork:
            quiet_forked_workers()
        # the scheduler's, nannies' and workers' event-loop check every second, not every 20 ms (studies.batch.warm)
        with dask.config.set({"distributed.worker.daemon": False, "distributed.worker.multiprocessing-method": method,
                              "distributed.admin.tick.interval": f"{TICK_MS:g}ms"}):
            # no dashboard; the scheduler's small HTTP server on a free port (not 8787: no warning beside a 2nd run)
            cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None,
                                   scheduler_kwargs={"dashboard_address": ":0"}, memory_limit=0, silence_logs=50)
        return Client(cluster, set_as_default=False), cluster, f"local processes ({counted(n, 'worker')})"
    probe_scheduler(scheduler, timeout_s)
    try:
        client = Client(scheduler, timeout=f"{timeout_s}s", set_as_default=False)
    except (OSError, TimeoutError) as exc:
        raise SchedulerError(f"--scheduler: cannot reach the Dask scheduler at {scheduler!r} within "
                             f"{timeout_s:g} s ({exc})") from None
    except Exception as exc:  # malformed address and other connection errors
        raise SchedulerError(f"--scheduler: cannot connect to {scheduler!r}: {type(exc).__name__}: {exc}") from None
    try:
        client.wait_for_workers(1, timeout=worker_wait_s)  # a worker started with the scheduler may still import
    except TimeoutError:
        client.close()
        raise SchedulerError(f"--scheduler {scheduler}: the cluster has no worker (waited {worker_wait_s:g} s); start "
                             f"one with 'dask worker {scheduler} --nthreads 1'") from None
    return client, None, f"dask {scheduler}"


def quiet_forked_workers() -> None:
    """Dask's own records below WARNING are not made at all in this process while it forks workers: a nanny forks
    its worker from a thread of this process at any moment (a restart too), and a record another thread was writing
    then leaves that handler's stream locked in the child, whose first ``logger.info`` ("Start worker at …") waits on
    it for ever (seen under pytest, whose root logger writes to a file: a LifePool start hung 10 minutes). The
    cluster's logs are silenced to CRITICAL on screen anyway (``silence_logs``)."""
    import logging

    dask_logger = logging.getLogger("distributed")
    if dask_logger.getEffectiveLevel() < logging.WARNING:
        dask_logger.setLevel(logging.WARNING)


#: the address schemes of a Dask scheduler (distributed's comm backends)
SCHEMES = ("tcp", "tls", "ws", "wss", "ucx")


def check_scheduler(text: str | None) -> str | None:
    """The ``--scheduler`` value, checked without connecting: ``local``, ``synchronous`` or ``SCHEME://HOST:PORT``
    (scheme of :data:`SCHEMES`, a host, a port 1-65535); None (the option not given) is the default."""
    if text is None or text in ("local", "synchronous"):
        return text
    expected = "expected local, synchronous or tcp://HOST:PORT"
    if "://" not in text:
        raise SchedulerError(f"--scheduler {text!r}: {'empty; ' if not text.strip() else ''}{expected}")
    scheme, host, port = _address_parts(text)
    if scheme not in SCHEMES:
        raise SchedulerError(f"--scheduler {text!r}: unknown scheme {scheme!r} (a Dask scheduler's address is "
                             f"{', '.join(s + '://' for s in SCHEMES)}); {expected}")
    if not host:
        raise SchedulerError(f"--scheduler {text!r}: no host; {expected}")
    if port is None:
        raise SchedulerError(f"--scheduler {text!r}: no port or not a port in 1-65535; {expected} "
                             "(dask scheduler's default port is 8786)")
    return text


def reach_scheduler(text: str | None, timeout_s: float = 10.0) -> str | None:
    """:func:`check_scheduler`, then :func:`probe_scheduler` for an address: in a command before it prints or
    creates anything, so that an unknown host or a closed port is its one line and leaves no ``--out`` behind."""
    scheduler = check_scheduler(text)
    if scheduler not in (None, "local", "synchronous"):
        probe_scheduler(scheduler, timeout_s)
    return scheduler


def _address_parts(text: str) -> tuple[str, str, int | None]:
    """(scheme, host, port or None when missing or out of range) of ``SCHEME://HOST:PORT``."""
    from urllib.parse import urlsplit

    parts = urlsplit(text)
    try:
        port = parts.port
    except ValueError:
        port = None
    return parts.scheme.lower(), parts.hostname or "", port if port and not parts.path.strip("/") else None


def probe_scheduler(address: str, timeout_s: float) -> None:
    """Say in words what is wrong with a ``tcp://`` address before Dask's client tries it: an unknown host at once,
    a port where nothing listens (connection refused, tried again until ``timeout_s``: a scheduler started just
    before, as in docs/scale-out.md, may not listen yet) — Dask says 'Timed out' for both. Other schemes and
    unreachable or slow networks are left to Dask's own connection and timeout."""
    import socket

    scheme, host, port = _address_parts(address)
    if scheme != "tcp" or port is None:
        return
    deadline = time.monotonic() + timeout_s
    while True:
        try:
            socket.create_connection((host, port), timeout=timeout_s).close()
            return
        except socket.gaierror as exc:
            raise SchedulerError(f"--scheduler {address}: unknown host {host!r} ({exc.strerror or exc})") from None
        except ConnectionRefusedError:
            if time.monotonic() >= deadline:
                raise SchedulerError(f"--scheduler {address}: nothing listens at {host}:{port} (connection refused "
                                     f"for {timeout_s:g} s); start 'dask scheduler --port {port}' there, or give "
                                     "the address it printed") from None
            time.sleep(0.25)
        except OSError:
            return


def first_task_extra(arrived: list[TaskResult]) -> float:
    """How much longer (s) a worker's first task ran than the median of the others, averaged over the workers
    (``arrived`` in completion order): what the warm-up left to the first task (imports, kernels, fonts)."""
    first: dict[str, float] = {}
    rest: list[float] = []
    for r in arrived:
        if r.worker and r.worker not in first:
            first[r.worker] = r.wall_s
        else:
            rest.append(r.wall_s)
    if not first or not rest:
        return 0.0
    median = sorted(rest)[len(rest) // 2]
    return sum(first.values()) / len(first) - median


def _first_done(client: Any, futures: list[Any]) -> list[Any]:
    """The futures done now, waiting until one is or :data:`POLL_S` passed (then maybe none: the caller looks at
    the workers). A future cancelled with its worker's data comes back here as done, it does not raise."""
    from distributed import wait
    from distributed.client import FuturesCancelledError

    with client.as_current(), contextlib.suppress(TimeoutError, FuturesCancelledError, asyncio.CancelledError):
        wait(futures, timeout=POLL_S, return_when="FIRST_COMPLETED")
    return [f for f in futures if f.done()]


def timed_task(fn: TaskFn, key: str, files: dict[str, bytes], shared: dict[str, bytes], options: Any) -> Any:
    """``fn(key, files, shared, options)``, its result stamped with when it started and the CPU of this thread
    alone (what the task itself used, apart from the worker's own threads: event loop, heartbeats, profiler); its
    wall and process CPU too when ``fn`` left them unset."""
    started, t0, c0, th0 = time.time(), time.perf_counter(), time.process_time(), time.thread_time()
    result = fn(key, files, shared, options)
    if isinstance(result, TaskResult):
        result.started, result.thread_cpu_s = started, time.thread_time() - th0
        if not result.wall_s and not result.cpu_s:
            result.wall_s, result.cpu_s = time.perf_counter() - t0, time.process_time() - c0
    return result


# --- running -----------------------------------------------------------------------------------------------------
def run_tasks(tasks: list[tuple[str, dict[str, bytes]]], fn: TaskFn, options: Any, *,
              shared: dict[str, bytes] | None = None, scheduler: str | None = None, workers: int | None = None,
              warm: Callable[[], None] | None = None, progress: ProgressFn | None = None,
              on_result: ResultFn | None = None, timeout_s: float = 10.0,
              longest_first: bool = False) -> BatchOutcome:
    """Run ``fn`` once per ``(key, files)`` and return the results ordered by key (never by completion).
    ``longest_first``: on Dask, the tasks with the most input bytes start first (a board with more visits, a
    longer record), so no long task is left alone for the last wave."""
    shared = shared or {}
    t0 = time.perf_counter()
    if scheduler == "synchronous":
        outcome = _run_here(tasks, fn, options, shared, warm, progress, on_result)
    else:
        client, cluster, desc = connect(scheduler, workers, len(tasks), timeout_s)
        connect_s = time.perf_counter() - t0
        try:
            outcome = _run_dask(client, desc, tasks, fn, options, shared, warm, progress, on_result, longest_first)
        finally:
            client.close()
            if cluster is not None:
                cluster.close()
        outcome.phases_s = {"connect": connect_s, **outcome.phases_s}
    outcome.results.sort(key=lambda r: r.key)
    outcome.wall_s = time.perf_counter() - t0
    outcome.bytes_returned = sum(len(b) for r in outcome.results for b in r.files.values())
    return outcome


def _run_here(tasks, fn, options, shared, warm, progress, on_result) -> BatchOutcome:
    warm_s = {}
    if warm is not None:
        t0 = time.perf_counter()
        warm()
        warm_s["this process"] = time.perf_counter() - t0
    results = []
    for i, (key, files) in enumerate(sorted(tasks, key=lambda t: t[0])):
        results.append(timed_task(fn, key, files, shared, options))
        if on_result is not None:
            on_result(results[-1])
        if progress is not None:
            progress(BatchProgress(i + 1, len(tasks), 1, 0, 0))
    return BatchOutcome(results, "synchronous (this process)", 1, warm_s=warm_s)


def scatter_one(client: Any, files: dict[str, bytes], broadcast: bool = False) -> Any:
    """One future holding one task's files (the dict as one object; ``broadcast``: on every worker), once a worker
    is there (a dead worker's nanny starts a new one). ``client.scatter(files)`` would scatter each file on its own,
    under the file's name as its Dask key: a rerun board's ``usage.db`` and ``records/...`` were then the same keys
    as another rerun board's, and one board was assessed on the other's data."""
    deadline = time.monotonic() + RESCATTER_WAIT_S
    while True:
        try:
            client.wait_for_workers(1, timeout=max(0.1, deadline - time.monotonic()))
            return client.scatter([files], broadcast=broadcast, hash=False)[0]
        except (OSError, TimeoutError):  # a worker that died meanwhile ('Stream is closed'): once it is replaced
            if time.monotonic() >= deadline:
                raise
            time.sleep(POLL_S)


def input_lost(future: Any) -> bool:
    """The scattered input of a task went with its worker (it must be scattered again for the rerun)."""
    return bool(future.status != "finished")


def _run_dask(client, desc, tasks, fn, options, shared, warm, progress, on_result,
              longest_first=False) -> BatchOutcome:
    from studies.batch.warm import WarmPlugin, warm_seconds

    t0 = time.perf_counter()
    client.register_plugin(WarmPlugin(warm), name=WarmPlugin.name)  # one thread per task, kernels warm
    warm_s = {w: s.get(WarmPlugin.name, 0.0) for w, s in client.run(warm_seconds).items()}
    t1 = time.perf_counter()
    run_id = uuid.uuid4().hex[:8]
    shared_f = [client.scatter([shared], broadcast=True, hash=False)[0]]  # [0] scattered again if every copy went
    inputs = dict(zip([k for k, _ in tasks], client.scatter([f for _, f in tasks], hash=False), strict=True))
    payload = {k: f for k, f in tasks}
    scattered = sum(len(b) for _, f in tasks for b in f.values()) + len(warm_s) * sum(len(b) for b in shared.values())
    attempts = dict.fromkeys(payload, 0)
    size_of = {k: sum(len(b) for b in f.values()) for k, f in payload.items()}

    def submit(key: str) -> Any:
        attempts[key] += 1
        # longest first (by its input's bytes) when asked: the last wave is then the short tasks
        return client.submit(timed_task, fn, key, inputs[key], shared_f[0], options, pure=False,
                             priority=size_of[key] if longest_first else 0,
                             key=f"shm-{key}-{run_id}-{attempts[key]}")

    order = sorted(payload, key=lambda k: (-size_of[k], k)) if longest_first else sorted(payload)
    t2 = time.perf_counter()
    pending = {submit(k): k for k in order}
    results: dict[str, TaskResult] = {}
    processing: dict[str, Any] = client.processing()
    lost = 0
    rerun: set[str] = set()
    n_workers = len(processing)
    while pending:
        done = _first_done(client, list(pending))
        now = client.processing()
        gone = set(processing) - set(now)
        lost += len(gone)
        by_dask_key = {f.key: k for f, k in pending.items()}
        # the scheduler reruns what a lost worker was running (or it comes back cancelled and is resubmitted below)
        rerun.update(by_dask_key[t] for w in gone for t in processing[w] if t in by_dask_key)
        processing = now
        n_workers = max(n_workers, len(now))
        changed = bool(done or gone)
        for fut in done:
            key = pending.pop(fut)
            try:
                results[key] = fut.result()
            except (Exception, asyncio.CancelledError) as exc:  # a worker died or took the task's data: again
                if attempts[key] >= MAX_ATTEMPTS:
                    results[key] = TaskResult(key, 1, f"lost {attempts[key]} times with its worker: "
                                                      f"{type(exc).__name__}: {exc}")
                    if on_result is not None:
                        on_result(results[key])
                    continue
                try:
                    if input_lost(shared_f[0]):  # every worker died at once (or the only one): no copy is left
                        shared_f[0] = scatter_one(client, shared, broadcast=True)
                    if input_lost(inputs[key]):
                        inputs[key] = scatter_one(client, payload[key])
                        scattered += sum(len(b) for b in payload[key].values())
                except (OSError, TimeoutError) as lost_exc:  # no worker came back: this task fails, the rest stay
                    results[key] = TaskResult(key, 1, f"lost with its worker, and no worker took its input again "
                                                      f"within {RESCATTER_WAIT_S:g} s: {lost_exc}")
                    if on_result is not None:
                        on_result(results[key])
                    continue
                rerun.add(key)
                pending[submit(key)] = key
                continue
            if on_result is not None:
                on_result(results[key])
        if progress is not None and changed:
            progress(BatchProgress(len(results), len(tasks), len(now), lost, len(rerun)))
    phases = {"warm": t1 - t0, "scatter": t2 - t1, "tasks": time.perf_counter() - t2,
              "first_task_extra": first_task_extra(list(results.values()))}
    return BatchOutcome(list(results.values()), desc, n_workers, lost, len(rerun), warm_s=warm_s,
                        bytes_scattered=scattered, phases_s=phases)
