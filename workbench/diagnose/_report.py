"""Figures and a self-contained HTML page for ``shm diagnose`` and ``shm fit``.

* ranking: held-out residual (RMS, in units of the noise level σ) of the nominal model and of every candidate,
  accepted ones highlighted, with the held-out error reduction and ΔBIC;
* overlay: measured, nominal model and the improved model on every record channel, held-out blocks shaded,
  and the residuals before/after in σ units;
* fit progress: the training error (σ) against the optimiser's iterations, with the noise floor and the
  starting level — updated while the fit runs.
"""

from __future__ import annotations

import html
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from reporting.figure_layout import count_axis, legend_clear_of_data
from reporting.figures import display_scale, pyplot, save_figure
from reporting.html_page import img_tag, table
from workbench.fit import FitHistoryPoint, SimBatch, Target


def _save(fig, path: Path) -> Path:
    return save_figure(fig, path, 90)


def _held_spans(tg: Target) -> list[tuple[float, float]]:
    spans = []
    k = tg.held.astype(int)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], k, [0]])))
    for a, b in zip(edges[::2], edges[1::2]):
        spans.append((float(tg.t[a]), float(tg.t[min(b, tg.t.size - 1)])))
    return spans


def overlay_figure(targets: Sequence[Target], before: SimBatch, after: SimBatch | None, path: Path,
                   label_after: str = "improved model") -> Path:
    plt = pyplot()
    rows = [(i, j) for i, tg in enumerate(targets) for j in range(len(tg.channels))]
    fig, axes = plt.subplots(2 * len(rows), 1, figsize=(11, 3.2 * len(rows) + 1.2), squeeze=False)
    for r, (i, j) in enumerate(rows):
        tg = targets[i]
        s, su = display_scale(tg.units[j])
        ax, axr = axes[2 * r, 0], axes[2 * r + 1, 0]
        for a, b in _held_spans(tg):
            ax.axvspan(a, b, color="0.85", lw=0)
            axr.axvspan(a, b, color="0.85", lw=0)
        ax.plot(tg.t, tg.measured[j] * s, color="k", lw=0.8, label="measured")
        ax.plot(tg.t, before.y[i][0, j] * s, color="tab:red", lw=0.9, label="nominal model")
        e0 = (tg.measured[j] - before.y[i][0, j]) / tg.sigma[j]
        axr.plot(tg.t, e0, color="tab:red", lw=0.7, label="nominal")
        if after is not None:
            ax.plot(tg.t, after.y[i][0, j] * s, color="tab:blue", lw=0.9, ls="--", label=label_after)
            e1 = (tg.measured[j] - after.y[i][0, j]) / tg.sigma[j]
            axr.plot(tg.t, e1, color="tab:blue", lw=0.7, label=label_after)
        ax.set_ylabel(f"{tg.channels[j]} ({su})")
        ax.set_title(f"{tg.name} ({tg.record.test}) — grey: held-out blocks", fontsize=9)
        axr.set_ylabel("residual (σ)")
        axr.axhline(0, color="0.5", lw=0.5)
    axes[-1, 0].set_xlabel("time (s)")
    fig.tight_layout()
    for ax in axes[:, 0]:  # on the final layout: head-room above the data for each legend
        legend_clear_of_data(ax, fontsize=7)
    return _save(fig, path)


def ranking_figure(diagnosis: Any, path: Path) -> Path:
    plt = pyplot()
    ranking = diagnosis.ranking
    names = ["nominal"] + [c.effect for c in ranking]
    vals = [diagnosis.baseline_held_rms_sigma] + [c.held_rms_sigma for c in ranking]
    colours = ["0.6"] + ["tab:green" if c.accepted else ("tab:red" if not c.stable else "tab:orange")
                         for c in ranking]
    fig, ax = plt.subplots(figsize=(9, 0.45 * len(names) + 1.6))
    y = np.arange(len(names))[::-1]
    vals_plot = [v if np.isfinite(v) else 0.0 for v in vals]
    ax.barh(y, vals_plot, color=colours)
    ax.axvline(1.0, color="k", ls=":", lw=1, label="noise floor (1 σ)")
    ax.set_yticks(y, names)
    ax.set_xscale("log")
    # explicit limits with room on the right for the labels: when every value sits near the noise floor, the
    # automatic log limits span a hair (1.003 .. 1.005 σ) and the labels run far outside the axes, which made
    # tight_layout give up (a UserWarning) and the figure unreadable
    positive = [v for v in vals_plot if v > 0] or [1.0]
    left = min(min(positive), 1.0) / 1.5
    ax.set_xlim(left, max(max(positive), 1.0) * 30.0)
    for yi, c in zip(y[1:], ranking):
        ax.text(max(c.held_rms_sigma if np.isfinite(c.held_rms_sigma) else 0.0, left) * 1.03, yi,
                " " + _ranking_label(c), va="center", fontsize=7)
    ax.set_xlabel("held-out residual RMS (σ)")
    ax.set_title("Which effect is missing? (green: accepted, orange: not enough, red: unstable)", fontsize=9)
    ax.legend(fontsize=7, loc="lower right")
    fig.tight_layout()
    return _save(fig, path)


