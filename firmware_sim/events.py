"""What the board reports: one small record type for everything that goes to the usage/event log.

``kind`` says which log table a record belongs to (see ``docs/board.md``, "Log schema"):

=====================  =====================================================================================
kind                   data keys (SI units in the names)
=====================  =====================================================================================
``regime_change``      from_regime, to_regime, trigger, v_battery_V
``incident``           incident (link_error: the first of a run of failed exchanges, link_restored: its end with
                       the count; sensor_fault / sensor_fault_cleared: a persisting sensor condition's start and
                       end with its count; limit_violation, overrun, brownout, brownout_cleared, wake_refused,
                       rearm_refused, rearm, mbit_aborted, mbit_clamped, visit_kept, clock_mismatch), detail
``usage_summary``      see :meth:`firmware_sim.usage.UsageSummary.as_record`
``mbit_result``        mbit, label, verdict (PASS / FAULT), fault_time_s, max_count, max_eps, n_samples, n_exceed,
                       n_invalid, clamp
``maintenance_verdict`` verdict (PASS / FAULT / INCOMPLETE), mbits, detail
``telemetry``          regime, v_battery_V, monitor_count, charge_used_C, incidents_total
``mbit_start``         mbit, label (not stored: timeline only)
``mbit_record``        mbit, label, test, rate_Hz, mbit_ticks, rows of (t s, v_ch1 V, v_ch2 V, z3 m): the completed
                       MBIT's full-rate record (not stored in the log; ``studies.health.visit_records`` writes it)
=====================  =====================================================================================
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Protocol


@dataclass(frozen=True, slots=True)
class BoardEvent:
    """A record the board emits at tick ``tick`` (board time ``time`` in s)."""

    kind: str
    tick: int
    time: float
    data: Mapping[str, Any] = field(default_factory=dict)


class EventSink(Protocol):
    """Where board events go (the SQLite usage log, a list in a test)."""

    def write(self, event: BoardEvent) -> object: ...  # what it returns (a row id, ...) is not used
