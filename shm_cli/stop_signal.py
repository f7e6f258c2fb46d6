"""A clean stop of ``shm run`` (a single run or a life) on SIGINT (Ctrl-C) or SIGTERM: the run ends after the current
tick (or quiet span, or visit), its results are written, and the exit code says which signal (130 / 143)."""

from __future__ import annotations

import signal
import sys
import threading
from types import FrameType
from typing import Any

from firmware_sim.scheduler import SchedulerWrapper, TickScheduler

EXIT_SIGINT = 130
EXIT_SIGTERM = 143


class StopOnSignal:
    """SIGINT (Ctrl-C) and SIGTERM request a clean stop after the current tick (a second signal aborts at once
    with KeyboardInterrupt). Installed only in the main thread; restores the previous handlers on exit."""

    def __init__(self) -> None:
        self.signal: int | None = None
        self._old: dict[int, Any] = {}

    def _handler(self, signum: int, frame: FrameType | None) -> None:
        if self.signal is not None:
            raise KeyboardInterrupt
        self.signal = signum

    @property
    def requested(self) -> bool:
        return self.signal is not None

    @property
    def exit_code(self) -> int:
        return EXIT_SIGTERM if self.signal == signal.SIGTERM else EXIT_SIGINT

    @property
    def name(self) -> str:
        return "SIGTERM" if self.signal == signal.SIGTERM else "SIGINT (Ctrl-C)"

    def __enter__(self) -> StopOnSignal:
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                self._old[sig] = signal.signal(sig, self._handler)
        return self

    def __exit__(self, *exc: object) -> None:
        for sig, old in self._old.items():
            signal.signal(sig, old)
        self._old.clear()

    def report(self, interrupted: bool, partial: str, what: str, complete_in: str) -> int:
        """After a stop was requested: one line on stderr, ``partial`` (what was kept) when the job was cut short,
        else that the signal came after ``what`` finished and its results are complete in ``complete_in``; the
        exit code of the signal."""
        if interrupted:
            print(f"shm run: interrupted by {self.name}{partial}", file=sys.stderr)
        else:
            print(f"shm run: {self.name} received after {what} finished; its results are complete in {complete_in}",
                  file=sys.stderr)
        return self.exit_code


class StoppableScheduler(SchedulerWrapper):
    """A scheduler whose run ends after the tick (or quiet span) in which ``stop.requested`` became true."""

    def __init__(self, inner: TickScheduler, stop: StopOnSignal) -> None:
        super().__init__(inner)
        self._stop = stop

    def after_ticks(self, k: int, overran: bool, ticks: int) -> bool:
        return self._stop.requested
