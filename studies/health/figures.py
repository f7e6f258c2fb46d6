"""The health page's figures: each parameter against operating hours, the forecast of the first FAULT, remaining life
against time. Drawn with the report layer (:mod:`reporting.figures`, :mod:`reporting.prognostics_figures`)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from reporting.figures import pyplot, save_figure
from reporting.prognostics_figures import plot_remaining_life

if TYPE_CHECKING:
    from studies.health.assess import Assessment

#: how each health parameter is called on the page
LABEL = {"k3": "k3 (tip section stiffness)", "alpha_h": "α_h (hysteresis linearity)",
         "beta_h": "β_h (hysteresis shape)"}


def _h_end(a: Assessment, hours: np.ndarray) -> float:
    fc = a.forecast
    end = hours[-1] * 1.6 + 100.0
    if fc.trip_interval_90 and fc.trip_interval_90[1] is not None:
        end = max(end, fc.trip_interval_90[1] * 1.1)
    bf = (a.doc.get("truth") or {}).get("first_fault") or a.doc.get("board_first_fault")
    if bf and bf.get("operating_hours") is not None:
        end = max(end, bf["operating_hours"] * 1.1)
    return float(min(fc.horizon_hours, end))


def _truth_series(a: Assessment, name: str) -> tuple[np.ndarray, np.ndarray] | None:
    rows = (a.doc.get("truth") or {}).get("visits") or []
    if not rows or any(name not in r["relative"] for r in rows):
        return None
    return (np.array([r["operating_hours"] for r in rows]), np.array([100 * r["relative"][name] for r in rows]))


def plot_parameters(a: Assessment, path: Path) -> None:
    """One panel per health parameter: the visit estimates (±2 s.e.), the chosen trend and its 90 % band, the truth
    when the records carry it, and on α_h the monitor's trip limits."""
    plt = pyplot()
    names = list(a.trends)
    fig, axes = plt.subplots(len(names), 1, figsize=(8, 2.7 * len(names)), layout="constrained", squeeze=False)
    hours = np.array([v.operating_hours for v in a.visits])
    h_end = _h_end(a, hours)
    hh = np.linspace(hours[0], h_end, 300)
    rng = np.random.default_rng(0)
    for ax, n in zip(axes[:, 0], names):
        t = a.trends[n]
        src = a.estimates if n in a.estimates[0].names() else (a.followed_estimates or [])
        y = [e.parameter(n) for e in src]
        own = y[0].nominal == 0.0  # an added effect's parameter: in its own unit, trended as such
        scale = 1.0 if own else 100.0
        rel = np.array([x.value if own else 100 * (x.value / x.nominal - 1) for x in y])
        se = np.array([scale * (x.stderr or 0) / (1.0 if own else abs(x.nominal)) for x in y])
        ax.errorbar(hours, rel, yerr=2 * se, fmt="o", ms=4, color="k", label="visit estimate (±2 s.e.)", zorder=3)
        med, lo, hi = t.band(hh, rng)
        ax.plot(hh, scale * med, color="C0", label=f"trend: {t.model}" + ("" if t.significant else
                                                                          " (not significant)"))
        ax.fill_between(hh, scale * lo, scale * hi, color="C0", alpha=0.2, label="90 % band")
        limit = (getattr(a, "effect_limits", None) or {}).get(n)
        if own and limit is not None and np.isfinite(limit):
            ax.axhline(limit, color="r", ls="--", label="monitor trip limit")
        truth = _truth_series(a, n)
        if truth is not None:
            ax.plot(*truth, "s--", color="C2", ms=3, lw=1, label="truth (from the records)", zorder=2)
        if n == "alpha_h":
            k3c = a.trends["k3"].best.predict(hh) if "k3" in a.trends else np.zeros_like(hh)
            bc = a.trends["beta_h"].best.predict(hh) if "beta_h" in a.trends else np.zeros_like(hh)
            lo_l, hi_l = a.boundary.alpha_limits(k3c, bc)
            ax.plot(hh, 100 * hi_l, "r--", label="monitor trip limit")
            ax.plot(hh, 100 * lo_l, "r--")
            ax.set_ylim(min(-12, rel.min() - 2), max(20, min(100 * float(np.max(hi)), 60) + 2))
        ax.axvline(hours[-1], color="0.6", ls=":", lw=1)
        ax.set_ylabel(f"{n} ({y[0].unit})" if own else "change (%)")
        ax.set_title(LABEL.get(n, n), fontsize=9, loc="left")
        ax.grid(alpha=0.3)
        ax.set_xlim(hours[0] - 10, h_end)
        ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0)
    axes[-1, 0].set_xlabel("operating time (h)")
    save_figure(fig, path, dpi=110)


