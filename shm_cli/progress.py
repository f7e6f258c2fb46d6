"""Progress of a long command on stderr: a live bar per stage on a terminal, one line per stage in a log.

:class:`StageReporter` implements :class:`workbench.diagnose._progress.DiagnoseProgress`. On a terminal each stage
gets a tqdm bar (counted stages show n/total and the unit just done) that a ticker thread redraws every second, so
the elapsed time keeps moving even while one long fit runs. When stderr is not a terminal (a log, a pipe) each stage
prints one line when it starts, ending in "…" (work under way); a line ending in "…" is what the
no-silence test accepts before a long gap. While a bar is shown, the plant's compile announcements are written
through the bar (``tqdm.write``) so they do not garble it.
"""

from __future__ import annotations

import os
import sys
import threading
from typing import Any, TextIO

#: seconds between redraws of a terminal bar (its elapsed-time field)
TICK_S = 1.0


def _terminal_sized(stream: TextIO) -> bool:
    """Whether the terminal reports its size (the bar then follows it); a pty nobody sized (0 columns, 0 rows) would
    get an empty, hidden bar, so it gets a fixed 100 x 24."""
    try:
        size = os.get_terminal_size(stream.fileno())
    except (OSError, ValueError, AttributeError):
        return False
    return size.columns > 0 and size.lines > 0


class StageReporter:
    """Stages of ``command`` on ``stream`` (default stderr): a bar on a terminal, a line per stage otherwise."""

    def __init__(self, command: str, stream: TextIO | None = None, tty: bool | None = None) -> None:
        self.command = command
        self.stream = stream if stream is not None else sys.stderr
        self.tty = bool(self.stream.isatty()) if tty is None else tty
        self._bar: Any = None
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._ticker: threading.Thread | None = None
        self._restore_announcer: Any = None

    # --- DiagnoseProgress ------------------------------------------------------------------------------------
    def stage(self, name: str, total: int | None = None, detail: str = "") -> None:
        count = f"{total} " if total is not None else ""
        if not self.tty:
            what = f"{name}: {count}candidates" if total is not None else name
            text = f"{self.command}: {what}" + (f" ({detail})" if detail else "") + " …"
            print(text, file=self.stream, flush=True)
            return
        from tqdm import tqdm

        with self._lock:
            if self._bar is not None:
                self._bar.close()
            sized = _terminal_sized(self.stream)
            counted = total is not None
            desc = f"{self.command}: {name}" + ("" if counted or not detail else f" ({detail})")
            self._bar = tqdm(total=total, desc=desc, unit="", file=self.stream, leave=False, dynamic_ncols=sized,
                             ncols=None if sized else 100, nrows=None if sized else 24, mininterval=0.2,
                             bar_format=None if counted else "{desc} … {elapsed}")
            if counted and detail:
                self._bar.set_postfix_str(detail, refresh=True)
        self._start_ticker()

    def advance(self, label: str = "") -> None:
        if not self.tty:
            return
        with self._lock:
            if self._bar is not None:
                if label:
                    self._bar.set_postfix_str(label, refresh=False)
                self._bar.update(1)

    # --- lifetime ----------------------------------------------------------------------------------------------
    def __enter__(self) -> StageReporter:
        if self.tty:
            from plant import kernel_cache

            self._restore_announcer = kernel_cache.set_announcer(self.write)
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def write(self, text: str) -> None:
        """A line on the stream that does not garble the bar."""
        if self.tty and self._bar is not None:
            from tqdm import tqdm

            with self._lock:
                tqdm.write(text, file=self.stream)
        else:
            print(text, file=self.stream, flush=True)

    def close(self) -> None:
        self._stop.set()
        if self._ticker is not None:
            self._ticker.join(timeout=2 * TICK_S)
            self._ticker = None
        with self._lock:
            if self._bar is not None:
                self._bar.close()
                self._bar = None
        if self._restore_announcer is not None:
            from plant import kernel_cache

            kernel_cache.set_announcer(self._restore_announcer)
            self._restore_announcer = None

    def _start_ticker(self) -> None:
        if self._ticker is not None:
            return
        self._stop = threading.Event()
        self._ticker = threading.Thread(target=self._tick, name="progress-ticker", daemon=True)
        self._ticker.start()

    def _tick(self) -> None:
        stop = self._stop
        while not stop.wait(TICK_S):
            with self._lock:
                if self._bar is not None:
                    self._bar.refresh()
