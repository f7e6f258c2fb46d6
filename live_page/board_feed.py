"""The board's side of the live page: read the board after each tick, publish a snapshot at most 20 times a second.

Three small pieces wrap what ``shm run`` already has, so the firmware itself knows nothing of the page:

* :class:`PublishingScheduler` wraps the run's scheduler; after every tick (or quiet span) it calls
  :meth:`BoardFeed.after_tick` in the board's own thread. That call reads a few attributes and, during an MBIT, keeps
  the tick's tip deflections (list appends); only when the publication period has passed on the wall clock does it
  build a new :class:`~live_page.snapshot.Snapshot` and replace the slot's reference. Nothing there waits for a lock
  or for the page: a page that is slow, closed or never opened costs the tick nothing more.
* :class:`TimedLink` wraps the link and times each exchange into a fixed ring (the round trip p50/p99 of the last
  :data:`RTT_WINDOW` exchanges) and counts the exchanges that brought no sample.
* :meth:`BoardFeed.on_event` takes the board's events (after they are stored in the usage log) for the event log,
  the regime timeline and the verdicts.

The state of charge is an estimate: the measured battery voltage read on the cell's open-circuit-voltage curve
(``board_config.battery``), which is what a board that measures only its voltage can know.
"""

from __future__ import annotations

import contextlib
import math
import time
from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np

from drivers.link import ActuatorCommand, LinkError, RigSample
from firmware_sim.scheduler import SchedulerWrapper, TickScheduler
from live_page.snapshot import (
    MAX_CHUNKS,
    MAX_EVENTS,
    MAX_REGIMES,
    Chunk,
    LinkHealth,
    Snapshot,
    SnapshotSlot,
    bounded,
)
from live_page.soc import SocEstimate
from studies.board_run.timeline import format_event

#: at most this many publications per second (wall clock)
PUBLISH_HZ = 20.0
#: exchanges whose round trip the p50/p99 cover
RTT_WINDOW = 1000


class TimedLink:
    """A link that times each exchange (s, ``time.perf_counter``) into a ring of :data:`RTT_WINDOW` and counts the
    exchanges that raised :class:`~drivers.link.LinkError`; everything else is the wrapped link's."""

    def __init__(self, inner: Any) -> None:
        self._inner = inner
        self.rtt_s = [math.nan] * RTT_WINDOW
        self.timed = 0
        self.misses = 0

    def exchange(self, command: ActuatorCommand) -> RigSample:
        t0 = time.perf_counter()
        try:
            return self._inner.exchange(command)
        except LinkError:
            self.misses += 1
            raise
        finally:
            self.rtt_s[self.timed % RTT_WINDOW] = time.perf_counter() - t0
            self.timed += 1

    def rtt_percentiles(self) -> tuple[float | None, float | None]:
        """(p50, p99) of the round trips in the ring (s); None before the first exchange."""
        n = min(self.timed, RTT_WINDOW)
        if n == 0:
            return None, None
        a = np.asarray(self.rtt_s[:n] if n < RTT_WINDOW else self.rtt_s)
        p50, p99 = np.percentile(a, (50, 99))
        return float(p50), float(p99)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._inner, name)


