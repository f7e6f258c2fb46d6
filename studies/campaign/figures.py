"""Figures of the Monte-Carlo MBIT campaign (``shm campaign``, ``shm campaign-roc``): Fig. 11-style bars, error
traces, ROC curves (matplotlib Agg)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from reporting.figure_layout import hide_colliding_texts, legend_clear_of_data
from reporting.figures import pyplot, save_figure
from studies.campaign import CampaignResult, RocTable
from studies.campaign.paper import PAPER_FAULT_PROBABILITY


def _save(fig, path: Path, svg: bool = True) -> list[Path]:
    paths = [path.with_suffix(".png"), *([path.with_suffix(".svg")] if svg else [])]
    save_figure(fig, paths[0], 130, also=paths[1:])
    return paths


def fig11(result: CampaignResult, path: Path) -> list[Path]:
    """Detected BIT faults (top) and fault probability with 95 % Wilson intervals (bottom) per range and MBIT,
    with the paper's stated probabilities as red segments over the ranges they refer to."""
    plt = pyplot()
    keys = list(result.mbits)
    stats = result.summary()
    fig, axes = plt.subplots(2, len(keys), figsize=(5.2 * len(keys), 6.4), squeeze=False, sharex="col")
    for col, key in enumerate(keys):
        rows = [s for s in stats if s.mbit == key]
        x = np.arange(len(rows))
        labels = [s.range_label for s in rows]
        det = [s.n_detected for s in rows]
        n = [s.n_valid for s in rows]
        ax = axes[0, col]
        ax.bar(x - 0.2, n, width=0.4, color="0.85", edgecolor="0.6", label="runs")
        ax.bar(x + 0.2, det, width=0.4, color="tab:blue", label="detected BIT faults")
        for xi, d in zip(x, det):
            ax.text(xi + 0.2, d, str(d), ha="center", va="bottom", fontsize=8)
        ax.set_ylabel("number of runs")
        ax.set_title(f"({'abcdefgh'[col]}) {result.mbits[key].label}")
        ax = axes[1, col]
        p = np.array([s.probability for s in rows])
        lo = np.array([s.interval[0] for s in rows])
        hi = np.array([s.interval[1] for s in rows])
        ax.bar(x, 100 * p, color="tab:blue", alpha=0.8, label=f"model ({result.spec.params_name})")
        # bar lengths clipped at 0: the interval contains p, but a rounding hair must never fail the figure
        yerr = np.clip(np.nan_to_num(100 * np.array([p - lo, hi - p]), nan=0.0), 0.0, None)
        ax.errorbar(x, 100 * np.nan_to_num(p, nan=0.0), yerr=yerr, fmt="none", ecolor="k", capsize=3,
                    label="95 % Wilson interval")
        first = True
        for c_lo, c_hi, pp in PAPER_FAULT_PROBABILITY.get(key, ()):
            idx = [i for i, s in enumerate(rows) if s.lo >= c_lo - 1e-9 and s.hi <= c_hi + 1e-9]
            if not idx:
                continue
            ax.hlines(100 * pp, min(idx) - 0.4, max(idx) + 0.4, colors="tab:red", linewidth=2.5,
                      label="paper (stated)" if first else None)
            first = False
        ax.set_ylim(0, 105)
        ax.set_ylabel("BIT fault probability (%)")
        ax.set_xlabel("deviation range of (k3, alpha_h, beta_h)")
        ax.set_xticks(x, labels)
        ax.legend(fontsize=8, loc="lower right")
    fig.suptitle(f"Condition-monitor performance, {result.spec.n_runs} runs per range "
                 f"(eps_th={result.spec.monitor.eps_th:g}, count_max={result.spec.monitor.count_max}, "
                 f"seed {result.spec.seed})", fontsize=10)
    fig.tight_layout()
    for ax in axes[0]:  # on the final layout: head-room above the bars and their counts
        legend_clear_of_data(ax, fontsize=8, loc="upper left")
    out = _save(fig, path)
    plt.close(fig)
    return out


