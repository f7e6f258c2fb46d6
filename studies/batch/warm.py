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


def warm_seconds() -> dict[str, float]:
    """What the warm-up cost on this worker (s); run on every worker with ``client.run``."""
    return dict(WARM_S)


def task_threads() -> str | None:
    """The integrator's thread setting on this worker (``$MFC_SHM_THREADS``); run with ``client.run``."""
    return os.environ.get("MFC_SHM_THREADS")


class WarmPlugin(WorkerPlugin):
    """On every worker before it runs a task — a worker that joins later too: one integration thread per task
    (:data:`TASK_THREADS`, whatever the worker inherited), then ``warm()`` if given."""

    name = "mfc-shm-warm"

    def __init__(self, warm: Callable[[], None] | None) -> None:
        self.warm = warm

    def setup(self, worker: Any) -> None:
        os.environ["MFC_SHM_THREADS"] = TASK_THREADS
        t0 = time.perf_counter()
        if self.warm is not None:
            self.warm()
        WARM_S[self.name] = time.perf_counter() - t0
