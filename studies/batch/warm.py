"""Warm every Dask worker once before its first task (imports distributed: loaded only for a Dask run)."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from distributed.diagnostics.plugin import WorkerPlugin

#: seconds the warm-up took in this worker process, by plugin name
WARM_S: dict[str, float] = {}


def warm_seconds() -> dict[str, float]:
    """What the warm-up cost on this worker (s); run on every worker with ``client.run``."""
    return dict(WARM_S)


class WarmPlugin(WorkerPlugin):
    """``warm()`` once on every worker before it runs a task — a worker that joins later too."""

    name = "mfc-shm-warm"

    def __init__(self, warm: Callable[[], None]) -> None:
        self.warm = warm

    def setup(self, worker: Any) -> None:
        t0 = time.perf_counter()
        self.warm()
        WARM_S[self.name] = time.perf_counter() - t0
