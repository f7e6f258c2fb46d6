"""The rig host: owns one :class:`drivers.RigEndpoint`, runs its clock, and publishes snapshots for the servers.

Two clock modes:

``realtime`` (default)
    A dedicated thread advances the rig every ``dt`` seconds of wall-clock time (100 Hz). A command that
    arrived since the previous tick is applied at the start of the tick (the latest one wins: zero-order
    hold, as the CompactRIO loop does); the rig then advances and an immutable :class:`Snapshot` is
    published. The servers never touch the endpoint: they post commands to a mailbox and answer from the
    latest snapshot, so a request never waits for the physics and requests faster than the tick cause no
    queue growth. With ``start="first-command"`` the rig clock stands still until the board's first command
    arrives, so a scenario's time 0 is the moment the board connects. Deadline misses and tick lateness are
    counted (:class:`PacingStats`).

``lockstep``
    No clock thread: every command advances the rig by exactly one ``dt`` — apply, advance, sample, the
    in-process link's order (``drivers.sim_link.InProcessLink``). The board then runs in virtual time against
    a rig across a real port, so a run over a link is reproducible and comparable with the in-process link.

A new board run — its command counter (the board's tick, ``ActuatorCommand.seq``) starts again below the last one
seen; a link that reconnects in the middle of a run keeps counting up — is counted (``board_runs``). In lockstep mode,
with a ``restart`` factory (``shm hil serve`` gives one), the rig then starts again as it was built: the scenario
plays from t = 0 for every board run, as the in-process link does, so consecutive board runs against one served stub
each get their maintenance visit and verdict. A real-time rig plays its scenario once, on the wall clock; a new board
run is logged as an incident saying so.

Rig-side checks, independent of the board: every command is checked against Table 1 limits
(``board_config.load_mfc_limits``) before it reaches the rig; a refused one is counted, the last valid output
stays applied, and samples carry ``FLAG_LIMIT_REFUSED`` until the next accepted command. Commands are
delivered to the endpoint only when new, so the rig's own watchdog (``SimulatedRig.watchdog``: no command for
0.1 s → zero demand) sees a silent board exactly as in-process. If the endpoint schedules link outages
(``link_down()``, a scenario's ``link_outage`` events), commands during an outage are not delivered and get no
reply, as the in-process link behaves.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from enum import Enum

from board_config import MfcLimits, load_mfc_limits
from board_config.errors import InputError
from drivers.framing import sanitize_sample
from drivers.latency_slice import request_slice
from drivers.link import FLAG_LIMIT_REFUSED, ActuatorCommand, RigEndpoint, RigSample

log = logging.getLogger("hil_stub.rig")

BOARD_CURRENT_MAX = 10.0  # A (the simulated rig's own bound; the board draws milliamps)
#: the resolution of an asyncio timer on Linux (s): ``epoll_wait`` takes whole milliseconds, rounded up
LOOP_TIMER_RESOLUTION_S = 1e-3


class Delivery(Enum):
    """What became of a command posted to the host."""

    ACCEPTED = "accepted"
    REFUSED = "refused"  #: outside the limits: not applied, reply carries FLAG_LIMIT_REFUSED (Modbus: exception 03)
    UNDELIVERED = "undelivered"  #: the rig schedules a link outage now: no reply


@dataclass(frozen=True)
class Snapshot:
    """What the rig shows at one instant (immutable; replaced as a whole)."""

    sample: RigSample  #: sanitised (no NaN/Inf), host flags merged
    cmd_seq_applied: int  #: sequence number of the last accepted command
    refused_count: int
    tick: int
    amplifier_active: bool  #: the applied demand is not zero


@dataclass
class PacingStats:
    """Wall-clock pacing of the realtime loop (seconds)."""

    ticks: int = 0
    deadline_misses: int = 0  #: ticks that ended after the next tick's start time
    lateness_max: float = 0.0  #: worst start lateness of a tick
    lateness_sum: float = 0.0
    lateness_sq_sum: float = 0.0
    step_time_max: float = 0.0  #: worst duration of apply+advance+publish
    lateness_samples: list[float] = field(default_factory=list, repr=False)

    def record(self, lateness: float, step_time: float, keep: bool) -> None:
        self.ticks += 1
        self.lateness_max = max(self.lateness_max, lateness)
        self.lateness_sum += lateness
        self.lateness_sq_sum += lateness * lateness
        self.step_time_max = max(self.step_time_max, step_time)
        if keep:
            self.lateness_samples.append(lateness)

    def summary(self) -> dict[str, float | int]:
        n = max(self.ticks, 1)
        mean = self.lateness_sum / n
        return {"ticks": self.ticks, "deadline_misses": self.deadline_misses,
                "tick_lateness_mean_ms": 1e3 * mean,
                "tick_jitter_rms_ms": 1e3 * math.sqrt(max(self.lateness_sq_sum / n - mean * mean, 0.0)),
                "tick_lateness_max_ms": 1e3 * self.lateness_max, "step_time_max_ms": 1e3 * self.step_time_max}


def check_command(command: ActuatorCommand, limits: MfcLimits) -> str | None:
    """Why the rig refuses ``command`` (None: acceptable). Pure."""
    for name in ("v_ch1", "v_ch2"):
        v = getattr(command, name)
        if not math.isfinite(v) or not limits.voltage_min <= v <= limits.voltage_max:
            return (f"{name}={v!r} V outside the MFC limits [{limits.voltage_min:g}, {limits.voltage_max:g}] V "
                    f"(Table 1)")
    cur = command.board_current
    if not math.isfinite(cur) or not 0.0 <= cur <= BOARD_CURRENT_MAX:
        return f"board_current={cur!r} A outside [0, {BOARD_CURRENT_MAX:g}] A"
    return None


class RigHost:
    """Serialises access to one rig endpoint and publishes its snapshots (see the module docstring)."""

    def __init__(self, endpoint: RigEndpoint, *, dt: float = 0.01, mode: str = "realtime",
                 limits: MfcLimits | None = None, start: str = "first-command",
                 clock: Callable[[], float] = time.perf_counter, keep_lateness: bool = False,
                 on_tick: Callable[[Snapshot], None] | None = None,
                 restart: Callable[[], RigEndpoint] | None = None, clock_slice_s: float | None = None) -> None:
        if mode not in ("realtime", "lockstep"):
            raise InputError(f"rig clock mode {mode!r}: allowed realtime, lockstep")
        if start not in ("first-command", "now"):
            raise InputError(f"rig start {start!r}: allowed first-command, now")
        if not (dt > 0 and math.isfinite(dt)):
            raise ValueError(f"rig tick dt={dt!r} s must be positive")
        self.endpoint = endpoint
        self.dt = float(dt)
        self.mode = mode
        self.limits = limits or load_mfc_limits()
        self.clock = clock
        self.keep_lateness = keep_lateness
        self.on_tick = on_tick
        self._lock = threading.Lock()  # guards the endpoint (held during a plant step)
        self._mail_lock = threading.Lock()  # guards only the mailbox swap (never held for long)
        self._applied = ActuatorCommand(seq=0)  # last accepted command (what the amplifier outputs)
        self._pending: ActuatorCommand | None = None
        self._refused_flag = False
        self._clock_running = start == "now"
        self.refused_count = 0
        self.accepted_seq = 0  #: sequence number of the last accepted command (applied at the next tick)
        self.commands = 0
        self.undelivered = 0
        self.incidents: list[str] = []
        self.incident_count = 0
        self.pacing = PacingStats()
        self._tick = 0
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._loop: asyncio.AbstractEventLoop | None = None  #: the event loop the clock runs on (or None)
        self._tick_handle: asyncio.TimerHandle | None = None
        self._next_t: float | None = None  #: the clock time the next realtime tick is due
        self._link_down_fn = getattr(endpoint, "link_down", None)
        self._restart = restart
        self._last_seq: int | None = None
        self.board_runs = 0  #: board runs seen (a command counter that started again counts a new one)
        self.restarts = 0  #: times the lockstep rig started again for a new board run
        #: the CPU time slice (s) the realtime clock thread asks for (:func:`drivers.latency_slice.request_slice`;
        #: 0: the kernel's default; None: what it inherits from the thread that starts it) and what became of it
        self.clock_slice_s = clock_slice_s
        self.clock_slice_note = "inherited"
        self._snapshot = self._make_snapshot()

    # ------------------------------------------------------------------------------------------ snapshot
    @property
    def snapshot(self) -> Snapshot:
        """The latest snapshot, with the live refused state merged in."""
        snap = self._snapshot
        flags = snap.sample.flags | (FLAG_LIMIT_REFUSED if self._refused_flag else 0)
        if flags == snap.sample.flags and snap.refused_count == self.refused_count and \
                snap.cmd_seq_applied == self.accepted_seq:
            return snap
        # built directly (a request reads this once per transaction: dataclasses.replace costs ~5 us a call)
        sample = snap.sample if flags == snap.sample.flags else replace(snap.sample, flags=flags)
        return Snapshot(sample, self.accepted_seq, self.refused_count, snap.tick, snap.amplifier_active)

    def _make_snapshot(self) -> Snapshot:
        sample = sanitize_sample(self.endpoint.sample())
        a = self._applied
        return Snapshot(sample, self.accepted_seq, self.refused_count, self._tick, a.v_ch1 != 0.0 or a.v_ch2 != 0.0)

    def incident(self, text: str) -> None:
        """Record and log an incident (the last 1000 are kept)."""
        self.incident_count += 1
        self.incidents.append(text)
        if len(self.incidents) > 1000:
            del self.incidents[:500]
        log.warning("%s", text)

    def link_down(self) -> bool:
        """Whether the rig schedules a link outage now (the endpoint's ``link_down()``, if it has one)."""
        if self._link_down_fn is None:
            return False
        try:
            return bool(self._link_down_fn())
        except Exception:  # an endpoint extra must not break serving
            return False

    # ------------------------------------------------------------------------------------------ commands
    def submit(self, command: ActuatorCommand, source: str = "") -> Delivery:
        """A command from a server. In lockstep mode this advances the rig one tick (also when undelivered)."""
        self.commands += 1
        self._note_board_run(command.seq & 0xFFFFFFFF, source)
        if not self._clock_running:
            self._clock_running = True
        if self.link_down():
            self.undelivered += 1
            if self.mode == "lockstep":
                with self._lock:
                    self._step_locked(deliver=False)
            return Delivery.UNDELIVERED
        why = check_command(command, self.limits)
        if why is not None:
            self.refused_count += 1
            self._refused_flag = True
            self.incident(f"refused command seq {command.seq}{' from ' + source if source else ''}: {why}")
        else:
            self._refused_flag = False
            self.accepted_seq = command.seq & 0xFFFFFFFF
            with self._mail_lock:
                self._pending = command
        if self.mode == "lockstep":
            with self._lock:
                self._step_locked()
        return Delivery.REFUSED if why is not None else Delivery.ACCEPTED

    # ------------------------------------------------------------------------------------------ board runs
    def starts_again(self, seq: int) -> bool:
        """Whether a command with sequence number ``seq`` would start the lockstep rig again for a new board run
        (building a rig: seconds, not the plant step's microseconds)."""
        last = self._last_seq
        seq &= 0xFFFFFFFF
        return (self.mode == "lockstep" and self._restart is not None and last is not None and seq < last
                and not (last >= 0xFFFF0000 and seq < 0x10000) and self._tick > 0)

    def _note_board_run(self, seq: int, source: str) -> None:
        """Count a new board run when the command counter starts again; restart a lockstep rig for it."""
        last, self._last_seq = self._last_seq, seq
        if last is None:
            self.board_runs = 1
            return
        if seq >= last or (last >= 0xFFFF0000 and seq < 0x10000):  # the same run (or its counter wrapping)
            return
        self.board_runs += 1
        where = f" on {source}" if source else ""
        if self.mode == "lockstep" and self._restart is not None:
            if self._tick > 0:
                self._start_again(f"board run {self.board_runs}{where} (its command counter started again at {seq})")
            return
        self.incident(f"board run {self.board_runs}{where}: its command counter started again ({last} -> {seq}); "
                      f"the {self.mode} rig plays its scenario on at t = {self._snapshot.sample.t:.2f} s (a real-time "
                      "rig plays it once: restart `shm hil serve`, or serve with --clock lockstep)")

    def _start_again(self, why: str) -> None:
        """The rig as it was built (a fresh endpoint from the ``restart`` factory) for a new board run."""
        assert self._restart is not None
        try:
            endpoint = self._restart()
        except Exception as exc:  # keep serving the old rig rather than fail the board's exchange
            self.incident(f"{why}: could not start the rig again ({exc!r}); it plays on at t = "
                          f"{self._snapshot.sample.t:.2f} s")
            return
        with self._lock:
            with self._mail_lock:
                self._pending = None
            self.endpoint = endpoint
            self._link_down_fn = getattr(endpoint, "link_down", None)
            self._applied = ActuatorCommand(seq=0)
            self._refused_flag = False
            self.accepted_seq = 0
            self._tick = 0
            self._snapshot = self._make_snapshot()
        self.restarts += 1
        log.info("%s: the rig starts again from t = 0", why)

    # ------------------------------------------------------------------------------------------ ticking
    def _step_locked(self, deliver: bool = True) -> None:
        with self._mail_lock:
            pending, self._pending = self._pending, None
        if pending is not None and deliver:
            self._applied = pending
            self.endpoint.apply(pending)
        self.endpoint.advance(self.dt)
        self._tick += 1
        self._snapshot = self._make_snapshot()
        if self.on_tick is not None:
            self.on_tick(self._snapshot)

    def tick(self) -> Snapshot:
        """One realtime tick (called by the loop thread; public for tests that drive the clock by hand)."""
        with self._lock:
            if self._clock_running:
                self._step_locked()
        return self._snapshot

    def start(self, loop: asyncio.AbstractEventLoop | None = None, due: float | None = None) -> None:
        """Start the realtime clock (no-op in lockstep mode): on ``loop``, the thread that runs the servers' event
        loop (one serving thread: no GIL hand-over and no second thread to wake between a request and its reply), or
        without one in a thread of its own (``rig-clock``); ``due``: the next tick's clock time (None: anchored at
        the first command)."""
        if self.mode != "realtime" or self._thread is not None or self._loop is not None:
            return
        self._stop.clear()
        self._next_t = due
        if loop is not None:
            self._loop = loop
            self.clock_slice_note = "the rig clock runs on the Modbus event loop's thread"
            loop.call_soon_threadsafe(self._on_loop)
            return
        self._thread = threading.Thread(target=self._run, name="rig-clock", daemon=True)
        self._thread.start()
        if self.clock_slice_s is not None and self._thread.native_id is not None:
            self.clock_slice_note = request_slice(self.clock_slice_s, self._thread.native_id).note

    def run_clock_on(self, loop: asyncio.AbstractEventLoop) -> None:
        """Move a realtime clock running in its own thread onto ``loop``, its schedule kept."""
        if self._thread is None:
            return
        self.stop()
        self.start(loop, due=self._next_t)

    def stop(self) -> None:
        self._stop.set()
        if self._loop is not None:
            loop, self._loop = self._loop, None
            if not loop.is_closed():  # cancel the pending tick on the loop's own thread (a tick due stops anyway)
                with contextlib.suppress(RuntimeError, TimeoutError):
                    asyncio.run_coroutine_threadsafe(self._cancel_tick(), loop).result(2.0)
        if self._thread is not None:
            self._thread.join(timeout=2.0)
            self._thread = None

    async def _cancel_tick(self) -> None:
        if self._tick_handle is not None:
            self._tick_handle.cancel()
            self._tick_handle = None

    def _due(self) -> float | None:
        """The clock time the next tick is due; None while the clock stands still (before the first command)."""
        if self._next_t is None and self._clock_running:
            # first command: anchor the schedule half a tick later, so that the board's commands (one per tick, at
            # the same phase) arrive mid-tick and a little jitter never moves one into another tick
            self._next_t = self.clock() + 0.5 * self.dt
        return self._next_t

    def _tick_due(self, due: float) -> None:
        """The tick due at ``due`` (clock time), its pacing recorded, the next one scheduled."""
        clock = self.clock
        start = clock()
        try:
            self.tick()
        except Exception as exc:  # the clock must survive a bad plant step
            self.incident(f"rig tick failed: {exc!r}")
        end = clock()
        self.pacing.record(max(0.0, start - due), end - start, self.keep_lateness)
        next_t = due + self.dt
        if end > next_t:
            self.pacing.deadline_misses += 1
            behind = int((end - next_t) / self.dt)
            if behind > 5:  # a long stall: skip the lost ticks instead of racing to catch up
                self.incident(f"rig loop stalled {behind} ticks; re-anchoring the schedule")
                next_t += behind * self.dt
        self._next_t = next_t

    def _on_loop(self) -> None:
        """The realtime clock on the event loop: the tick due now, then a timer for the next one (every 1 ms
        before the first command, as the thread polls). The loop's timer wakes up to 1 ms late (``epoll`` counts
        milliseconds, rounded up), so it is set :data:`LOOP_TIMER_RESOLUTION_S` early and a tick due within that runs
        at once: up to 1 ms early (lateness 0) instead of up to 1 ms late."""
        self._tick_handle = None
        loop = self._loop
        if loop is None or self._stop.is_set():
            return
        due = self._due()
        if due is not None and due - self.clock() <= LOOP_TIMER_RESOLUTION_S:
            self._tick_due(due)
            due = self._next_t
        delay = 1e-3 if due is None else max(0.0, due - self.clock() - LOOP_TIMER_RESOLUTION_S)
        self._tick_handle = loop.call_later(delay, self._on_loop)

    def _run(self) -> None:
        while not self._stop.is_set():
            due = self._due()
            if due is None:
                self._stop.wait(0.001)
                continue
            delay = due - self.clock()
            if delay > 0:
                self._stop.wait(delay)
            self._tick_due(due)
