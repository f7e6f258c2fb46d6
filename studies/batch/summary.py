"""One table over all tasks of a batch: ``summary.csv`` (units in the column names) and ``summary.html`` (each
row links to the task's own report in its subfolder)."""

from __future__ import annotations

import csv
import html
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from reporting.html_page import page

_CSS = ("body{font-family:sans-serif;margin:1.5em} table{border-collapse:collapse} "
        "td,th{border:1px solid #bbb;padding:3px 8px;text-align:left} th{background:#eee} .bad{color:#b00}")


def _number_sig(key: str, value: Any) -> bool:
    return isinstance(value, float | int) and not isinstance(value, bool) and key.rsplit("_", 1)[-1] in (
        "sigma", "pct", "s", "Hz", "m", "h", "J", "V", "count")


def scalar_columns(doc: dict[str, Any], skip: Sequence[str] = ()) -> dict[str, Any]:
    """The document's top-level numbers whose name ends in a unit (``held_rms_sigma``, ``fit_pct`` ...) and its
    top-level text fields ``verdict``/``winner``/``best_set``: what a summary row shows of any command."""
    row: dict[str, Any] = {}
    for k in ("verdict", "winner", "best_set"):
        if isinstance(doc.get(k), str):
            row[k] = doc[k]
    for k, v in doc.items():
        if k not in skip and _number_sig(k, v):
            row[k] = v
    return row


def columns_of(rows: Sequence[dict[str, Any]]) -> list[str]:
    """All columns in first-seen order."""
    seen: dict[str, None] = {}
    for r in rows:
        seen.update(dict.fromkeys(r))
    return list(seen)


def _cell(v: Any) -> str:
    if v is None:
        return ""
    if isinstance(v, float):
        return repr(v)
    return str(v)


def write_summary(out: Path, title: str, rows: Sequence[dict[str, Any]], report_of: dict[str, str],
                  notes: Sequence[str] = (), stem: str = "summary", key: str = "task") -> dict[str, Path]:
    """``<stem>.csv`` and ``<stem>.html`` in ``out``; ``rows`` carry a ``key`` column (the task), ``report_of``
    maps a task to its report's path relative to ``out``."""
    cols = columns_of(rows)
    csv_path = out / f"{stem}.csv"
    with csv_path.open("w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(cols)
        for r in rows:
            w.writerow([_cell(r.get(c)) for c in cols])
    head = "".join(f"<th>{html.escape(c)}</th>" for c in cols)
    body = []
    for r in rows:
        cells = []
        for c in cols:
            v = r.get(c)
            text = html.escape(f"{v:.6g}" if isinstance(v, float) else _cell(v))
            if c == key and r.get(key) in report_of:
                text = f"<a href='{html.escape(report_of[str(r[key])])}'>{text}</a>"
            bad = c == "exit_code" and v not in (0, None)
            cells.append(f"<td class='bad'>{text}</td>" if bad else f"<td>{text}</td>")
        body.append("<tr>" + "".join(cells) + "</tr>")
    parts = [f"<h1>{html.escape(title)}</h1>", f"<table><tr>{head}</tr>{''.join(body)}</table>",
             *(f"<p>{html.escape(n)}</p>" for n in notes)]
    html_path = out / f"{stem}.html"
    html_path.write_text(page(title, _CSS, parts), encoding="utf-8")
    return {"csv": csv_path, "html": html_path}
