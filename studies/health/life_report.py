"""The life-level report of ``shm run`` on a ``[life]`` scenario: ``life.png`` and ``report.html`` in the run's
directory — how the truth degraded visit by visit, what the board's MBITs saw (largest normalised error, fault
counter, verdict), and where the first FAULT came. Built from the life summary (``life.json``'s document) alone."""

from __future__ import annotations

import html
from pathlib import Path
from typing import Any

import numpy as np

from reporting.figures import pyplot, save_figure
from reporting.html_page import img_tag, page, table
from studies.batch.runner import counted
from studies.health.page import CSS


# ``summary``: life.json as written (:func:`.life.write_life_log`; the JSON document at the edge), so that a life's
# report can be rebuilt from its files
def plot_life(summary: dict[str, Any], path: Path) -> None:
    """Truth deviations (%) and each MBIT's largest normalised error against operating hours; FAULTs marked."""
    plt = pyplot()
    visits = summary["visits"]
    h = np.array([v["operating_hours"] for v in visits], float)
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(8, 5.6), sharex=True, layout="constrained")
    names = sorted({k for v in visits for k in v["truth_deviations"]})
    for n in names:
        ax1.plot(h, [100 * v["truth_deviations"].get(n, 0.0) for v in visits], "o-", ms=3, label=n)
    ax1.set_ylabel("true change (%)")
    labels = sorted({m["label"] for v in visits for m in v["mbits"]})
    for j, lab in enumerate(labels):
        eps = np.array([next((m["max_eps"] for m in v["mbits"] if m["label"] == lab), np.nan) for v in visits])
        bad = np.array([any(m["label"] == lab and m["verdict"] == "FAULT" for m in v["mbits"]) for v in visits])
        ax2.plot(h, eps, "-", color=f"C{j}", lw=1, label=f"{lab} largest normalised error")
        ax2.plot(h[~bad], eps[~bad], "o", color=f"C{j}", ms=4)
        if bad.any():
            ax2.plot(h[bad], eps[bad], "X", color="C3", ms=8, label=f"{lab} FAULT")
    ax2.set_ylabel("max ε (MBIT)")
    ax2.set_xlabel("operating time (h)")
    first = summary.get("first_fault_operating_hours")
    for ax in (ax1, ax2):
        if first is not None:
            ax.axvline(first, color="C3", ls="--", lw=1, label="first FAULT" if ax is ax1 else None)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0)
    save_figure(fig, path, dpi=110)


def life_page(summary: dict[str, Any], figure: Path | None, out_name: str = "DIR") -> str:
    """report.html of a life run."""
    visits = summary["visits"]
    first = summary.get("first_fault_visit")
    names = sorted({k for v in visits for k in v["truth_deviations"]})
    labels = sorted({m["label"] for v in visits for m in v["mbits"]})
    rows = []
    for v in visits:
        cells = [str(v["visit"]), f"{v['operating_hours']:g}"]
        cells += [f"{100 * v['truth_deviations'].get(n, 0.0):+.2f} %" for n in names]
        for lab in labels:
            m = next((m for m in v["mbits"] if m["label"] == lab), None)
            cells.append("" if m is None else f"{m['verdict']} (ε {m['max_eps']:.3f}, counter {m['max_count']})")
        verdict = html.escape(v["verdict"])
        cells.append(f"<span class='bad'>{verdict}</span>" if v["verdict"] == "FAULT" else verdict)
        cells.append(" ".join(f"<a href='{html.escape(r)}'>{html.escape(Path(r).name)}</a>" for r in v["records"]))
        rows.append([c if c.startswith("<") else html.escape(c) for c in cells[:-2]] + cells[-2:])
    head = ["visit", "h", *[f"true {n}" for n in names], *labels, "board", "records"]
    cls = "alert" if first else "ok"
    answer = (f"visit {first} at {summary['first_fault_operating_hours']:g} h" if first else "never in this life")
    cards = ("<div class='levels'>"
             f"<div class='card {cls}'><h3>FIRST FAULT</h3><div class='answer'>{html.escape(answer)}</div>"
             "<p>the board's own maintenance verdict (MBIT.a / MBIT.b through the condition monitor)</p></div>"
             f"<div class='card'><h3>VISITS</h3><div class='answer'>{len(visits)} every "
             f"{summary['visit_interval_h']:g} h</div><p>{summary['flights_between_visits']} flights between visits"
             f"; seed {summary['seed']}, params {html.escape(str(summary['params']))}</p></div>"
             f"<div class='card'><h3>RUN</h3><div class='answer'>{summary['wall_s']:.1f} s wall</div>"
             f"<p>{counted(summary['workers'], 'worker')}; every visit a full board run (100 Hz firmware, simulated "
             "rig, link, MBITs, monitor)</p></div></div>")
    body = ["<main>", f"<h1>A life: {html.escape(summary['scenario'])}</h1>",
            f"<p class='sub'>{html.escape(summary['scenario_file'])}</p>",
            (f"<p class='note'><b>interrupted</b>: {len(summary['visits'])} of {summary.get('visits_planned', '?')} "
             "visits finished before the stop (SIGTERM / Ctrl-C); the page shows those</p>"
             if summary.get("status") == "interrupted" else ""), cards,
            "<h2>The truth and what the board saw, visit by visit</h2>",
            img_tag(figure) if figure is not None and figure.exists() else "<p class='note'>(life.png could not be "
            "drawn)</p>",
            "<p class='note'>What comes next: <code>shm health " + html.escape(out_name) + " --evaluate</code> "
            "re-estimates the health parameters from each visit's records, forecasts the first FAULT and scores "
            "the forecast against it (docs/health.md).</p>",
            "<h2>Visits</h2>", table(head, rows, raw=True),
            "<footer>Machine-readable: <a href='life.json'>life.json</a> · <a href='summary.json'>summary.json</a> · "
            "<a href='timeline.txt'>timeline.txt</a> · <code>usage.db</code> (tables life_visits, mbit_records)"
            "</footer>", "</main>"]
    return page(f"shm run: life {summary['scenario']}", CSS + "td{white-space:nowrap}", body)


def write_life_report(summary: dict[str, Any], out: Path, out_name: str = "DIR") -> dict[str, str]:
    """life.png and report.html in ``out``; returns the artefacts that could not be written (name: why)."""
    failed: dict[str, str] = {}
    fig: Path | None = out / "life.png"
    try:
        plot_life(summary, out / "life.png")
    except Exception as exc:  # a figure must not cost the page
        failed["life.png"] = f"{type(exc).__name__}: {exc}"
        fig = None
    try:
        (out / "report.html").write_text(life_page(summary, fig, out_name))
    except Exception as exc:
        failed["report.html"] = f"{type(exc).__name__}: {exc}"
    return failed