class BoardFeed:
    """Reads ``board`` after each tick and publishes into ``slot`` (see the module docstring)."""

    def __init__(self, slot: SnapshotSlot, board: Any, *, title: str, planned_s: float, paced: bool,
                 link: TimedLink | None = None, soc: SocEstimate | None = None,
                 clock: Callable[[], float] = time.perf_counter, publish_hz: float = PUBLISH_HZ) -> None:
        self.slot = slot
        self.board = board
        self.link = link
        self.soc = soc if soc is not None else SocEstimate()
        self._clock = clock
        self._period = 1.0 / publish_hz
        self.broken = ""  #: why the feed stopped ('' while it works)
        self._next = 0.0
        self._tick_s = board.period
        settings = board.maintenance.monitor.settings
        self._monitor = board.maintenance.monitor
        self._ticks = 0
        self._deadline_misses = 0
        self._chunk_index = 0
        self._event_index = 0
        self._mbit_id = 0
        self._mbit_label: str | None = None
        self._rows_t: list[float] = []
        self._rows_z: list[float] = []
        self._rows_zm: list[float] = []
        self._pending_events: list[tuple[int, str]] = []
        self._regimes: list[tuple[float, str]] = []
        self._verdicts: list[str] = []
        self._last_regime = board.regime.value
        self._regime_since = 0.0
        slot.publish(Snapshot(
            source="board", title=title, planned_s=planned_s, paced=paced, regime=self._last_regime,
            regime_since_s=0.0, regimes=((0.0, self._last_regime),), count_max=settings.count_max,
            eps_th=settings.eps_th, soc_note=self.soc.note))

    # --- the board's thread ------------------------------------------------------------------------------
    def on_event(self, ev: Any) -> None:
        """A board event (already in the usage log): the event log, regime timeline and verdicts."""
        if self.broken or ev.kind == "telemetry" or ev.kind == "mbit_record":
            return
        try:
            self._take_event(ev)
        except Exception as exc:  # the page stops; the board's run never does
            self._break(exc)

    def _take_event(self, ev: Any) -> None:
        line = format_event(ev)
        if line is not None:
            self._pending_events.append((self._event_index, line.strip()))
            self._event_index += 1
        d = ev.data
        if ev.kind == "regime_change":
            self._regimes.append((ev.time, str(d["to_regime"])))
        elif ev.kind == "mbit_start":
            self._mbit_id += 1
            self._mbit_label = str(d["label"])
        elif ev.kind == "mbit_result":
            self._verdicts.append(f"{d['label']} {d['verdict']}")
        elif ev.kind == "maintenance_verdict":
            self._verdicts.append(f"MAINTENANCE {d['verdict']}")

    def after_tick(self, k: int, overran: bool = False, ticks: int = 1) -> None:
        """After board tick ``k`` (the last of ``ticks`` ticks done at once): keep an MBIT's row, publish if due.
        Never raises: a failure of the page's feed stops the page (it says why), not the board."""
        if self.broken:
            return
        try:
            self._after_tick(k, overran, ticks)
        except Exception as exc:
            self._break(exc)

    def _break(self, exc: Exception) -> None:
        """The feed failed: publish why (once) and publish nothing more."""
        self.broken = f"{type(exc).__name__}: {exc}"
        with contextlib.suppress(Exception):
            prev = self.slot.latest()
            self.slot.publish(replace(prev, version=prev.version + 1, status="page stopped", extra=(
                *prev.extra, ("live page stopped (the board runs on)", self.broken))))

    def _after_tick(self, k: int, overran: bool, ticks: int) -> None:
        self._ticks += ticks
        if overran:
            self._deadline_misses += 1
        mnt = self.board.maintenance
        if mnt.active and self._mbit_label is not None and mnt.current == self._mbit_label:
            sample = self.board.last_sample
            self._rows_t.append((k + 1) * self._tick_s)
            self._rows_z.append(sample.z3 if sample is not None else math.nan)
            self._rows_zm.append(mnt.z3_model)
        now = self._clock()
        if now >= self._next:
            self._next = now + self._period
            self.publish()

    def publish(self, **final: Any) -> Snapshot:
        """Build the snapshot of now from the previous one and store it (``final``: fields of the last one)."""
        prev = self.slot.latest()
        board = self.board
        t_now = self._ticks * self._tick_s
        sample = board.last_sample
        v_batt = float(sample.v_battery) if sample is not None else None
        soc = self.soc.soc(v_batt)
        mnt = board.maintenance
        state = self._monitor.state
        rtt50, rtt99 = self.link.rtt_percentiles() if self.link is not None else (None, None)
        chunk = self._take_chunk(t_now, v_batt, soc, mnt.monitor_count if mnt.active else None, rtt99)
        regimes, self._regimes = tuple(self._regimes), []
        regime = board.regime.value
        if regime != self._last_regime:
            self._last_regime = regime
            self._regime_since = regimes[-1][0] if regimes else t_now
        events, self._pending_events = tuple(self._pending_events), []
        link = LinkHealth(
            exchanges=self._ticks, misses=self.link.misses if self.link is not None else 0, rtt_p50_s=rtt50,
            rtt_p99_s=rtt99, incidents=int(board.incidents), deadline_misses=self._deadline_misses,
            counters=tuple(sorted((str(k), int(v)) for k, v in (getattr(self.link, "stats", None) or {}).items())))
        snap = replace(
            prev, version=prev.version + 1, board_time_s=t_now, regime=regime, regime_since_s=self._regime_since,
            regimes=bounded(prev.regimes, regimes, MAX_REGIMES), v_battery_V=v_batt, soc=soc,
            monitor_count=mnt.monitor_count, fault_latched=bool(state.fault) if self._mbit_id else False,
            maintenance=mnt.current if mnt.active else None, mbit_id=self._mbit_id, mbit_label=self._mbit_label,
            mbit_max_eps=state.max_eps if self._mbit_id else None,
            mbit_max_count=state.max_count if self._mbit_id else None, verdicts=tuple(self._verdicts),
            link=link, chunks=bounded(prev.chunks, (chunk,), MAX_CHUNKS),
            events=bounded(prev.events, events, MAX_EVENTS), **final)
        self.slot.publish(snap)
        return snap

    def _take_chunk(self, t_now: float, v_batt: float | None, soc: float | None, count: int | None,
                    rtt99: float | None) -> Chunk:
        """The chunk of this publication: its slow point and the MBIT rows kept since the last one."""
        rows_t, rows_z, rows_zm = self._rows_t, self._rows_z, self._rows_zm
        eps: tuple[float, ...] = ()
        if rows_t:
            err = self._monitor.error
            eps = tuple(err(zm, z) for zm, z in zip(rows_zm, rows_z, strict=True))
            self._rows_t, self._rows_z, self._rows_zm = [], [], []
        chunk = Chunk(self._chunk_index, t_now, v_batt, soc, count, rtt99, self._mbit_id, tuple(rows_t),
                      tuple(rows_z), tuple(rows_zm), eps)
        self._chunk_index += 1
        return chunk

    def finish(self, status: str, report: str | None) -> Snapshot:
        """The run has ended: the last snapshot, kept by the page (``report``: its URL path, if written)."""
        if self.broken:
            prev = self.slot.latest()
            snap = replace(prev, version=prev.version + 1, finished=True, status=status, report=report)
            self.slot.publish(snap)
            return snap
        return self.publish(finished=True, status=status, report=report)


class PublishingScheduler(SchedulerWrapper):
    """A scheduler that calls ``feed.after_tick`` after each tick (and quiet span) of the wrapped one."""

    def __init__(self, inner: TickScheduler, feed: BoardFeed) -> None:
        super().__init__(inner)
        self._feed = feed

    def after_ticks(self, k: int, overran: bool, ticks: int) -> bool:
        self._feed.after_tick(k, overran, ticks)
        return False
