"""Figures of the plant model and its calibration (``shm model frf|step|loop``, ``shm calibrate``): Bode plots of
the frequency responses, time responses and hysteresis loops, and the calibration's falling error."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from reporting.figure_layout import count_axis
from reporting.figures import pyplot, save_figure

#: the frequency responses ``shm model frf`` draws: file stem -> (axis label, title); amplitudes in the label's unit
FRF_FIGURES: dict[str, tuple[str, str]] = {
    "frf_z3_per_va": ("|z3 / v_a| (µm/V)", "Tip deformation response to voltage (cf. Fig. 6a)"),
    "frf_vstored_per_accel": ("|v_stored / z̈0| (V/g)", "Stored voltage response to base acceleration (cf. Fig. 6b)"),
}


def bode_figure(path: Path, f: np.ndarray, h: np.ndarray, ylabel: str, title: str) -> Path:
    """Amplitude (log-log) and unwrapped phase of the complex response ``h`` at frequencies ``f`` (Hz)."""
    plt = pyplot()
    fig, (a1, a2) = plt.subplots(2, 1, sharex=True, figsize=(7, 6))
    a1.loglog(f, np.abs(h))
    a1.set_ylabel(ylabel)
    a1.set_title(title)
    a1.grid(True, which="both", alpha=0.3)
    a2.semilogx(f, np.degrees(np.unwrap(np.angle(h))))
    a2.set_ylabel("phase (deg)")
    a2.set_xlabel("frequency (Hz)")
    a2.grid(True, which="both", alpha=0.3)
    return save_figure(fig, path, 120, tight=True)


def time_response_figure(path: Path, resp: Any, xy_loop: bool, title: str) -> Path:
    """Tip displacement against time, or against the differential drive (``xy_loop``: the hysteresis loop)."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7, 4.5))
    if xy_loop:
        ax.plot(resp.va, resp.z3 * 1e3)
        ax.set_xlabel("differential drive v_a (V)")
    else:
        ax.plot(resp.t, resp.z3 * 1e3)
        ax.set_xlabel("time (s)")
    ax.set_ylabel("tip displacement z3 (mm)")
    ax.set_title(title)
    ax.grid(True, alpha=0.3)
    return save_figure(fig, path, 120, tight=True)


def calibration_figure(path: Path, history: Sequence[float], rows: Sequence[dict[str, Any]], start_name: str,
                       name: str) -> Path:
    """The weighted cost against model evaluations, and each claim's relative error before and after."""
    plt = pyplot()
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4))
    a1.semilogy(history)
    count_axis(a1.xaxis)
    a1.set_xlabel("model evaluation")
    a1.set_ylabel("weighted cost")
    a1.set_title("calibration: the error falling")
    a1.grid(True, alpha=0.3)
    names = [r["claim"] for r in rows]
    y = np.arange(len(names))[::-1]  # first claim on top; each claim's two bars side by side
    a2.barh(y + 0.2, [100 * r["rel_error_start"] for r in rows], height=0.4, color="tab:gray", label=start_name)
    a2.barh(y - 0.2, [100 * r["rel_error_calibrated"] for r in rows], height=0.4, color="tab:blue", label=name)
    a2.set_yticks(y, names)
    a2.axvline(0.0, color="k", lw=0.6)
    a2.set_xscale("symlog", linthresh=1.0)
    a2.set_xlabel("relative error against the paper (%)")
    a2.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, fontsize=8)
    return save_figure(fig, path, 110, tight=True)
