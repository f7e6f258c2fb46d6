"""What a planner reads: the four levels in words, the figures and ``report.html``; ``health.json`` first."""

from __future__ import annotations

import html
import json
from pathlib import Path

import numpy as np

from board_config.json_values import to_jsonable
from reporting.figures import pyplot, save_figure
from reporting.html_page import img_tag
from studies.health.assess import Assessment


def four_levels_text(a: Assessment) -> str:
    lv = a.doc["levels"]
    return "\n".join([
        f"DETECTED?  {lv['detected']}",
        f"WHERE?     {lv['where']}",
        f"HOW MUCH?  {lv['how_much']}",
        f"HOW LONG?  {lv['how_long']}",
    ])


def health_json(a: Assessment) -> str:
    return json.dumps(to_jsonable(a.doc), indent=2)


def plot_parameters(a: Assessment, path: Path) -> None:
    plt = pyplot()
    names = list(a.trends)
    fig, axes = plt.subplots(len(names) + 1, 1, figsize=(8, 2.6 * (len(names) + 1)), constrained_layout=True)
    hours = np.array([v.operating_hours for v in a.visits])
    fc = a.forecast
    h_end = min(fc.horizon_hours, max(hours[-1] * 2.0, (fc.trip_interval_90[1] or hours[-1]) * 1.1)
                if fc.trip_interval_90 else hours[-1] * 2.0)
    hh = np.linspace(hours[0], h_end, 300)
    rng = np.random.default_rng(0)
    for ax, n in zip(axes, names):
        t = a.trends[n]
        y = [next(x for x in e["estimates"] if x["name"] == n) for e in a.estimates]
        rel = np.array([100 * (x["value"] / x["nominal"] - 1) for x in y])
        se = np.array([100 * (x["stderr"] or 0) / abs(x["nominal"]) for x in y])
        ax.errorbar(hours, rel, yerr=2 * se, fmt="o", ms=4, color="k", label="visit estimate (±2 s.e.)")
        med, lo, hi = t.band(hh, rng)
        ax.plot(hh, 100 * med, color="C0", label=f"trend: {t.model}" + ("" if t.significant else " (not significant)"))
        ax.fill_between(hh, 100 * lo, 100 * hi, color="C0", alpha=0.2, label="90 % band")
        if n == "alpha_h":
            k3c = a.trends["k3"].best.predict(hh) if "k3" in a.trends else np.zeros_like(hh)
            bc = a.trends["beta_h"].best.predict(hh) if "beta_h" in a.trends else np.zeros_like(hh)
            lo_l, hi_l = a.boundary.alpha_limits(k3c, bc)
            ax.plot(hh, 100 * hi_l, "r--", label="monitor trip limit")
            ax.plot(hh, 100 * lo_l, "r--")
            ax.set_ylim(min(-12, rel.min() - 2), max(20, 100 * float(np.max(hi)) + 2))
        ax.set_ylabel(f"{n} change (%)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="best")
    ax = axes[-1]
    trips = fc.trip_samples[np.isfinite(fc.trip_samples)]
    if trips.size:
        ax.hist(trips, bins=40, color="C3", alpha=0.7, label="sampled trip times")
    if fc.trip_interval_90:
        for x in fc.trip_interval_90:
            if x is not None:
                ax.axvline(x, color="k", ls=":")
    bf = a.doc.get("board_first_fault")
    if bf:
        ax.axvline(bf["operating_hours"], color="r", label=f"board's first FAULT (visit {bf['visit']})")
    ax.axvline(hours[-1], color="gray", ls="--", label="last visit used")
    ax.set_xlabel("operating time (h)")
    ax.set_ylabel("trip-time samples")
    ax.legend(fontsize=7)
    for ax in axes:
        ax.set_xlim(hours[0] - 10, h_end)
    save_figure(fig, path, 110)


def write_health_outputs(a: Assessment, out: Path, text: str) -> dict[str, str]:
    """health.json (first), then health.png and report.html; returns the artefacts that failed."""
    (out / "health.json").write_text(health_json(a))
    (out / "levels.txt").write_text(text + "\n")
    failed: dict[str, str] = {}
    try:
        plot_parameters(a, out / "health.png")
    except Exception as exc:  # a figure must not lose the numbers
        failed["health.png"] = f"{type(exc).__name__}: {exc}"
    try:
        img = img_tag(out / "health.png") if (out / "health.png").exists() else ""
        rows = "".join(
            f"<tr><td>{v['visit']}</td><td>{v['operating_hours']:g}</td><td>{v['board_verdict'] or ''}</td>"
            + "".join(f"<td>{100 * e['relative']:+.2f} ± {100 * (e['stderr'] or 0) / abs(e['nominal']):.2f} %</td>"
                      for e in v["estimates"]) + "</tr>" for v in a.doc["visits"])
        heads = "".join(f"<th>{html.escape(n)}</th>" for n in a.trends)
        lv = "".join(f"<p><b>{k.replace('_', ' ').upper()}?</b> {html.escape(v)}</p>"
                     for k, v in a.doc["levels"].items())
        loc = a.doc.get("location") or {}
        loc_html = ""
        if loc.get("run"):
            crow = "".join(
                f"<tr><td>{html.escape(c['name'])}</td><td>{c.get('section') or ''}</td>"
                + (f"<td>{100 * c['relative']:+.2f} ± {100 * (c.get('relative_stderr') or 0):.2g} %</td>"
                   if "relative" in c else "<td></td>")
                + (f"<td>{c['held_rss_sigma2']:.0f}</td>" if "held_rss_sigma2" in c
                   else f"<td>{html.escape(c.get('error', ''))}</td>") + "</tr>" for c in loc["candidates"])
            loc_html = (f"<h2>Where? (visit at {loc.get('operating_hours')} h)</h2><p>{html.escape(loc['reason'])}</p>"
                        "<table border=1 cellpadding=3><tr><th>freed alone (with α_h, β_h)</th><th>section</th>"
                        f"<th>change</th><th>held-out RSS (σ²)</th></tr>{crow}</table>")
        page = (f"<!doctype html><meta charset='utf-8'><title>shm health</title><h1>Health over time</h1>{lv}"
                + img
                + loc_html
                + f"<h2>Visits</h2><table border=1 cellpadding=3><tr><th>visit</th><th>h</th><th>board</th>{heads}"
                f"</tr>{rows}</table><h2>JSON</h2><pre>{html.escape(health_json(a))}</pre>")
        (out / "report.html").write_text(page)
    except Exception as exc:
        failed["report.html"] = f"{type(exc).__name__}: {exc}"
    return failed
