"""What the board publishes for the live page: an immutable snapshot in a slot that never blocks the writer.

A :class:`Snapshot` is a frozen value: the scalars of the moment (regime, battery, fault counter, link health ...)
and bounded histories as tuples (regime changes, event-log lines, the chunks of the series). The publisher builds a
new one from the previous (``dataclasses.replace``) and stores it in a :class:`SnapshotSlot` by replacing one
reference — an atomic store in CPython, so the tick never waits for a reader and a reader never sees half a
snapshot. Histories are bounded (``MAX_CHUNKS``, ``MAX_EVENTS``, ``MAX_REGIMES``): a run of hours keeps the last
stretch; every item carries a running index, so a reader knows what it has already sent.

Units are SI and in the field names (``_s``, ``_V``, ``_m``); ``None`` where a value is not known (the rig does
not know the board's regime; no MBIT has run yet).
"""

from __future__ import annotations

from dataclasses import dataclass, field

#: chunks kept (one per publication, at most 20 per second: the last 2 minutes at 20 Hz)
MAX_CHUNKS = 2400
#: event-log lines kept
MAX_EVENTS = 1000
#: regime changes kept
MAX_REGIMES = 500


@dataclass(frozen=True, slots=True)
class Chunk:
    """The series points of one publication: one point of the slow series (battery, SoC, fault counter, link
    round trip) and the MBIT rows since the previous publication (every tick of an MBIT: 100 Hz)."""

    index: int  # running number of the chunk (0, 1, 2, ...)
    t_s: float  # board time of the slow point (s)
    v_battery_V: float | None
    soc: float | None  # state of charge, 1 full, 0 at the cut-off
    monitor_count: int | None
    rtt_p99_s: float | None
    mbit_id: int  # which MBIT the rows belong to (0: none yet)
    mbit_t_s: tuple[float, ...] = ()  # board time of each MBIT row (s)
    z3_meas_m: tuple[float, ...] = ()  # measured tip deflection (m)
    z3_model_m: tuple[float, ...] = ()  # the nominal model's tip deflection (m)
    eps: tuple[float, ...] = ()  # normalised error (Eq. 11), NaN where not finite


@dataclass(frozen=True, slots=True)
class LinkHealth:
    """Link health as the board (or the rig) sees it."""

    exchanges: int = 0  # exchanges tried (board) / commands received (rig)
    misses: int = 0  # exchanges without a sample (board) / commands refused (rig)
    rtt_p50_s: float | None = None  # round trip of the last exchanges (s), median
    rtt_p99_s: float | None = None  # ... 99th percentile
    incidents: int = 0  # incidents so far (the board's count; the rig's)
    deadline_misses: int = 0  # ticks that ended after the next deadline (paced runs)
    counters: tuple[tuple[str, int], ...] = ()  # the link's own counters (timeouts, reopened, ...)


@dataclass(frozen=True, slots=True)
class Snapshot:
    """The state of the board (or the rig) at one moment, as the page shows it."""

    version: int = 0  # increases with every publication
    source: str = "board"  # "board" (shm run) or "rig" (shm hil serve)
    title: str = ""  # scenario, link, pacing
    board_time_s: float = 0.0
    planned_s: float | None = None  # board time the run is planned for (s)
    paced: bool = False
    regime: str | None = None
    regime_since_s: float | None = None
    regimes: tuple[tuple[float, str], ...] = ()  # (board time s, regime entered), first: the start
    v_battery_V: float | None = None
    soc: float | None = None
    soc_note: str = ""
    monitor_count: int | None = None
    count_max: int | None = None
    fault_latched: bool = False
    eps_th: float | None = None
    maintenance: str | None = None  # what the MBIT sequencer does: settle, MBIT.a, ..., done (None: not active)
    mbit_id: int = 0
    mbit_label: str | None = None
    mbit_max_eps: float | None = None  # of the current or last MBIT
    mbit_max_count: int | None = None
    verdicts: tuple[str, ...] = ()  # "MBIT.b FAULT", "MAINTENANCE FAULT", ...
    link: LinkHealth = field(default_factory=LinkHealth)
    extra: tuple[tuple[str, str], ...] = ()  # further (label, value) lines (the rig's own view)
    chunks: tuple[Chunk, ...] = ()
    events: tuple[tuple[int, str], ...] = ()  # (running index, line)
    finished: bool = False
    status: str = "running"  # running, finished, interrupted, failed
    report: str | None = None  # URL path of the report once written ("/report")


class SnapshotSlot:
    """One published :class:`Snapshot`: ``publish`` replaces it (the writer never waits), ``latest`` reads it."""

    __slots__ = ("_snapshot",)

    def __init__(self, first: Snapshot | None = None) -> None:
        self._snapshot = first if first is not None else Snapshot()

    def publish(self, snapshot: Snapshot) -> None:
        self._snapshot = snapshot  # one reference store: atomic, no lock

    def latest(self) -> Snapshot:
        return self._snapshot


def bounded(items: tuple, new: tuple, limit: int) -> tuple:
    """``items + new``, keeping the last ``limit``."""
    joined = items + new if new else items
    return joined[-limit:] if len(joined) > limit else joined
