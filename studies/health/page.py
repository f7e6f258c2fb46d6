"""``report.html`` of ``shm health``: the page an engineer reads — the four levels in words, the figures, the tables;
the JSON is linked, not printed. Pure: the assessment's document and the figure files in, one HTML string out."""

from __future__ import annotations

import html
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from reporting.html_page import img_tag, page, table
from reporting.uncertainty_text import format_percent_change
from studies.batch.runner import counted

# Every ``dict[str, Any]`` below is health.json as written (docs/health.md) or one of its sections: the page is
# rendered from the JSON document at the edge, so that it shows exactly what the linked file holds.

CSS = """
body{font-family:system-ui,-apple-system,'Segoe UI',Roboto,sans-serif;color:#1d2430;background:#f5f6f8;margin:0}
main{max-width:1080px;margin:0 auto;padding:18px 24px 40px}
h1{font-size:1.6em;margin:8px 0 2px}h2{font-size:1.2em;margin:28px 0 8px;border-bottom:1px solid #d5d9e0;
padding-bottom:4px}.sub{color:#5a6472;margin:0 0 14px}
.levels{display:grid;grid-template-columns:repeat(auto-fit,minmax(240px,1fr));gap:12px}
.card{background:#fff;border-radius:8px;padding:12px 14px;box-shadow:0 1px 3px rgba(0,0,0,.12);
border-top:4px solid #8a94a6}.card.alert{border-top-color:#c0392b}.card.ok{border-top-color:#27ae60}
.card.warn{border-top-color:#e67e22}.card h3{margin:0;font-size:.8em;letter-spacing:.06em;color:#5a6472}
.card .answer{font-size:1.2em;font-weight:600;margin:4px 0 6px}.card p{margin:0;font-size:.88em;line-height:1.4}
table{border-collapse:collapse;background:#fff;font-size:.86em;margin:6px 0;box-shadow:0 1px 2px rgba(0,0,0,.08)}
th,td{padding:4px 9px;border-bottom:1px solid #e3e6eb;text-align:left;vertical-align:top}
th{background:#eef0f4;font-weight:600}td.num{text-align:right;font-variant-numeric:tabular-nums;white-space:nowrap}
tr:nth-child(even) td{background:#fafbfc}img{max-width:100%;background:#fff;border-radius:6px;margin:6px 0}
.note{color:#5a6472;font-size:.85em}.bad{color:#c0392b;font-weight:600}.good{color:#1e8449;font-weight:600}
footer{margin-top:30px;font-size:.85em;color:#5a6472}
"""


def _pct(x: float | None, se: float | None = None) -> str:
    if x is None:
        return ""
    return format_percent_change(x, se) if se is not None else f"{100 * x:+.2f} %"


def _truth_pct(x: float) -> str:
    """A true change: exact, printed to 0.0001 % (the estimates beside it may be that precise)."""
    return f"{100 * x:+.4f} %"


def _h(x: float | None) -> str:
    return "—" if x is None else f"{x:.0f} h"


def _where_short(doc: dict[str, Any], detected: bool) -> str:
    if not detected:
        return "nothing to place"
    last = doc["visits"][-1]["estimates"]
    moved = {e["name"] for e in last if e["verdict"] == "changed"} | {n for n, t in doc["trend"].items()
                                                                     if t["significant"]}
    parts = ["patch hysteresis"] if moved & {"alpha_h", "beta_h"} else []
    loc = doc.get("location") or {}
    if loc.get("section"):
        parts.append(f"section {loc['section']} stiffness")
    elif loc.get("run") and loc.get("distinguishable") is False:
        parts.append("stiffness: section " + " or ".join(map(str, loc.get("possible_sections") or [])))
    elif moved - {"alpha_h", "beta_h"}:
        parts.append("stiffness (" + ", ".join(sorted(moved - {"alpha_h", "beta_h"})) + ")")
    return " + ".join(parts) or "not placed"


