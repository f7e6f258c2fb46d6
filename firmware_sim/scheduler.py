"""The fixed-rate tick scheduler (100 Hz): virtual time or wall-clock pacing; the clock is injected.

The board logic never reads a clock: it gets the tick number (board time = tick / rate). The scheduler decides
*when* a tick runs:

* :class:`VirtualClock` — as fast as the machine allows, deterministic: the clock jumps to each deadline.
* :class:`WallClock` — real time: sleep until each deadline (coarse ``time.sleep``, then a short spin for the last
  ``spin_s``; no spin under a real-time policy), run the tick, measure.

Per tick ``k`` the deadline is ``start + k / rate``. The tick's *jitter* is its start minus its deadline; it *misses
its deadline* when it ends after the next deadline (the next tick then starts late — there is no catch-up burst and
no skipped tick: the board's time is its tick count). The step function learns whether the previous tick overran,
so the board can go SAFE after ``[tick] overrun_ticks`` in a row. :class:`TickStats` summarises jitter (mean, std,
p50, p99, max), busy time, deadline misses and the longest run of consecutive misses.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np


class Clock(Protocol):
    """Monotonic time source (s) that can wait."""

    def now(self) -> float: ...

    def sleep_until(self, t: float) -> None: ...


class VirtualClock:
    """Virtual time: ``sleep_until`` jumps; work takes no time. Deterministic."""

    def __init__(self, t0: float = 0.0) -> None:
        self.t = float(t0)

    def now(self) -> float:
        return self.t

    def sleep_until(self, t: float) -> None:
        if t > self.t:
            self.t = t


def running_real_time() -> bool:
    """Whether this process runs under a real-time scheduling policy (``chrt -f``/``-r``: SCHED_FIFO or SCHED_RR)."""
    try:
        return os.sched_getscheduler(0) in (os.SCHED_FIFO, os.SCHED_RR)
    except (AttributeError, OSError):  # not Linux, or not allowed to ask
        return False


#: the spin before a deadline at normal priority (a coarse sleep wakes up to ~1 ms late on a busy machine)
DEFAULT_SPIN_S = 0.0015


class WallClock:
    """``time.perf_counter``; sleeps coarsely, then spins for the last ``spin_s`` for a tight start.

    Under a real-time policy the default is no spin: the sleep itself is then precise, and a real-time thread
    that spins keeps every normal-priority thread of its core from running — among them the kernel workers that
    move pty bytes and the rig's own threads — so the board would starve the link it is waiting for (seen: two
    boards under ``chrt -f 10`` on 2 cores made no progress for 15 minutes).
    """

    def __init__(self, spin_s: float | None = None) -> None:
        self.spin_s = float(spin_s) if spin_s is not None else (0.0 if running_real_time() else DEFAULT_SPIN_S)

    def now(self) -> float:
        return time.perf_counter()

    def sleep_until(self, t: float) -> None:
        while True:
            remaining = t - time.perf_counter()
            if remaining <= 0:
                return
            if remaining > self.spin_s:
                time.sleep(remaining - self.spin_s)


@dataclass(frozen=True)
class TickStats:
    """What a paced (or virtual) run looked like. Times in s."""

    ticks: int
    rate: float  # Hz
    paced: bool
    deadline_misses: int
    max_consecutive_misses: int
    jitter_mean: float
    jitter_std: float
    jitter_p50: float
    jitter_p99: float
    jitter_max: float
    busy_mean: float  # mean tick duration
    busy_max: float
    elapsed: float  # clock time from the first deadline to the end of the last tick

    def as_dict(self) -> dict[str, float | int | bool]:
        return {"ticks": self.ticks, "rate_Hz": self.rate, "paced": self.paced,
                "deadline_misses": self.deadline_misses, "max_consecutive_misses": self.max_consecutive_misses,
                "jitter_mean_s": self.jitter_mean, "jitter_std_s": self.jitter_std, "jitter_p50_s": self.jitter_p50,
                "jitter_p99_s": self.jitter_p99, "jitter_max_s": self.jitter_max, "busy_mean_s": self.busy_mean,
                "busy_max_s": self.busy_max, "elapsed_s": self.elapsed}


#: step(k, overran_previous) -> True to stop after this tick
TickFunction = Callable[[int, bool], bool | None]
#: block(k, ticks_left) -> (ticks done from k on (1 .. ticks_left), stop after them), virtual time only
BlockFunction = Callable[[int, int], tuple[int, bool]]


class Scheduler:
    """Run ``step(k, overran_previous)`` at a fixed rate on an injected clock.

    With a :class:`VirtualClock` nothing waits and no wall time is read (jitter and misses are 0 by
    construction). With a :class:`WallClock` ticks are paced and measured.
    """

    def __init__(self, rate: float = 100.0, clock: Clock | None = None) -> None:
        if not rate > 0:
            raise ValueError(f"tick rate must be positive, got {rate!r}")
        self.rate = float(rate)
        self.period = 1.0 / self.rate
        self.clock: Clock = clock if clock is not None else VirtualClock()
        self.paced = not isinstance(self.clock, VirtualClock)
        self.consecutive_misses = 0
        self.stats: TickStats | None = None

    def run(self, n_ticks: int, step: TickFunction, first_tick: int = 0,
            progress: Callable[[int], None] | None = None) -> TickStats:
        """Run ticks ``first_tick .. first_tick + n_ticks - 1`` (or until ``step`` returns True)."""
        if not self.paced and type(self.clock) is VirtualClock:
            # virtual time, nothing to measure: one tick per block (the clock jumps to the last deadline at the end)
            return self.run_blocks(n_ticks, lambda k, _left: (1, bool(step(k, False))), first_tick, progress)
        return self._run_paced(int(n_ticks), step, first_tick, progress)

    def run_blocks(self, n_ticks: int, block: BlockFunction, first_tick: int = 0,
                   progress: Callable[[int], None] | None = None) -> TickStats:
        """Virtual time only: run ticks ``first_tick .. first_tick + n_ticks - 1`` as ``block(k, left)`` calls, each
        doing ticks ``k .. k + d - 1`` and returning ``(d, stop)`` for the ``1 <= d <= left`` it did (``left``: the
        ticks left) and whether to stop after them. The same ticks, in the same order, as :meth:`run` with a step
        per tick; ``progress(i)`` is called once per 256 ticks."""
        if self.paced or type(self.clock) is not VirtualClock:
            raise ValueError("run_blocks needs a virtual clock: a paced run ticks one deadline at a time")
        clock = self.clock
        n = int(n_ticks)
        start = clock.now()
        i = 0
        while i < n:
            d, stop = block(first_tick + i, n - i)
            if not 1 <= d <= n - i:
                raise ValueError(f"block at tick {first_tick + i} did {d} ticks (1..{n - i} allowed)")
            if progress is not None and ((i & 255) == 0 or (i >> 8) != ((i + d - 1) >> 8)):
                progress(i)
            i += d
            if stop:
                break
        self.consecutive_misses = 0
        if i:
            clock.sleep_until(start + (i - 1) * self.period)
        stats = TickStats(i, self.rate, False, 0, 0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, float(clock.now() - start))
        self.stats = stats
        return stats

    def _run_paced(self, n: int, step: TickFunction, first_tick: int, progress: Callable[[int], None] | None
                   ) -> TickStats:
        clock = self.clock
        period = self.period
        start = clock.now()
        jitter = np.zeros(n if self.paced else 0)  # s, filled only when paced
        busy = np.zeros(n if self.paced else 0)
        misses = 0
        run = 0
        worst_run = 0
        overran = False
        done = 0
        for i in range(n):
            k = first_tick + i
            deadline = start + i * period
            if self.paced:
                clock.sleep_until(deadline)
                t0 = clock.now()
                stop = step(k, overran)
                t1 = clock.now()
                jitter[i] = t0 - deadline
                busy[i] = t1 - t0
                overran = t1 > deadline + period
            else:
                clock.sleep_until(deadline)
                stop = step(k, False)
            if overran:
                misses += 1
                run += 1
                worst_run = max(worst_run, run)
            else:
                run = 0
            self.consecutive_misses = run
            done = i + 1
            if progress is not None and (i & 255) == 0:
                progress(i)
            if stop:
                break
        elapsed = clock.now() - start
        if self.paced and done:
            j = jitter[:done]
            b = busy[:done]
            stats = TickStats(done, self.rate, True, misses, worst_run, float(j.mean()), float(j.std()),
                              float(np.percentile(j, 50)), float(np.percentile(j, 99)), float(j.max()),
                              float(b.mean()), float(b.max()), float(elapsed))
        else:
            stats = TickStats(done, self.rate, self.paced, 0, 0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, float(elapsed))
        self.stats = stats
        return stats


class TickScheduler(Protocol):
    """What the board's runner needs of a scheduler: a :class:`Scheduler`, or a :class:`SchedulerWrapper` of one."""

    rate: float  # Hz
    period: float  # s
    paced: bool
    clock: Clock

    def run(self, n_ticks: int, step: TickFunction, first_tick: int = 0,
            progress: Callable[[int], None] | None = None) -> TickStats: ...

    def run_blocks(self, n_ticks: int, block: BlockFunction, first_tick: int = 0,
                   progress: Callable[[int], None] | None = None) -> TickStats: ...


