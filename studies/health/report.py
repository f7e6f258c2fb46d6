"""What a planner reads: the four levels in words, the figures and ``report.html`` (:mod:`.page`); ``health.json``
first."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from board_config.json_values import to_jsonable
from studies.health.assess import Assessment
from studies.health.figures import plot_forecast, plot_life_remaining, plot_parameters
from studies.health.page import health_page


def four_levels_text(a: Assessment) -> str:
    lv = a.doc["levels"]
    fol = a.doc.get("followed") or {}
    return "\n".join([
        *([f"FOLLOWED   {fol['why']}"] if fol.get("why") else []),
        f"DETECTED?  {lv['detected']}",
        f"WHERE?     {lv['where']}",
        f"HOW MUCH?  {lv['how_much']}",
        f"HOW LONG?  {lv['how_long']}",
    ])


def evaluation_text(ev: dict[str, Any]) -> str:
    """The --evaluate scores in a few lines (``ev``: health.json's ``evaluation``, the JSON document)."""
    ph = ev["prognostic_horizon_hours"]
    lines = [f"EVALUATED  against the true first FAULT at {ev['true_first_fault_hours']:g} h (visit "
             f"{ev.get('true_first_fault_visit')}; {ev.get('truth_source')}): {ev['dated_predictions']} dated "
             f"predictions from {ev['first_prediction_hours']:g} h" if ev["first_prediction_hours"] is not None else
             f"EVALUATED  against the true first FAULT at {ev['true_first_fault_hours']:g} h: no prediction with a "
             "date before it"]
    for p in ev["alpha_lambda"]:
        verdict = "no prediction at or after it" if p["ok"] is None else ("met" if p["ok"] else "MISSED")
        ra = "" if p["relative_accuracy"] is None else f", relative accuracy {p['relative_accuracy']:.2f}"
        at = "" if p["prediction_hours"] is None else f" (prediction at {p['prediction_hours']:g} h{ra})"
        lines.append(f"  alpha-lambda (alpha {ev['alpha']:g}, lambda {p['lambda']:g}, t_lambda "
                     f"{p['t_lambda_hours'] if p['t_lambda_hours'] is None else round(p['t_lambda_hours'])} h): "
                     f"{verdict}{at}")
    cov = ev["coverage_90"]
    ra = ev["relative_accuracy_mean"]
    lines.append(f"  prognostic horizon: {'none' if ph is None else f'{ph:.0f} h'}; relative accuracy (mean over "
                 f"dated predictions): {'-' if ra is None else f'{ra:.2f}'}; 90 % interval holds the first FAULT in "
                 f"{'-' if cov is None else f'{100 * cov:.0f} %'} of them")
    return "\n".join(lines)


def health_json(a: Assessment) -> str:
    return json.dumps(to_jsonable(a.doc), indent=2)


def write_health_outputs(a: Assessment, out: Path, text: str) -> dict[str, str]:
    """health.json (first), levels.txt, the figures and report.html; returns the artefacts that failed."""
    (out / "health.json").write_text(health_json(a))
    (out / "levels.txt").write_text(text + "\n")
    failed: dict[str, str] = {}
    figures = {"health.png": plot_parameters, "forecast.png": plot_forecast,
               "remaining_life.png": plot_life_remaining}
    paths: dict[str, Path] = {}
    for name, draw in figures.items():
        try:
            draw(a, out / name)
            paths[name] = out / name
        except Exception as exc:  # a figure must not lose the numbers
            failed[name] = f"{type(exc).__name__}: {exc}"
    try:
        (out / "report.html").write_text(health_page(a.doc, paths, ["health.json", "levels.txt", *paths]))
    except Exception as exc:
        failed["report.html"] = f"{type(exc).__name__}: {exc}"
    return failed
