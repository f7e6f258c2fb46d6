"""The harvesting study's figure: Fig. 9-style charge curve with the stored voltage and the projection."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from board_config.physical_constants import G0
from reporting.figure_layout import few_ticks, legend_clear_of_data
from reporting.figures import pyplot, save_figure
from studies.harvest.outputs import format_duration
from studies.harvest.setup import PAPER_CLAIM_S


def plot_charge_curve(run: Any, path: Path) -> Path:
    """Fig. 9 style: cell voltage against time (minutes), the 10-minute mark, and the stored (patch) voltage."""
    plt = pyplot()
    has_proj = run.projection is not None and len(run.projection.curve.q_d) > 1
    fig, axes = plt.subplots(1, 3 if has_proj else 2, figsize=(14 if has_proj else 10, 4.2))
    s = run.setup
    ax = axes[0]
    ax.plot(run.t / 60.0, run.v_bat_term, lw=0.4, alpha=0.25, color="tab:orange", zorder=1,
            label="terminal voltage (pulses with the charging current)")
    ax.plot(run.t / 60.0, run.v_bat, lw=2.0, color="tab:blue", zorder=3, label="open-circuit v_b")
    proj = run.projection
    if proj is not None and proj.t_path.size and math.isfinite(proj.t_full_s) and proj.t_full_s < 20 * run.t_end:
        ax.plot(proj.t_path / 60.0, proj.v_path, "--", color="tab:blue", zorder=3, label="projected (quasi-steady)")
    lo = min(float(np.nanmin(run.v_bat)), run.battery.spec.cutoff_voltage) - 0.1
    ax.set_ylim(lo, run.battery.spec.full_voltage + 0.25)
    ax.axvline(PAPER_CLAIM_S / 60.0, color="k", ls=":", lw=1, label="paper: full within 10 min")
    ax.axhline(run.battery.spec.full_voltage, color="g", ls="--", lw=0.8, label="full")
    ax.set_xlabel("time (min)")
    ax.set_ylabel("cell voltage (V)")
    ax.set_title(f"{s.coupling}: {s.accel / G0:g} g, {s.freq:g} Hz, R_bint {s.r_int:g} ohm")
    ax.grid(alpha=0.3)
    ax = axes[1]
    ax.plot(run.tail["t_s"], run.tail["v_stored_V"], lw=0.8)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("patch terminal voltage v_a (V)")
    ax.set_title(f"last seconds: peak {run.chunks['va_peak_V'][-1]:.3g} V")
    few_ticks(ax.xaxis)  # "596.0 596.5 ..." in a narrow panel ran together
    ax.grid(alpha=0.3)
    if has_proj:
        c = run.projection.curve
        ax = axes[2]
        ax.plot(c.v_oc, c.i_mean * 1e3, "o-")
        ax.set_xlabel("cell open-circuit voltage (V)")
        ax.set_ylabel("cycle-mean charging current (mA)")
        ax.set_title(f"projection: full after {format_duration(run.projection.t_full_s)}")
        ax.grid(alpha=0.3)
    fig.tight_layout()
    legend_clear_of_data(axes[0], fontsize=7, loc="upper left")  # on the final layout, above the charge curve
    return save_figure(fig, path, 120, tight=True)
