"""Task functions that fail on purpose, for the campaign's crash and resume tests (importable by worker processes
because pytest puts this directory on sys.path, which spawned/forkserver workers inherit)."""

from __future__ import annotations

import os

from studies.campaign import BatchSpec, run_batch


def crash_process_on(batch: BatchSpec, threads: int | None = 1, *, key: str):
    """Kill the worker process abruptly (as a segfault or the OOM killer would) when it reaches batch ``key``."""
    if batch.key == key:
        os._exit(7)
    return run_batch(batch, threads)


def raise_on(batch: BatchSpec, threads: int | None = 1, *, key: str):
    """Raise an ordinary exception for batch ``key``."""
    if batch.key == key:
        raise RuntimeError(f"injected failure in {key}")
    return run_batch(batch, threads)
