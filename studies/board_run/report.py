"""The self-contained HTML summary of ``shm run`` (the figures of :mod:`studies.board_run.figures` embedded)."""

from __future__ import annotations

import html
from pathlib import Path
from typing import Any

from reporting.html_page import img_tag, records_table
from studies.board_run.figures import maintenance_plot, overview_plot, usage_plot

#: the report's tables: (summary key, column heading)
MBIT_COLUMNS = [("label", "MBIT"), ("verdict", "verdict"), ("max_count", "fault counter max"), ("max_eps", "max eps"),
                ("n_exceed", "samples above eps_th"), ("n_samples", "samples"),
                ("fault_time_s", "fault latched at (s)"), ("time_s", "ended at (s)")]
REGIME_CHANGE_COLUMNS = [("time_s", "time (s)"), ("from_regime", "from"), ("to_regime", "to"), ("trigger", "trigger"),
                         ("v_battery_V", "battery (V)")]
POWER_COLUMNS = [("regime", "regime"), ("current_A", "current (A)"), ("time_s", "time (s)"), ("charge_C", "charge (C)")]
USAGE_COLUMNS = [("t_start_s", "start (s)"), ("duration_s", "duration (s)"), ("reason", "closed by"),
                 ("peak_z3_m", "peak |z3| (m)"), ("peak_z0dd_m_s2", "peak |z0dd| (m/s²)"), ("n_cycles", "cycles"),
                 ("max_range_m", "max range (m)")]
INCIDENT_COLUMNS = [("time_s", "time (s)"), ("incident", "incident"), ("regime", "regime"), ("detail", "detail")]


def write_plots_and_report(out: Path, summary: dict[str, Any], result, timeline: list[str]) -> list[str]:
    """Write the PNGs and ``report.html``; return the file names written (``summary``: summary.json as written, the
    JSON document at the edge)."""
    from board_config import load_monitor_settings

    figures: list[str] = []
    cols = result.trace.columns() if result.trace is not None else None
    windows = []
    starts = {e.data["label"]: e.time for e in result.events if e.kind == "mbit_start"}
    last_start: dict[str, float] = {}
    for e in result.events:
        if e.kind == "mbit_start":
            last_start[e.data["label"]] = e.time
        elif e.kind == "mbit_result":
            windows.append({"label": e.data["label"], "start_s": last_start.get(e.data["label"],
                                                                                starts.get(e.data["label"], 0.0)),
                            "end_s": e.time})
    summary["mbit_windows"] = windows
    if cols is not None and cols["time_s"].size:
        overview_plot(out / "overview.png", cols, summary)
        figures.append("overview.png")
        if maintenance_plot(out / "maintenance.png", cols, summary, load_monitor_settings().count_max):
            figures.append("maintenance.png")
    if usage_plot(out / "usage.png", summary):
        figures.append("usage.png")

    s = summary
    verdicts = s["maintenance_verdicts"]
    verdict = verdicts[-1]["verdict"] if verdicts else "no maintenance visit"
    exp = s["expected_verdict"]
    mark = ("<span class=ok>as expected</span>" if s["verdict_as_expected"]
            else "<span class=bad>NOT as expected</span>")
    exp_html = "" if exp is None else f" &nbsp;(scenario expects <b>{html.escape(exp)}</b>: {mark})"
    cfg = s["board_config"]
    power_rows = [
        {"regime": r, "current_A": cfg[f"power_current_{k}"], "time_s": s["time_in_regime_s"].get(r, 0.0),
         "charge_C": cfg[f"power_current_{k}"] * s["time_in_regime_s"].get(r, 0.0)}
        for r, k in (("STANDBY_HARVEST", "standby"), ("SENSING", "sensing"), ("MAINTENANCE", "maintenance"),
                     ("SAFE", "safe"))]
    ts = s["tick_stats"]
    stats_rows = [{"quantity": k, "value": v} for k, v in (
        ("ticks", s["ticks"]), ("board time (s)", s["board_time_s"]), ("wall time (s)", s["wall_s"]),
        ("real-time factor", s["realtime_factor"]), ("paced on the wall clock", s["paced"]),
        ("deadline misses", ts["deadline_misses"]), ("max consecutive misses", ts["max_consecutive_misses"]),
        ("tick jitter p50 / p99 / max (ms)", f"{ts['jitter_p50_s'] * 1e3:.3f} / {ts['jitter_p99_s'] * 1e3:.3f} / "
                                              f"{ts['jitter_max_s'] * 1e3:.3f}" if s["paced"] else "n/a (virtual)"),
        ("battery first / last / min (V)", f"{s['battery_first_V']:.4f} / {s['battery_last_V']:.4f} / "
                                           f"{s['battery_min_V']:.4f}"),
        ("charge drawn by the board (C)", s["charge_used_C"]), ("brown-outs", s["brownouts"]))]
    figs_html = "".join(f"<h2>{html.escape(f)}</h2>{img_tag(out / f)}" for f in figures)
    page = f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>shm run — {html.escape(s['scenario'])}</title>
<style>body{{font-family:sans-serif;margin:2em;max-width:1200px}} table{{border-collapse:collapse;margin:0.5em 0}}
td,th{{border:1px solid #bbb;padding:3px 7px;font-size:90%;text-align:left}} th{{background:#eee}}
pre{{background:#f6f6f6;padding:1em;font-size:80%;overflow-x:auto}}
.ok{{color:#070}} .bad{{color:#b00;font-weight:bold}}
</style></head><body>
<h1>Board run: scenario “{html.escape(s['scenario'])}”</h1>
<p>Scenario file <code>{html.escape(str(s['scenario_file']))}</code>, seed {s['seed']}, parameter set
<code>{html.escape(s['params'])}</code>, link <code>{html.escape(s['link'])}</code>. Usage log:
<code>{html.escape(Path(s['database']).name)}</code> (SQLite, schema in docs/board.md).</p>
<h2>Verdict: {html.escape(verdict)}{exp_html}</h2>
{records_table(s['mbit_results'], MBIT_COLUMNS)}
<h2>Run</h2>{records_table(stats_rows, [('quantity', 'quantity'), ('value', 'value')])}
<h2>Regime changes</h2>
{records_table(s['regime_changes'], REGIME_CHANGE_COLUMNS)}
<h2>Power budget (board's declared draw)</h2>
{records_table(power_rows, POWER_COLUMNS)}
<h2>Usage summaries</h2>
{records_table(s['usage_summaries'], USAGE_COLUMNS)}
<h2>Incidents</h2>
{records_table(s['incidents_list'], INCIDENT_COLUMNS)}
{figs_html}
<h2>Timeline</h2><pre>{html.escape(chr(10).join(timeline))}</pre>
</body></html>
"""
    (out / "report.html").write_text(page)
    return figures
