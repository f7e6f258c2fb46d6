"""Ready every Dask worker once before its first task (imports distributed: loaded only for a Dask run): one
integration thread per task, then the compiled kernels warmed."""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from typing import Any

from distributed.diagnostics.plugin import WorkerPlugin

#: seconds the warm-up took in this worker process, by plugin name
WARM_S: dict[str, float] = {}
#: the integrator's threads per task on a worker (``$MFC_SHM_THREADS``, read at each batch): a worker runs one task
#: per thread and is meant to have one core (``--nthreads 1``, one worker per core), so a task that split its
#: batches over every CPU of the machine would compete with the next worker's task for the same cores
TASK_THREADS = "1"
#: the worker's periodic callbacks of its statistical profiler (``distributed.worker.profile``: the task thread's
#: stack sampled every 10 ms of wall time, for the dashboard): 4-18 % of a health task's CPU on a thread beside the
#: task, which on a full machine is taken from the next worker's task (docs/scale-out.md, "Why the fleet lagged")
PROFILER_CALLBACKS = ("profile", "profile-cycle")
#: the event loop's health check ("tick": Dask's default every 20 ms, to warn when the loop was stuck > 3 s) every
#: second instead: at 20 ms it costs ~2 % of a core per worker, scheduler and nanny, all the time (docs/scale-out.md)
TICK_MS = 1000.0
#: glibc's malloc (M_MMAP_THRESHOLD, M_TRIM_THRESHOLD, bytes): arrays up to 128 MB come from the heap and up to 512 MB
#: freed at its top stay in the process for the next array. A Dask nanny starts its worker with
#: ``MALLOC_TRIM_THRESHOLD_=65536``, which also pins the mmap threshold at 128 kB: every larger numpy array was mapped
#: fresh and unmapped when freed, so its pages were faulted in and zeroed again in every use — a health task spent
#: 1.0-1.3 s of its 5 s in the kernel (150 000 page faults; 0.03 s with these; docs/scale-out.md)
MALLOC_KEEP = (128 << 20, 512 << 20)


def warm_seconds() -> dict[str, float]:
    """What the warm-up cost on this worker (s); run on every worker with ``client.run``."""
    return dict(WARM_S)


def profiler_running() -> bool:
    """Whether this worker's statistical profiler still samples its tasks; run with ``client.run``."""
    from distributed import get_worker

    callbacks = get_worker().periodic_callbacks
    return any(name in callbacks and callbacks[name].is_running() for name in PROFILER_CALLBACKS)


def stop_profiler(worker: Any) -> None:
    """Stop the worker's statistical profiler for the worker's life (removed from its periodic callbacks, so a
    worker that starts them after its plugins' setup does not restart it)."""
    callbacks = getattr(worker, "periodic_callbacks", {})
    for name in PROFILER_CALLBACKS:
        pc = callbacks.pop(name, None)
        if pc is not None:
            pc.stop()


def slow_tick(worker: Any) -> None:
    """Check the worker's event loop every :data:`TICK_MS` instead of every 20 ms (a stuck loop is still reported)."""
    pc = getattr(worker, "periodic_callbacks", {}).get("tick")
    if pc is not None:
        pc.callback_time = max(pc.callback_time, TICK_MS)


def tick_ms(dask_worker: Any = None) -> float:
    """The worker's event-loop check interval (ms); run with ``client.run``."""
    from distributed import get_worker

    return float((dask_worker or get_worker()).periodic_callbacks["tick"].callback_time)


def keep_freed_memory() -> bool:
    """Let this process's malloc keep freed memory for the next allocation (:data:`MALLOC_KEEP`); False where the
    C library is not glibc (nothing changed)."""
    import ctypes
    import ctypes.util

    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return False
    m_trim_threshold, m_mmap_threshold = -1, -3
    return bool(mallopt(m_mmap_threshold, MALLOC_KEEP[0])) and bool(mallopt(m_trim_threshold, MALLOC_KEEP[1]))


def refault_pages(nbytes: int) -> int:
    """Minor page faults of filling an array of ``nbytes`` after one of the same size was filled and freed: about
    ``nbytes`` / 4 kB when freed memory goes back to the system, near 0 when it is kept; run with ``client.run``."""
    import resource

    import numpy as np

    np.ones(nbytes // 8)
    before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    np.ones(nbytes // 8)
    return resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before


def task_threads() -> str | None:
    """The integrator's thread setting on this worker (``$MFC_SHM_THREADS``); run with ``client.run``."""
    return os.environ.get("MFC_SHM_THREADS")


class WarmPlugin(WorkerPlugin):
    """On every worker before it runs a task — a worker that joins later too: one integration thread per task
    (:data:`TASK_THREADS`, whatever the worker inherited), no statistical profiler beside the task, its event loop
    checked every second, freed memory kept for the next task (:func:`keep_freed_memory`), then ``warm()`` if
    given."""

    name = "mfc-shm-warm"

    def __init__(self, warm: Callable[[], None] | None) -> None:
        self.warm = warm

    def setup(self, worker: Any) -> None:
        os.environ["MFC_SHM_THREADS"] = TASK_THREADS
        stop_profiler(worker)
        slow_tick(worker)
        keep_freed_memory()
        t0 = time.perf_counter()
        if self.warm is not None:
            self.warm()
        WARM_S[self.name] = time.perf_counter() - t0