def _cards(doc: dict[str, Any]) -> str:
    lv = doc["levels"]
    f = doc["forecast"]
    detected = lv["detected"].startswith("yes")
    where = _where_short(doc, detected)
    last = doc["visits"][-1]
    big = max(last["estimates"], key=lambda e: abs(e["relative"]))
    if f.get("already_faulty"):
        long_ans, cls = "now: beyond the trip limit", "alert"
    elif f.get("trip_operating_hours") is not None:
        lo, hi = f["trip_interval_90"]
        long_ans = f"FAULT at ≈ {f['trip_operating_hours']:.0f} h ({lo:.0f}–{_h(hi)})"
        cls = "alert" if (f.get("p_fault_next_visit") or 0) > 0.05 else "warn"
    elif f.get("lower_bound_hours") is not None:
        long_ans, cls = f"no date: no FAULT before {f['lower_bound_hours']:.0f} h", "ok"
    else:
        long_ans, cls = "no FAULT within the horizon", "ok"
    cards = [("DETECTED?", "yes" if detected else "no", "alert" if detected else "ok", lv["detected"]),
             ("WHERE?", where, "warn" if detected else "ok", lv["where"]),
             ("HOW MUCH?", f"{big['name']} {_pct(big['relative'])}", "warn" if detected else "ok", lv["how_much"]),
             ("HOW LONG?", long_ans, cls, lv["how_long"])]
    return "<div class='levels'>" + "".join(
        f"<div class='card {c}'><h3>{t}</h3><div class='answer'>{html.escape(a)}</div><p>{html.escape(s)}</p></div>"
        for t, a, c, s in cards) + "</div>"


def _trend_table(doc: dict[str, Any]) -> str:
    last = doc["visits"][-1]
    truth_rows = (doc.get("truth") or {}).get("visits") or []
    truth_last = truth_rows[-1]["relative"] if truth_rows else None
    rows = []
    for e in last.get("followed_estimates") or last["estimates"]:
        t = doc["trend"].get(e["name"])
        if t is None:
            continue
        law = t["model"] + (f" (step at {t['change_point_hours']:g} h)" if t.get("change_point_hours") else "")
        if e["nominal"] == 0.0:  # an added effect's parameter, in its own unit
            se_s = f" ± {e['stderr']:.2g}" if e["stderr"] is not None else ""
            value = f"{e['value']:.3g}{se_s} {e['unit']}"
            rate = f"{100 * t['rate']:+.3g} {e['unit']}" if t["significant"] else "—"
            truth = ""
        else:
            se = e["stderr"] / abs(e["nominal"]) if e["stderr"] is not None else None
            value = _pct(e["value"] / e["nominal"] - 1.0, se)
            rate = f"{t['rate_per_100h_pct']:+.2f} %" if t["significant"] else "—"
            truth = _truth_pct(truth_last[e["name"]]) if truth_last and e["name"] in truth_last else ""
        rows.append([html.escape(e["name"]), f"<span class='num'>{html.escape(value)}</span>"
                     + (" <span class='bad'>at its fit bound</span>" if e.get("at_bound") else ""),
                     truth, html.escape(law), rate, f"{t['p_value']:.2g}",
                     html.escape(t.get("change_point_note") or "")])
    head = ["parameter", f"change at {last['operating_hours']:g} h", "truth" if truth_last else "", "trend law",
            "per 100 h", "p (vs no trend)", "note"]
    return table(head, rows, raw=True)


def _forecast_table(doc: dict[str, Any]) -> str:
    f = doc["forecast"]
    iv = f.get("trip_interval_90")
    tv = f.get("trip_visits_90")
    rows = [["trip of the monitor (median)", _h(f.get("trip_operating_hours"))],
            ["90 % interval", f"{iv[0]:.0f} – {_h(iv[1])}" if iv else "—"],
            ["seen at visit (90 %)", f"{f.get('trip_visit')} ({tv[0]}–{tv[1]})" if tv else "—"],
            ["remaining useful life from the last visit", _h(f.get("rul_hours"))],
            ["P(FAULT at the next visit, " + f"{f['next_visit_hours']:g} h)",
             "—" if f.get("p_fault_next_visit") is None else f"{100 * f['p_fault_next_visit']:.0f} %"],
            ["no FAULT expected before (no trend)", _h(f.get("lower_bound_hours"))]]
    ff = (doc.get("truth") or {}).get("first_fault") or doc.get("board_first_fault")
    if ff and ff.get("operating_hours") is not None:
        rows.append(["first FAULT in the records (truth)", f"{ff['operating_hours']:g} h (visit {ff.get('visit')})"])
    return table(["", ""], rows)