def _ranking_label(c: Any) -> str:
    """What a ranking bar says: the held-out reduction and ΔBIC of a scored candidate, else why it has none
    (screened out, rejected) — never a nan or inf."""
    scored = c.stable and np.isfinite(c.held_reduction) and np.isfinite(c.delta_bic_held)
    if scored:
        return f"{100 * c.held_reduction:+.1f} %, ΔBIC {c.delta_bic_held:.3g}"
    why = c.rejection or getattr(c, "status", "") or "not scored"
    return why[:60] if why.startswith("screened out") else f"rejected: {why[:50]}"


class ProgressPlot:
    """The training error against iterations, re-drawn to ``path`` at most every ``min_interval_s`` while a fit
    runs (open the PNG in a viewer that reloads), and once more at the end."""

    def __init__(self, path: Path, start_rms: float, held_before: float, min_interval_s: float = 1.0):
        self.path = Path(path)
        self.start = start_rms
        self.held_before = held_before
        self.min_interval_s = min_interval_s
        self.points: list[FitHistoryPoint] = []
        self._last = 0.0

    def add(self, pt: FitHistoryPoint) -> None:
        self.points.append(pt)
        now = time.monotonic()
        if now - self._last >= self.min_interval_s:
            self.draw()
            self._last = now

    def draw(self, held_after: float | None = None) -> Path:
        plt = pyplot()
        fig, ax = plt.subplots(figsize=(7, 4))
        it = [0] + [p.iteration for p in self.points]
        err = [self.start] + [p.train_rms_sigma for p in self.points]
        ax.plot(it, err, "o-", color="tab:blue", ms=3, label="training error (best so far)")
        ax.axhline(1.0, color="k", ls=":", lw=1, label="noise floor (1 σ)")
        ax.axhline(self.start, color="tab:red", ls="--", lw=0.8, label=f"before: {self.start:.3g} σ")
        if held_after is not None:
            ax.plot([it[-1]], [held_after], "s", color="tab:green", label=f"held-out after: {held_after:.3g} σ")
            ax.plot([0], [self.held_before], "s", color="tab:orange",
                    label=f"held-out before: {self.held_before:.3g} σ")
        ax.set_yscale("log")
        count_axis(ax.xaxis)
        ax.set_xlabel("iteration")
        ax.set_ylabel("residual RMS (σ)")
        ax.set_title("Error falling while the fit runs", fontsize=9)
        ax.legend(fontsize=7)
        fig.tight_layout()
        return _save(fig, self.path)


_CSS = ("body{font-family:sans-serif;max-width:1100px;margin:auto;padding:1em}table{border-collapse:collapse;"
        "font-size:13px;margin:0.5em 0}td,th{border:1px solid #bbb;padding:2px 6px;text-align:left}"
        ".verdict{font-size:15px;background:#f4f4f4;padding:0.6em;border-left:4px solid #36c}")


def write_html(path: Path, title: str, verdict: str, tables: Sequence[tuple[str, Sequence[str], Sequence]],
               images: Sequence[Path], notes: Sequence[str] = ()) -> Path:
    parts = [f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{html.escape(title)}</title>",
             f"<style>{_CSS}</style></head><body><h1>{html.escape(title)}</h1>",
             f"<p class='verdict'>{html.escape(verdict)}</p>"]
    for caption, header, rows in tables:
        parts.append(f"<h2>{html.escape(caption)}</h2>{table(header, rows)}")
    for img in images:
        parts.append(img_tag(img))
    if notes:
        parts.append("<h2>Notes</h2><ul>" + "".join(f"<li>{html.escape(n)}</li>" for n in notes) + "</ul>")
    parts.append("</body></html>")
    path.write_text("\n".join(parts), encoding="utf-8")
    return path
