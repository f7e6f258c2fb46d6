"""Figures of a board run (``shm run``): the overview (regimes, base acceleration, tip deflection, battery), the
maintenance MBITs (measured vs nominal, commands, fault counter) and the usage summaries (rainflow, exceedance)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from reporting.figures import minmax_envelope, pyplot, save_figure

#: board regimes in the order of the trace's regime_code, and their shading
REGIME_NAMES = ("STANDBY_HARVEST", "SENSING", "MAINTENANCE", "SAFE")
REGIME_COLOURS = ("#d9ead3", "#fff2cc", "#cfe2f3", "#f4cccc")


def _shade_regimes(ax, t: np.ndarray, code: np.ndarray, scale: float) -> None:
    if t.size == 0:
        return
    edges = np.flatnonzero(np.diff(code)) + 1
    starts = np.r_[0, edges]
    ends = np.r_[edges, code.size - 1]
    for a, b in zip(starts, ends):
        c = int(code[a]) if np.isfinite(code[a]) else 0
        ax.axvspan(t[a] * scale, t[b] * scale, color=REGIME_COLOURS[c], lw=0)


# ``summary``: summary.json as written (the JSON document at the edge, partial when a step failed; issue 29 pt 1)
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
        tt, lo, hi = minmax_envelope(t, cols[key] * fac)
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
    save_figure(fig, path, 110, tight=True)


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
    save_figure(fig, path, 110, tight=True)
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
    save_figure(fig, path, 110, tight=True)
    return True
