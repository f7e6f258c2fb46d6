"""Run the board against a link on a scheduler: the firmware's main loop, plus a trace for plots.

Per tick ``k`` (``k = 0 .. n-1``): send the command decided at the previous tick through the link
(``link.exchange``; a :class:`~drivers.link.LinkError` becomes "no sample"), hand the sample to
``board.tick(sample, k + 1)`` (board time ``(k + 1) / rate`` — the end of the interval the command covered), write
its events to the sink (each committed before the next one; a ``on_event`` callback, e.g. the timeline printer,
sees an event only after it is stored) and keep the next command. Operator re-arms scheduled by time are handed to
the board at the first tick at or after their time. Nothing escapes the loop except a bug in the board itself
or an interrupt (``KeyboardInterrupt``/``SystemExit``, e.g. SIGTERM turned into one by the CLI); whatever ends
the run, a zero demand is sent through the link before ``run`` returns or re-raises (:meth:`BoardRunner.command_zero`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from drivers.link import ActuatorCommand, Link, LinkError
from firmware_sim.board import Board
from firmware_sim.events import BoardEvent, EventSink
from firmware_sim.regimes import REGIME_CODES
from firmware_sim.scheduler import Scheduler, TickStats

#: trace columns (unit in the name)
TRACE_COLUMNS: tuple[str, ...] = ("time_s", "regime_code", "z3_m", "z3_model_m", "z0dd_m_s2", "v_patch_V",
                                  "v_battery_V", "v_ch1_V", "v_ch2_V", "monitor_count", "board_current_A", "link_ok")


class Trace:
    """Per-tick record of what the board saw and did (``every`` keeps one tick in ``every``).

    Rows are kept as tuples (one list append per tick: about 6x cheaper than writing a preallocated array row
    element by element) and turned into an array when read (``data``, ``columns()``)."""

    def __init__(self, n_ticks: int, every: int = 1) -> None:
        self.every = max(1, int(every))
        self.rows: list[tuple[float, ...]] = []
        self._array: np.ndarray | None = None

    @property
    def n(self) -> int:
        return len(self.rows)

    @property
    def data(self) -> np.ndarray:
        """The rows so far, shape (n, len(TRACE_COLUMNS)) (NaN where a value did not exist)."""
        a = self._array
        if a is None or a.shape[0] != len(self.rows):
            a = self._array = np.array(self.rows, dtype=float).reshape(len(self.rows), len(TRACE_COLUMNS))
        return a

    def columns(self) -> dict[str, np.ndarray]:
        data = self.data
        return {name: data[:, i] for i, name in enumerate(TRACE_COLUMNS)}


@dataclass
class RunResult:
    ticks: int
    duration_s: float  # board time covered
    wall_s: float  # wall-clock time of the loop
    stats: TickStats
    events: list[BoardEvent] = field(default_factory=list)
    trace: Trace | None = None

    @property
    def realtime_factor(self) -> float:
        """Board time per wall-clock time (> 1: faster than real time)."""
        return self.duration_s / self.wall_s if self.wall_s > 0 else math.inf


class BoardRunner:
    """The board's main loop against ``link`` on ``scheduler`` (virtual time by default)."""

    def __init__(self, board: Board, link: Link, *, sink: EventSink | None = None, scheduler: Scheduler | None = None,
                 rearm_times: Sequence[float] = (), on_event: Callable[[BoardEvent], None] | None = None,
                 trace_every: int | None = 1) -> None:
        self.board = board
        self.link = link
        self.sink = sink
        self.scheduler = scheduler if scheduler is not None else Scheduler(board.cfg.tick_rate)
        if abs(self.scheduler.rate - board.cfg.tick_rate) > 1e-9:
            raise ValueError(f"scheduler rate {self.scheduler.rate:g} Hz differs from the board's tick rate "
                             f"{board.cfg.tick_rate:g} Hz")
        if self.scheduler.paced:  # paced on the wall clock: the rig may be a real-time one (one tick of link delay)
            board.set_realtime_rig(True)
        self.rearm_times = sorted(float(t) for t in rearm_times)
        self.on_event = on_event
        self.trace_every = trace_every
        self.events: list[BoardEvent] = []
        self.command = ActuatorCommand(0, 0.0, 0.0, board.budget.current(board.regime))
        self.zero_sent = False  #: the run ended with a zero demand answered by the rig

    def _emit(self, ev: BoardEvent) -> None:
        if self.sink is not None:
            self.sink.write(ev)
        self.events.append(ev)
        if self.on_event is not None:
            self.on_event(ev)

    def run(self, duration_s: float, progress: Callable[[int], None] | None = None) -> RunResult:
        """Run ``duration_s`` seconds of board time (a whole number of ticks, rounded up)."""
        board = self.board
        period = board.period
        n = math.ceil(duration_s / period - 1e-9)
        trace = Trace(n, self.trace_every) if self.trace_every else None
        rearms = list(self.rearm_times)
        link = self.link
        emit = self._emit
        rows_append = trace.rows.append if trace is not None else None
        nan = math.nan
        every = trace.every if trace is not None else 0
        codes = REGIME_CODES

        def step(k: int, overran: bool) -> None:
            cmd = self.command
            try:
                sample = link.exchange(cmd)
                err = ""
            except LinkError as exc:
                sample = None
                err = str(exc) or type(exc).__name__
            kk = k + 1
            if rearms and kk * period >= rearms[0] - 1e-12:
                rearms.pop(0)
                board.request_rearm()
            res = board.tick(sample, kk, overrun=overran, link_error=err)
            for ev in res.events:
                emit(ev)
            self.command = res.command
            if rows_append is not None and kk % every == 0:
                mnt = board.maintenance
                z3m, mcount = (mnt.z3_model, mnt.monitor_count) if mnt.active else (nan, nan)
                if sample is not None:
                    rows_append((kk * period, codes[res.regime], sample.z3, z3m, sample.z0dd, sample.v_patch,
                                 sample.v_battery, cmd.v_ch1, cmd.v_ch2, mcount, cmd.board_current, 1.0))
                else:
                    rows_append((kk * period, codes[res.regime], nan, z3m, nan, nan, nan, cmd.v_ch1, cmd.v_ch2,
                                 mcount, cmd.board_current, 0.0))

        t0 = time.perf_counter()
        try:
            stats = self.scheduler.run(n, step, progress=progress)
        finally:  # every exit — the end, an exception, Ctrl-C / SIGTERM mid-tick — leaves the amplifier at 0 V
            self.zero_sent = self.command_zero()
        wall = time.perf_counter() - t0
        for ev in board.close(stats.ticks):
            emit(ev)
        return RunResult(stats.ticks, stats.ticks * period, wall, stats, self.events, trace)

    def command_zero(self, attempts: int = 3) -> bool:
        """Send a zero demand (both channels 0 V) through the link; True once the rig has answered it.

        Called when the run ends for any reason, before the caller closes the link; never raises (a link that is
        down, or a second Ctrl-C, leaves the rig's own watchdog to zero the amplifier after 0.1 s)."""
        board = self.board
        seq = (self.command.seq + 1) & 0xFFFFFFFF
        zero = ActuatorCommand(seq, 0.0, 0.0, board.budget.current(board.regime))
        for _ in range(max(1, attempts)):
            try:
                self.link.exchange(zero)
                self.command = zero
                return True
            except LinkError:
                continue
            except BaseException:  # a second interrupt while shutting down: the rig watchdog remains
                return False
        return False