def _evaluation_html(ev: dict[str, Any]) -> str:
    pts = [[f"{p['lambda']:g}", _h(p["t_lambda_hours"]), _h(p["prediction_hours"]),
            "—" if p["ok"] is None else ("<span class='good'>met</span>" if p["ok"] else "<span class='bad'>missed"
                                                                                          "</span>"),
            "—" if p["relative_accuracy"] is None else f"{p['relative_accuracy']:.2f}"] for p in ev["alpha_lambda"]]
    ph = ev["prognostic_horizon_hours"]
    summary = table(["score", "value"], [
        ["truth: first FAULT", f"{ev['true_first_fault_hours']:g} h (visit {ev.get('true_first_fault_visit')}; "
                               f"{html.escape(ev.get('truth_source', ''))})"],
        ["predictions with a date before it",
         f"{ev['dated_predictions']} (first at {_h(ev['first_prediction_hours'])})"],
        ["prognostic horizon (α = " + f"{ev['alpha']:g})", "none" if ph is None else f"{ph:.0f} h"],
        ["relative accuracy, mean", "—" if ev["relative_accuracy_mean"] is None
         else f"{ev['relative_accuracy_mean']:.2f}"],
        ["90 % interval holds the first FAULT", "—" if ev["coverage_90"] is None
         else f"{100 * ev['coverage_90']:.0f} % of the dated predictions"]], raw=True)
    return (summary + table(["λ", "t_λ", "judged on the prediction at", f"α-λ (α = {ev['alpha']:g}, "
                             f"β = {ev['beta']:g})", "relative accuracy"], pts, raw=True))


def _predictions_table(doc: dict[str, Any]) -> str:
    ev = doc.get("evaluation")
    rows_src = ev["predictions"] if ev else doc.get("remaining_life") or []
    rows = []
    for r in rows_src:
        iv = r["trip_interval_90"]
        date = ("no trend: not before " + _h(r["lower_bound_hours"]) if not r["significant"] else
                "beyond the forecast horizon" if r["trip_hours_median"] is None else
                f"{_h(r['trip_hours_median'])} ({_h(iv[0])} – {_h(iv[1]) if iv[1] is not None else 'beyond'})")
        row = [f"{r['as_of_hours']:g} h", str(r["visits_used"]), date,
               _h(r["rul_median_hours"]) if r["significant"] else "—"]
        if ev:
            row += [_h(r["rul_true_hours"]), "" if r["within_alpha"] is None else ("yes" if r["within_alpha"] else
                                                                                 "no"),
                    "" if r["relative_accuracy"] is None else f"{r['relative_accuracy']:.2f}"]
        rows.append(row)
    head = ["as of", "visits", "trip seen at (90 %)", "predicted RUL"]
    if ev:
        head += ["true RUL", "within α", "relative accuracy"]
    return table(head, rows)


def _where_html(loc: dict[str, Any]) -> str:
    if not loc.get("run"):
        return f"<p class='note'>{html.escape(loc.get('reason', ''))}</p>"
    rows = []
    for c in loc["candidates"]:
        change = format_percent_change(c["relative"], c.get("relative_stderr")) if "relative" in c else ""
        rows.append([html.escape(c["name"]), str(c.get("section") or ""), change,
                     f"{c['held_rss_sigma2']:.0f}" if "held_rss_sigma2" in c else html.escape(c.get("error", "")),
                     "<span class='bad'>at its fit bound: a limit, not an estimate</span>" if c.get("at_bound")
                     else ""])
    return (f"<p>{html.escape(loc['reason'])}</p>"
            + table(["freed alone (with α_h, β_h)", "section", "change", "held-out RSS (σ²)", "note"], rows, raw=True)
            + (f"<p class='note'>{html.escape(loc['at_bound_note'])}</p>" if loc.get("at_bound_note") else ""))


