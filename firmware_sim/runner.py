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
from drivers.quiet_span import QuietSpan, QuietSpanSource
from firmware_sim.board import Board
from firmware_sim.events import BoardEvent, EventSink
from firmware_sim.regimes import REGIME_CODES
from firmware_sim.scheduler import BlockFunction, Scheduler, TickFunction, TickScheduler, TickStats, VirtualClock

#: trace columns (unit in the name)
TRACE_COLUMNS: tuple[str, ...] = ("time_s", "regime_code", "z3_m", "z3_model_m", "z0dd_m_s2", "v_patch_V",
                                  "v_battery_V", "v_ch1_V", "v_ch2_V", "monitor_count", "board_current_A", "link_ok")


class Trace:
    """Per-tick record of what the board saw and did (``every`` keeps one tick in ``every``).

    Rows of single ticks are kept as tuples (one list append per tick: about 6x cheaper than writing a preallocated
    array row element by element), the rows of a quiet span as one array (:meth:`add_block`); both are turned into
    one array, in tick order, when read (``data``, ``columns()``)."""

    def __init__(self, n_ticks: int, every: int = 1) -> None:
        self.every = max(1, int(every))
        self.rows: list[tuple[float, ...]] = []  # single-tick rows since the last block (appended by the runner)
        self._parts: list[np.ndarray | list[tuple[float, ...]]] = []  # everything before ``rows``, in order
        self._count = 0  # rows in _parts
        self._array: np.ndarray | None = None

    @property
    def n(self) -> int:
        return self._count + len(self.rows)

    def add_block(self, rows: np.ndarray) -> None:
        """Append the rows of several ticks at once (shape (k, len(TRACE_COLUMNS))); ``rows`` stays the same list
        (emptied), so a bound ``rows.append`` keeps appending after the block."""
        if self.rows:
            self._parts.append(self.rows.copy())
            self._count += len(self.rows)
            self.rows.clear()
        self._parts.append(rows)
        self._count += rows.shape[0]

    @property
    def data(self) -> np.ndarray:
        """The rows so far, shape (n, len(TRACE_COLUMNS)) (NaN where a value did not exist)."""
        a = self._array
        n = self.n
        if a is None or a.shape[0] != n:
            width = len(TRACE_COLUMNS)
            parts = [p if isinstance(p, np.ndarray) else np.array(p, dtype=float).reshape(len(p), width)
                     for p in (*self._parts, self.rows) if len(p)]
            a = self._array = np.concatenate(parts) if parts else np.empty((0, width))
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


def _ticks_before_rearm(k: int, limit: int, rearms: list[float], period: float) -> int:
    """How many of the ``limit`` ticks from ``k`` on may run as a quiet span: all, or those before the tick that hands
    the next re-arm to the board (the first ``kk = k + 1 + j`` with ``kk * period >= rearms[0]``)."""
    if not rearms:
        return limit
    r = rearms[0] - 1e-12
    j = min(limit, max(0, int(r / period) - k - 2))  # a few ticks short of it, then exactly
    while j > 0 and (k + j) * period >= r:
        j -= 1
    while j < limit and (k + 1 + j) * period < r:
        j += 1
    return j


