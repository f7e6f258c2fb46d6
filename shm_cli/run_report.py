"""Plots and the self-contained HTML summary of ``shm run`` (matplotlib Agg; PNGs embedded as base64)."""

from __future__ import annotations

import base64
import html
import json
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from shm_cli.common import pyplot

REGIME_NAMES = ("STANDBY_HARVEST", "SENSING", "MAINTENANCE", "SAFE")
REGIME_COLOURS = ("#d9ead3", "#fff2cc", "#cfe2f3", "#f4cccc")


def _envelope(t: np.ndarray, y: np.ndarray, max_points: int = 4000) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Min/max envelope of ``y`` in ``max_points`` buckets (for long traces)."""
    n = y.size
    if n <= max_points:
        return t, y, y
    k = n // max_points
    m = (n // k) * k
    tt = t[:m].reshape(-1, k)[:, 0]
    yy = y[:m].reshape(-1, k)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN buckets (link down) stay NaN
        return tt, np.nanmin(yy, axis=1), np.nanmax(yy, axis=1)


def _shade_regimes(ax, t: np.ndarray, code: np.ndarray, scale: float) -> None:
    if t.size == 0:
        return
    edges = np.flatnonzero(np.diff(code)) + 1
    starts = np.r_[0, edges]
    ends = np.r_[edges, code.size - 1]
    for a, b in zip(starts, ends):
        c = int(code[a]) if np.isfinite(code[a]) else 0
        ax.axvspan(t[a] * scale, t[b] * scale, color=REGIME_COLOURS[c], lw=0)


def overview_plot(path: Path, cols: dict[str, np.ndarray], summary: dict[str, Any]) -> None:
    plt = pyplot()
    t = cols["time_s"]
    minutes = t[-1] > 300 if t.size else False
    scale, unit = (1 / 60, "min") if minutes else (1.0, "s")
    fig, axes = plt.subplots(4, 1, figsize=(11, 9), sharex=True)
    code = cols["regime_code"]
    ax = axes[0]
    ax.step(t * scale, code, where="post", color="k", lw=1)
    ax.set_yticks(range(4), REGIME_NAMES, fontsize=8)
    ax.set_ylim(-0.5, 3.5)
    ax.set_title(f"shm run — scenario {summary['scenario']} (seed {summary['seed']}, params {summary['params']})")
    for ax_, key, label, fac in ((axes[1], "z0dd_m_s2", "base accel. z0dd (m/s²)", 1.0),
                                 (axes[2], "z3_m", "tip deflection z3 (mm)", 1e3)):
        _shade_regimes(ax_, t, code, scale)
        tt, lo, hi = _envelope(t, cols[key] * fac)
        ax_.fill_between(tt * scale, lo, hi, color="C0", lw=0.5, step="mid")
        ax_.set_ylabel(label)
    ax = axes[3]
    _shade_regimes(ax, t, code, scale)
    v = cols["v_battery_V"]
    ax.plot(t * scale, v, color="C3", lw=1, label="battery (measured by the board)")
    cfg = summary["board_config"]
    ax.axhline(cfg["power_wake_min_voltage"], color="C2", ls="--", lw=0.8, label="wake_min_voltage")
    ax.axhline(cfg["power_brownout_voltage"], color="C1", ls=":", lw=0.8, label="brownout_voltage")
    ax.set_ylabel("battery (V)")
    ax.legend(fontsize=7, loc="lower left")
    ax.set_xlabel(f"board time ({unit})")
    for ch in summary["regime_changes"]:
        for a in axes:
            a.axvline(ch["time_s"] * scale, color="k", lw=0.4, alpha=0.4)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def maintenance_plot(path: Path, cols: dict[str, np.ndarray], summary: dict[str, Any], count_max: int) -> bool:
    mb = summary["mbit_results"]
    if not mb:
        return False
    plt = pyplot()
    t = cols["time_s"]
    fig, axes = plt.subplots(3, len(mb), figsize=(5.5 * len(mb), 8), squeeze=False)
    starts = {}
    for ev in summary.get("mbit_windows", []):
        starts[(ev["label"], ev["end_s"])] = ev["start_s"]
    for j, r in enumerate(mb):
        end = r["time_s"]
        start = starts.get((r["label"], end), end - r["n_samples"] / 100.0)
        m = (t >= start - 0.5) & (t <= end + 0.5)
        tt = t[m] - start
        ax = axes[0][j]
        ax.plot(tt, cols["z3_m"][m] * 1e3, label="z3 measured (rig)", lw=1)
        ax.plot(tt, cols["z3_model_m"][m] * 1e3, "--", label="z3 nominal model", lw=1)
        ax.set_title(f"{r['label']}: {r['verdict']}")
        ax.set_ylabel("z3 (mm)")
        ax.legend(fontsize=7)
        ax = axes[1][j]
        ax.plot(tt, cols["v_ch1_V"][m], label="v_ch1")
        ax.plot(tt, cols["v_ch2_V"][m], label="v_ch2")
        ax.set_ylabel("command (V)")
        ax.legend(fontsize=7)
        ax = axes[2][j]
        ax.plot(tt, cols["monitor_count"][m], color="C3")
        ax.axhline(count_max, color="k", ls="--", lw=0.8, label=f"count_max = {count_max}")
        ax.set_ylabel("fault counter")
        ax.set_xlabel(f"time from {r['label']} start (s)")
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return True


def usage_plot(path: Path, summary: dict[str, Any]) -> bool:
    us = summary["usage_summaries"]
    if not us:
        return False
    plt = pyplot()
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4))
    hist: dict[tuple[float, float], float] = {}
    exc: dict[float, float] = {}
    for u in us:
        for b in json.loads(u["rainflow_json"]):
            key = (b["range_low_m"], b["range_high_m"])
            hist[key] = hist.get(key, 0.0) + b["cycles"]
        for e in json.loads(u["exceedance_json"]):
            exc[e["level_m"]] = exc.get(e["level_m"], 0.0) + e["time_s"]
    if hist:
        keys = sorted(hist)
        a1.bar([k[0] * 1e3 for k in keys], [hist[k] for k in keys], width=[(k[1] - k[0]) * 1e3 for k in keys],
               align="edge", edgecolor="k")
    a1.set_xlabel("z3 range (mm)")
    a1.set_ylabel("cycles (rainflow, half cycles = 0.5)")
    a1.set_title(f"Rainflow histogram, {len(us)} usage summaries")
    levels = sorted(exc)
    a2.bar([f"{lv * 1e3:g}" for lv in levels], [exc[lv] for lv in levels], edgecolor="k")
    a2.set_xlabel("|z3| level (mm)")
    a2.set_ylabel("time at or above (s)")
    a2.set_title("Exceedance durations")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return True


def _img(path: Path) -> str:
    data = base64.b64encode(path.read_bytes()).decode("ascii")
    return f'<img alt="{html.escape(path.name)}" src="data:image/png;base64,{data}" style="max-width:100%">'


def _table(rows: list[dict[str, Any]], cols: list[tuple[str, str]]) -> str:
    if not rows:
        return "<p><i>none</i></p>"
    head = "".join(f"<th>{html.escape(label)}</th>" for _, label in cols)
    body = []
    for r in rows:
        cells = []
        for key, _ in cols:
            v = r.get(key)
            if isinstance(v, float):
                v = f"{v:.6g}"
            cells.append(f"<td>{html.escape('' if v is None else str(v))}</td>")
        body.append("<tr>" + "".join(cells) + "</tr>")
    return f"<table><tr>{head}</tr>{''.join(body)}</table>"


def write_plots_and_report(out: Path, summary: dict[str, Any], result, timeline: list[str]) -> list[str]:
    """Write the PNGs and ``report.html``; return the file names written."""
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
    figs_html = "".join(f"<h2>{html.escape(f)}</h2>{_img(out / f)}" for f in figures)
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
{_table(s['mbit_results'], [('label', 'MBIT'), ('verdict', 'verdict'), ('max_count', 'fault counter max'),
                            ('max_eps', 'max eps'), ('n_exceed', 'samples above eps_th'), ('n_samples', 'samples'),
                            ('fault_time_s', 'fault latched at (s)'), ('time_s', 'ended at (s)')])}
<h2>Run</h2>{_table(stats_rows, [('quantity', 'quantity'), ('value', 'value')])}
<h2>Regime changes</h2>
{_table(s['regime_changes'], [('time_s', 'time (s)'), ('from_regime', 'from'), ('to_regime', 'to'),
                              ('trigger', 'trigger'), ('v_battery_V', 'battery (V)')])}
<h2>Power budget (board's declared draw)</h2>
{_table(power_rows, [('regime', 'regime'), ('current_A', 'current (A)'), ('time_s', 'time (s)'),
                     ('charge_C', 'charge (C)')])}
<h2>Usage summaries</h2>
{_table(s['usage_summaries'], [('t_start_s', 'start (s)'), ('duration_s', 'duration (s)'), ('reason', 'closed by'),
                               ('peak_z3_m', 'peak |z3| (m)'), ('peak_z0dd_m_s2', 'peak |z0dd| (m/s²)'),
                               ('n_cycles', 'cycles'), ('max_range_m', 'max range (m)')])}
<h2>Incidents</h2>
{_table(s['incidents_list'], [('time_s', 'time (s)'), ('incident', 'incident'), ('regime', 'regime'),
                              ('detail', 'detail')])}
{figs_html}
<h2>Timeline</h2><pre>{html.escape(chr(10).join(timeline))}</pre>
</body></html>
"""
    (out / "report.html").write_text(page)
    return figures