def _visits_table(doc: dict[str, Any]) -> str:
    names = [e["name"] for e in doc["visits"][0]["estimates"]]
    truth = {r["operating_hours"]: r["relative"] for r in ((doc.get("truth") or {}).get("visits") or [])}
    rows = []
    for v in doc["visits"]:
        cells = [str(v["visit"]), f"{v['operating_hours']:g}", v["board_verdict"] or ""]
        for e in v["estimates"]:
            se = e["stderr"] / abs(e["nominal"]) if e["stderr"] is not None else None
            cells.append(_pct(e["relative"], se) + (" (at bound)" if e.get("at_bound") else ""))
        if truth:
            t = truth.get(v["operating_hours"])
            cells += [_truth_pct(t[n]) if t else "" for n in names]
        cells.append(f"{v['held_rms_sigma']:.2f}")
        rows.append(cells)
    head = ["visit", "h", "board", *names, *([f"{n} truth" for n in names] if truth else []), "held-out rms (σ)"]
    return table(head, rows)


def health_page(doc: dict[str, Any], figures: dict[str, Path], files: Sequence[str]) -> str:
    """The page: ``figures`` maps health.png / forecast.png / remaining_life.png to files (missing ones are left
    out); ``files`` are linked at the foot (health.json, levels.txt, ...)."""
    first, last = doc["visits"][0], doc["visits"][-1]
    as_of = f"as of {doc['as_of_hours']:g} h, " if doc.get("as_of_hours") is not None else ""
    sub = (f"{as_of}{counted(doc['visits_used'], 'visit')} ({first['operating_hours']:g} – "
           f"{last['operating_hours']:g} h"
           + (f"; {counted(doc['visits_later_not_used'], 'later visit')} not used"
              if doc.get("visits_later_not_used") else "")
           + f") · re-estimating {', '.join(doc['free'])} with params {doc['params']}")

    def fig(name: str) -> str:
        return img_tag(figures[name]) if name in figures and figures[name].exists() else \
            f"<p class='note'>({name} could not be drawn)</p>"

    ev = doc.get("evaluation")
    fol = doc.get("followed") or {}
    followed = (f"<p class='note'><b>What was re-estimated, and why:</b> {html.escape(fol['why'])}</p>"
                if fol.get("why") else "")
    body = ["<main>", "<h1>Laminate health over time</h1>", f"<p class='sub'>{html.escape(sub)}</p>", followed,
            _cards(doc),
            "<h2>Each parameter against operating hours</h2>",
            "<p class='note'>Visit estimates with ±2 standard errors, the trend law chosen on the evidence (AIC "
            "on the visits' own errors) with its 90 % band, the truth where the records carry it; on α_h the board "
            "monitor's trip limits."
            "</p>", fig("health.png"), _trend_table(doc),
            "<h2>When will the board's monitor say FAULT?</h2>", fig("forecast.png"), _forecast_table(doc),
            "<h2>Remaining life against time</h2>",
            "<p class='note'>The forecast rebuilt as of each visit from the visits up to it"
            + (", against the true remaining life and its α-λ cone" if ev else "") + ".</p>",
            fig("remaining_life.png")]
    if ev:
        body += ["<h3>Prognostics scores (ProgPy / Saxena et al. definitions)</h3>", _evaluation_html(ev)]
    body += [_predictions_table(doc), "<h2>Where? Each section stiffness freed alone</h2>",
             _where_html(doc.get("location") or {}), "<h2>Visits</h2>", _visits_table(doc),
             "<footer>Machine-readable: " + " · ".join(f"<a href='{html.escape(f)}'>{html.escape(f)}</a>"
                                                       for f in files)
             + ". Definitions: docs/health.md.</footer>", "</main>"]
    return page("shm health", CSS, body)