class BoardRunner:
    """The board's main loop against ``link`` on ``scheduler`` (virtual time by default)."""

    def __init__(self, board: Board, link: Link, *, sink: EventSink | None = None,
                 scheduler: TickScheduler | None = None,
                 rearm_times: Sequence[float] = (), on_event: Callable[[BoardEvent], None] | None = None,
                 trace_every: int | None = 1, quiet_spans: bool = True) -> None:
        self.board = board
        self.link = link
        self.sink = sink
        self.scheduler: TickScheduler = scheduler if scheduler is not None else Scheduler(board.cfg.tick_rate)
        if abs(self.scheduler.rate - board.cfg.tick_rate) > 1e-9:
            raise ValueError(f"scheduler rate {self.scheduler.rate:g} Hz differs from the board's tick rate "
                             f"{board.cfg.tick_rate:g} Hz")
        if self.scheduler.paced:  # paced on the wall clock: the rig may be a real-time one (one tick of link delay)
            board.set_realtime_rig(True)
            # the visit's nominal reference now, not in the tick that starts a visit (tens of ms on a loaded
            # machine: missed deadlines in a row, SAFE for an overrun)
            board.maintenance.prepare()
        self.rearm_times = sorted(float(t) for t in rearm_times)
        self.on_event = on_event
        self.trace_every = trace_every
        self.quiet_spans = quiet_spans
        self.events: list[BoardEvent] = []
        self.command = ActuatorCommand(0, 0.0, 0.0, board.budget.current(board.regime))
        self.zero_sent = False  #: the run ended with a zero demand answered by the rig
        self.lost_exchanges = 0  #: ticks whose exchange failed (no sample: a lost reply, a link down)

    def _emit(self, ev: BoardEvent) -> None:
        if self.sink is not None:
            self.sink.write(ev)
        self.events.append(ev)
        if self.on_event is not None:
            self.on_event(ev)

    def run(self, duration_s: float, progress: Callable[[int], None] | None = None) -> RunResult:
        """Run ``duration_s`` seconds of board time (a whole number of ticks, rounded up)."""
        board = self.board
        n = math.ceil(duration_s / board.period - 1e-9)
        trace = Trace(n, self.trace_every) if self.trace_every else None
        rearms = list(self.rearm_times)  # operator re-arms still to hand to the board (s), each taken once
        step = self._tick_function(trace, rearms)
        spans = self._quiet_span_source()
        t0 = time.perf_counter()
        try:
            if spans is not None:
                block = self._block_function(spans, step, trace, rearms)
                stats = self.scheduler.run_blocks(n, block, progress=progress)
            else:
                stats = self.scheduler.run(n, step, progress=progress)
        finally:  # every exit — the end, an exception, Ctrl-C / SIGTERM mid-tick — leaves the amplifier at 0 V
            self.zero_sent = self.command_zero()
        wall = time.perf_counter() - t0
        for ev in board.close(stats.ticks):
            self._emit(ev)
        return RunResult(stats.ticks, stats.ticks * board.period, wall, stats, self.events, trace)

    def _tick_function(self, trace: Trace | None, rearms: list[float]) -> TickFunction:
        """``step(k, overran)``: tick ``k`` — the command decided at the previous tick through the link, the sample
        to ``board.tick(sample, k + 1)`` (with a re-arm due by then), its events emitted, its trace row kept."""
        board = self.board
        period = board.period
        link = self.link
        emit = self._emit
        rows_append = trace.rows.append if trace is not None else None
        every = trace.every if trace is not None else 0
        nan = math.nan
        codes = REGIME_CODES

        def step(k: int, overran: bool) -> None:
            cmd = self.command
            try:
                sample = link.exchange(cmd)
                err = ""
            except LinkError as exc:
                sample = None
                err = str(exc) or type(exc).__name__
                self.lost_exchanges += 1
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

        return step

    def _block_function(self, spans: QuietSpanSource, step: TickFunction, trace: Trace | None,
                        rearms: list[float]) -> BlockFunction:
        """``block(k, left)`` against an in-process rig: the quiet ticks from ``k`` on at once (drivers.quiet_span),
        else the one tick ``k`` by ``step``; never asks to stop (a scheduler wrapper may: shm run's on a signal)."""
        board = self.board
        period = board.period
        every = trace.every if trace is not None else 0
        codes = REGIME_CODES

        def block(k: int, left: int) -> tuple[int, bool]:
            cmd = self.command
            if (left > 1 and board.can_take_quiet() and cmd.v_ch1 == 0.0 and cmd.v_ch2 == 0.0
                    and cmd.board_current == board.quiet_command_current()):
                limit = _ticks_before_rearm(k, left, rearms, period)
                span = spans.peek_quiet(cmd, limit) if limit > 1 else None
                if span is not None:
                    m, command = board.take_quiet(k + 1, span)
                    if m and command is not None:
                        spans.commit_quiet(span, m)
                        self.command = command
                        if trace is not None:
                            trace.add_block(self._trace_rows(k, m, every, period, codes[board.regime], cmd, command,
                                                             span))
                        return m, False
            step(k, False)
            return 1, False

        return block

    def _quiet_span_source(self) -> QuietSpanSource | None:
        """The link, if quiet stretches may be exchanged in one call: virtual time, a scheduler whose class defines
        ``run_blocks`` (a wrapper that only forwards it, e.g. to add a stop condition to ``run``, would lose that
        condition), an in-process rig that offers quiet spans, ``quiet_spans`` on. A paced run, and any serial or
        Modbus link, ticks one by one."""
        sched = self.scheduler
        if (not self.quiet_spans or sched.paced or type(sched.clock) is not VirtualClock
                or getattr(type(sched), "run_blocks", None) is None):  # a wrapper must define it, not forward it
            return None
        link = self.link
        return link if isinstance(link, QuietSpanSource) else None

    @staticmethod
    def _trace_rows(k: int, m: int, every: int, period: float, regime_code: int, first: ActuatorCommand,
                    command: ActuatorCommand, span: QuietSpan) -> np.ndarray:
        """The trace rows of the quiet ticks ``k + 1 .. k + m`` (exchanged with ``first``, then ``command``'s
        demand), as the per-tick loop writes them."""
        i0 = (-(k + 1)) % every
        sel = slice(i0, m, every)
        idx = np.arange(i0, m, every)
        rows = np.empty((idx.shape[0], len(TRACE_COLUMNS)))
        rows[:, 0] = (idx + (k + 1)) * period
        rows[:, 1] = regime_code
        rows[:, 2] = span.z3[sel]
        rows[:, 3] = math.nan
        rows[:, 4] = span.z0dd[sel]
        rows[:, 5] = span.v_patch[sel]
        rows[:, 6] = span.v_battery[sel]
        rows[:, 7] = command.v_ch1
        rows[:, 8] = command.v_ch2
        rows[:, 9] = math.nan
        rows[:, 10] = command.board_current
        rows[:, 11] = 1.0
        if i0 == 0 and rows.shape[0]:  # the first tick's row carries the command it was exchanged with
            rows[0, 7], rows[0, 8], rows[0, 10] = first.v_ch1, first.v_ch2, first.board_current
        return rows

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