def plot_forecast(a: Assessment, path: Path) -> None:
    """P(the monitor has said FAULT by h) with the 90 % interval of the trip time, the last visit, and the first
    FAULT (the board's, or the truth's) when known."""
    plt = pyplot()
    fc = a.forecast
    hours = np.array([v.operating_hours for v in a.visits])
    h_end = _h_end(a, hours)
    fig, ax = plt.subplots(figsize=(8, 3.4), layout="constrained")
    keep = fc.grid_hours <= h_end
    ax.plot(fc.grid_hours[keep], 100 * fc.p_fault[keep], color="C3", lw=2, label="P(FAULT by this time)")
    if fc.trip_interval_90:
        lo, hi = fc.trip_interval_90
        ax.axvspan(lo, hi if hi is not None else h_end, color="C3", alpha=0.15, label="90 % interval of the trip")
        if fc.trip_operating_hours is not None:
            ax.axvline(fc.trip_operating_hours, color="C3", ls="--", lw=1, label="median trip time")
    elif fc.lower_bound_hours is not None:
        ax.axvline(fc.lower_bound_hours, color="0.4", ls="--", label="no FAULT expected before (lower bound)")
    ax.axvline(hours[-1], color="0.6", ls=":", label="last visit used")
    ff = ((a.doc.get("truth") or {}).get("first_fault") or a.doc.get("board_first_fault"))
    if ff and ff.get("operating_hours") is not None:
        ax.axvline(ff["operating_hours"], color="k", lw=1.5, label=f"first FAULT (visit {ff.get('visit')})")
    ax.set_xlim(hours[0], h_end)
    ax.set_ylim(0, 102)
    ax.set_xlabel("operating time (h)")
    ax.set_ylabel("P(FAULT) (%)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0)
    save_figure(fig, path, dpi=110)


def plot_life_remaining(a: Assessment, path: Path) -> None:
    """Remaining life against time from :attr:`Assessment.sweep`, with the truth's cone when known."""
    rows = a.doc.get("remaining_life") or []
    ev = a.doc.get("evaluation")
    ff = (a.doc.get("truth") or {}).get("first_fault")
    t_eol = ff.get("operating_hours") if ff else None
    alpha = ev["alpha"] if ev else 0.2
    lam = [(p["lambda"], p["t_lambda_hours"]) for p in ev["alpha_lambda"] if p["t_lambda_hours"] is not None] \
        if ev else []
    note = None
    if ev:
        ph = ev["prognostic_horizon_hours"]
        note = (f"α-λ (α = {alpha:g}): " + ", ".join(f"λ={p['lambda']:g} {'met' if p['ok'] else 'missed'}"
                                                    for p in ev["alpha_lambda"] if p["ok"] is not None)
                + f"; prognostic horizon {'none' if ph is None else f'{ph:.0f} h'}")
    plot_remaining_life(path, [r["as_of_hours"] for r in rows], [r["rul_median_hours"] for r in rows],
                        [r["rul_interval_90"][0] for r in rows], [r["rul_interval_90"][1] for r in rows],
                        [r["significant"] for r in rows], lower_bound_hours=[r["lower_bound_hours"] for r in rows],
                        true_eol_hours=t_eol, alpha=alpha, lambda_hours=lam, horizon_note=note)
