"""Prognostics figures: remaining useful life against time, with the truth and its α-λ cone when known.

Plain arrays in (hours, predicted remaining life with its 90 % interval), a PNG out; no knowledge of what made the
predictions. The α-λ cone is Saxena et al.'s (2010, ProgPy's ``alpha_lambda``): the true remaining life
RUL*(t) = t_EOL − t and the band (1 ± α)·RUL*(t) a good prediction stays inside; the λ points t_λ are marked.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from reporting.figures import pyplot, save_figure


def _nan(xs: Sequence[float | None]) -> np.ndarray:
    return np.array([np.nan if x is None else float(x) for x in xs], float)


def plot_remaining_life(path: Path, as_of_hours: Sequence[float], rul_median_hours: Sequence[float | None],
                        rul_low_hours: Sequence[float | None], rul_high_hours: Sequence[float | None],
                        dated: Sequence[bool], *, lower_bound_hours: Sequence[float | None] | None = None,
                        true_eol_hours: float | None = None, alpha: float = 0.2,
                        lambda_hours: Sequence[tuple[float, float]] = (), horizon_note: str | None = None) -> None:
    """Predicted remaining life (h) against the time it was predicted (h): median and 90 % interval of each dated
    prediction; a prediction without a date (no significant trend) as its lower bound (▲, "at least");
    with ``true_eol_hours`` the true remaining life and its ±``alpha`` cone; ``lambda_hours`` (λ, t_λ) marked."""
    plt = pyplot()
    t = np.asarray(as_of_hours, float)
    med, lo, hi = _nan(rul_median_hours), _nan(rul_low_hours), _nan(rul_high_hours)
    ok = np.asarray(dated, bool)
    fig, ax = plt.subplots(figsize=(8.0, 4.4), layout="constrained")
    if true_eol_hours is not None and t.size:
        tt = np.linspace(min(float(t.min()), true_eol_hours) - 0.0, true_eol_hours, 200)
        r = true_eol_hours - tt
        ax.fill_between(tt, (1 - alpha) * r, (1 + alpha) * r, color="C2", alpha=0.18,
                        label=f"α-λ cone (true RUL ± {100 * alpha:.0f} %)")
        ax.plot(tt, r, color="C2", lw=1.6, label="true remaining life")
        for lam, t_lam in lambda_hours:
            ax.axvline(t_lam, color="0.4", ls=":", lw=1)
            ax.annotate(f"λ = {lam:g}", (t_lam, 1.0), xycoords=("data", "axes fraction"), xytext=(3, -12),
                        textcoords="offset points", fontsize=8, color="0.3")
    if ok.any():
        yerr = np.vstack([np.where(np.isfinite(lo), med - lo, 0.0), np.where(np.isfinite(hi), hi - med, 0.0)])[:, ok]
        ax.errorbar(t[ok], med[ok], yerr=yerr, fmt="o", color="C0", ms=5, capsize=3,
                    label="predicted remaining life (median, 90 % interval)")
        open_top = ok & ~np.isfinite(hi) & np.isfinite(med)
        if open_top.any():
            ax.plot(t[open_top], med[open_top], "^", color="C0", ms=7, mfc="none",
                    label="upper end beyond the forecast horizon")
    if lower_bound_hours is not None:
        lb = _nan(lower_bound_hours) - t
        nd = ~ok & np.isfinite(lb)
        if nd.any():
            ax.plot(t[nd], lb[nd], "^", color="0.45", ms=6, label="no significant trend: remaining life at least")
    ax.set_xlabel("operating time of the prediction (h)")
    ax.set_ylabel("remaining useful life (h)")
    ax.set_ylim(bottom=0)
    ax.grid(alpha=0.3)
    if horizon_note:
        ax.set_title(horizon_note, fontsize=9)
    handles, labels = ax.get_legend_handles_labels()
    if handles:
        fig.legend(handles, labels, loc="outside lower center", ncols=2, fontsize=8, frameon=False)
    save_figure(fig, path, dpi=110)
