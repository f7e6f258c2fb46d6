"""The timeline of a board run: one line per board event worth showing (regime changes, incidents, usage
summaries, MBITs and verdicts, periodic telemetry)."""

from __future__ import annotations

import json
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from firmware_sim.events import BoardEvent


def _fmt_v(v: Any) -> str:
    try:
        return f"{float(v):.3f} V"
    except (TypeError, ValueError):
        return "? V"


def format_event(ev: BoardEvent, incidents: int = 0) -> str | None:
    """One timeline line for a board event (None: not shown)."""
    d = ev.data
    t = f"{ev.time:9.2f} s  "
    if ev.kind == "regime_change":
        causes = f" [{', '.join(d.get('causes') or [])}]" if d.get("causes") else ""
        return (f"{t}{d['from_regime']:>15} -> {d['to_regime']:<15} trigger {d['trigger']}{causes}   "
                f"battery {_fmt_v(d.get('v_battery_V'))}")
    if ev.kind == "incident":
        return f"{t}  ! {d['incident']}: {d.get('detail', '')}"
    if ev.kind == "usage_summary":
        exc = json.loads(d["exceedance_json"])
        over = ", ".join(f"|z3|>={e['level_m'] * 1e3:g} mm {e['time_s']:.2f} s" for e in exc if e["time_s"] > 0)
        return (f"{t}  usage {d['duration_s']:.1f} s ({d['reason']}): peak z3 {d['peak_z3_m'] * 1e3:.3f} mm, "
                f"peak z0dd {d['peak_z0dd_m_s2']:.2f} m/s^2, {d['n_cycles']:g} cycles "
                f"(max range {d['max_range_m'] * 1e3:.3f} mm)" + (f"; {over}" if over else ""))
    if ev.kind == "mbit_start":
        return f"{t}  {d['label']} started"
    if ev.kind == "mbit_result":
        ft = f", fault latched at t = {d['fault_time_s']:.2f} s" if d.get("fault_time_s") is not None else ""
        return (f"{t}  {d['label']} {d['verdict']}: fault counter max {d['max_count']}, max eps {d['max_eps']:.3f}, "
                f"{d['n_exceed']}/{d['n_samples']} samples above eps_th{ft}")
    if ev.kind == "maintenance_verdict":
        return f"{t}  MAINTENANCE VERDICT {d['verdict']} ({d['mbits'] or 'no MBIT'}; {d['detail']})"
    if ev.kind == "telemetry":
        return (f"{t}  [{d['regime']}] battery {_fmt_v(d['v_battery_V'])}, fault counter {d['monitor_count']}, "
                f"incidents {d['incidents_total']}, charge used {d['charge_used_C'] * 1e3:.3f} mC")
    return None