class SchedulerWrapper:
    """A scheduler that runs the wrapped one's ticks and calls :meth:`after_ticks` after each tick (and each block
    of quiet ticks), in the board's own thread; its answer can end the run after that tick. Subclasses define
    :meth:`after_ticks` (e.g. ``shm run``'s stop on a signal, the live page's publication). Wrappers nest. It
    defines ``run_blocks`` itself (not by forwarding), so a run with quiet spans keeps the wrapper's condition."""

    def __init__(self, inner: TickScheduler) -> None:
        self._inner = inner
        self.rate = inner.rate
        self.period = inner.period
        self.paced = inner.paced
        self.clock = inner.clock

    @property
    def stats(self) -> TickStats | None:
        """The wrapped scheduler's statistics of its last run."""
        return getattr(self._inner, "stats", None)

    def after_ticks(self, k: int, overran: bool, ticks: int) -> bool:
        """After tick ``k``, the last of ``ticks`` ticks done at once (``overran``: tick ``k`` missed its deadline);
        True to stop the run there."""
        raise NotImplementedError

    def run(self, n_ticks: int, step: TickFunction, first_tick: int = 0,
            progress: Callable[[int], None] | None = None) -> TickStats:
        after = self.after_ticks

        def wrapped(k: int, overran: bool) -> bool:
            stop = bool(step(k, overran))
            return after(k, overran, 1) or stop

        return self._inner.run(n_ticks, wrapped, first_tick=first_tick, progress=progress)

    def run_blocks(self, n_ticks: int, block: BlockFunction, first_tick: int = 0,
                   progress: Callable[[int], None] | None = None) -> TickStats:
        after = self.after_ticks

        def wrapped(k: int, left: int) -> tuple[int, bool]:
            d, stop = block(k, left)
            return d, after(k + d - 1, False, d) or bool(stop)

        return self._inner.run_blocks(n_ticks, wrapped, first_tick=first_tick, progress=progress)
