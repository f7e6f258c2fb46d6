"""Visit records written beside a paced run, not inside its ticks (issue 29, point 4).

Writing an MBIT's record (``studies.health.visit_records.VisitRecordWriter``: 2 201 rows formatted, validated and
written, then linked in the log) takes 15–40 ms on a loaded machine. Done in the tick that ends the MBIT, that is
several missed tick deadlines in a row — enough for SAFE (overrun) and an aborted visit on a desk running other work.
:class:`BackgroundRecorder` hands the events the writer needs to a thread of its own, in order, and the tick goes on.

* The writer is built in the thread (its SQLite connection belongs there); a failure to build it is raised at once.
* A failing record is remembered (:attr:`failure`: the first ``"Type: message"``) and said once on stderr; the
  writer goes on with the next events. :meth:`close` waits until every queued record is written.
* While it runs, the interpreter's thread switch interval is 0.5 ms (restored at :meth:`close`): the tick's thread,
  waking for its deadline or its reply, then waits at most that long for the writer to yield (CPython's default
  is 5 ms).
"""

from __future__ import annotations

import queue
import sys
import threading
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from firmware_sim.events import BoardEvent

#: the events a visit record writer acts on (everything else is not queued)
RECORD_EVENTS = frozenset({"mbit_start", "mbit_record", "mbit_result"})
_SWITCH_INTERVAL_S = 5e-4


class BackgroundRecorder:
    """Feed ``factory()``'s recorder (a callable taking board events, with ``close()``) from a thread of its own."""

    def __init__(self, factory: Callable[[], Any], name: str = "visit records") -> None:
        self.name = name
        self.failure: str | None = None
        self._queue: queue.SimpleQueue[Any] = queue.SimpleQueue()
        self._ready = threading.Event()
        self._init_error: BaseException | None = None
        self._inner: Any = None
        self._switch = sys.getswitchinterval()
        self._thread = threading.Thread(target=self._main, args=(factory,), name="visit-records", daemon=True)
        self._thread.start()
        self._ready.wait()
        if self._init_error is not None:
            raise self._init_error
        sys.setswitchinterval(min(self._switch, _SWITCH_INTERVAL_S))

    def __call__(self, ev: BoardEvent) -> None:
        if ev.kind in RECORD_EVENTS:
            self._queue.put(ev)

    def _main(self, factory: Callable[[], Any]) -> None:
        try:
            self._inner = factory()
        except BaseException as exc:  # handed to the constructor's caller
            self._init_error = exc
            self._ready.set()
            return
        self._ready.set()
        while True:
            ev = self._queue.get()
            if ev is None:
                break
            try:
                self._inner(ev)
            except Exception as exc:  # a record that cannot be written is a failed step, never the end of the run
                why = f"{type(exc).__name__}: {' '.join(str(exc).split())}"
                if self.failure is None:
                    self.failure = why
                    print(f"shm run: could not write a visit record ({why}); the run goes on", file=sys.stderr)
        try:
            self._inner.close()
        except Exception:
            pass

    def close(self, timeout_s: float = 120.0) -> None:
        """Write what is queued, then stop the thread and restore the switch interval."""
        if self._thread.is_alive():
            self._queue.put(None)
            self._thread.join(timeout_s)
        sys.setswitchinterval(self._switch)
        if self._thread.is_alive() and self.failure is None:
            self.failure = f"TimeoutError: the visit records were not written within {timeout_s:g} s"