def error_traces(result: CampaignResult, path: Path) -> list[Path]:
    """Normalised error (top) and fault counter (bottom) of the first run of each range, per MBIT."""
    from firmware_sim.condition_monitor import evaluate

    plt = pyplot()
    keys = list(result.mbits)
    fig, axes = plt.subplots(2, len(keys), figsize=(5.2 * len(keys), 5.6), squeeze=False, sharex="col")
    mon = result.spec.monitor
    for col, key in enumerate(keys):
        runs = result.mbits[key]
        for i, r in enumerate(result.spec.ranges):
            idx = np.flatnonzero(result.range_index == i)
            if idx.size == 0:
                continue
            k = idx[0]
            trace = evaluate(runs.eps[k], mon, runs.t)
            color = f"C{i % 10}"
            axes[0, col].plot(runs.t, runs.eps[k], color=color, lw=0.9, label=r.label)
            axes[1, col].plot(runs.t, trace.count, color=color, lw=0.9)
            if trace.fault_index >= 0:
                axes[1, col].plot(runs.t[trace.fault_index], trace.count[trace.fault_index], "x", color=color)
        axes[0, col].axhline(mon.eps_th, color="k", ls="--", lw=0.8, label=f"eps_th = {mon.eps_th:g}")
        axes[1, col].axhline(mon.count_max, color="k", ls="--", lw=0.8, label=f"count_max = {mon.count_max}")
        axes[0, col].set_title(f"{runs.label}: first run of each range")
        axes[0, col].set_ylabel("normalised error eps (Eq. 11)")
        axes[1, col].set_ylabel("fault counter")
        axes[1, col].set_xlabel("time (s)")
    fig.tight_layout()
    for ax in axes.ravel():  # on the final layout: head-room above the traces
        legend_clear_of_data(ax, fontsize=7, ncol=2)
    out = _save(fig, path, svg=False)
    plt.close(fig)
    return out


def roc(tables: list[RocTable], path: Path, mark: tuple[float, int] | None = None) -> list[Path]:
    """Top: detection against false-alarm probability, one curve per count_max over the eps_th grid.
    Bottom: both probabilities against eps_th (solid: detection, dashed: false alarm) — where to set the threshold."""
    plt = pyplot()
    fig, axes = plt.subplots(2, len(tables), figsize=(5.6 * len(tables), 8.8), squeeze=False)
    eps_labels: list[list] = []
    for col, tab in enumerate(tables):
        ax, ax2 = axes[0, col], axes[1, col]
        pfa, pd = tab.p_false_alarm, tab.p_detection
        for j, c in enumerate(tab.count_max):
            color = f"C{j % 10}"
            ax.plot(100 * pfa[:, j], 100 * pd[:, j], "-o", ms=2.5, lw=1.0, color=color, label=f"count_max = {c}")
            ax2.plot(tab.eps_th, 100 * pd[:, j], "-", lw=1.2, color=color, label=f"count_max = {c}")
            ax2.plot(tab.eps_th, 100 * pfa[:, j], "--", lw=1.0, color=color)
        if mark is not None:
            e_i = np.flatnonzero(np.isclose(tab.eps_th, mark[0]))
            c_i = np.flatnonzero(tab.count_max == mark[1])
            if e_i.size and c_i.size:
                ax.plot(100 * pfa[e_i[0], c_i[0]], 100 * pd[e_i[0], c_i[0]], "r*", ms=12,
                        label=f"Table 3 (eps_th {mark[0]:g}, count_max {mark[1]})")
            ax2.axvline(mark[0], color="r", lw=0.8, ls=":", label=f"Table 3 eps_th = {mark[0]:g}")
        j = len(tab.count_max) // 2
        eps_labels.append([ax.annotate(f"{tab.eps_th[i]:.3g}", (100 * pfa[i, j], 100 * pd[i, j]), fontsize=6,
                                       textcoords="offset points", xytext=(3, -8))
                           for i in range(0, tab.eps_th.size, max(1, tab.eps_th.size // 6))])
        ax.set_xlim(-2, 102)
        ax.set_ylim(-2, 102)
        ax.set_xlabel(f"false-alarm probability (%): units within {100 * tab.healthy_max:g} % (n={tab.n_healthy})")
        ax.set_ylabel(f"detection probability (%): units from {100 * tab.faulty_min:g} % (n={tab.n_degraded})")
        ax.set_title(f"{tab.label}: ROC over eps_th (labels) and count_max", fontsize=10)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="lower right")
        ax2.set_xlabel("normalised error threshold eps_th")
        ax2.set_ylabel("probability (%): detection solid, false alarm dashed")
        ax2.set_ylim(-2, 102)
        ax2.grid(alpha=0.3)
        ax2.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)  # beside the curves
    fig.tight_layout()
    for col, labels in enumerate(eps_labels):  # points that coincide (few runs) would stack their labels
        hide_colliding_texts([axes[0, col].get_legend(), *labels])
    out = _save(fig, path, svg=False)
    plt.close(fig)
    return out
