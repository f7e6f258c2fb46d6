"""Self-contained HTML: images embedded as base64 data, tables, and the page around them."""

from __future__ import annotations

import base64
import html
from collections.abc import Sequence
from pathlib import Path
from typing import Any


def img_tag(path: Path | None, style: str | None = "max-width:100%") -> str:
    """An ``<img>`` carrying the PNG at ``path`` inline (empty for None)."""
    if path is None:
        return ""
    path = Path(path)
    data = base64.b64encode(path.read_bytes()).decode("ascii")
    attr = f' style="{style}"' if style else ""
    return f'<img alt="{html.escape(path.name)}" src="data:image/png;base64,{data}"{attr}>'


def table(header: Sequence[str], rows: Sequence[Sequence[Any]], raw: bool = False) -> str:
    """A table; cells are escaped unless ``raw`` (cells that already hold markup)."""
    h = "".join(f"<th>{html.escape(str(x))}</th>" for x in header)
    body = "".join("<tr>" + "".join(f"<td>{x if raw else html.escape(str(x))}</td>" for x in r) + "</tr>"
                   for r in rows)
    return f"<table><tr>{h}</tr>{body}</table>"


def records_table(rows: Sequence[dict[str, Any]], columns: Sequence[tuple[str, str]]) -> str:
    """A table of dict rows: ``columns`` are (key, heading); floats to 6 significant digits, None empty;
    no rows: *none*."""
    if not rows:
        return "<p><i>none</i></p>"
    cells = []
    for r in rows:
        line = []
        for key, _ in columns:
            v = r.get(key)
            line.append("" if v is None else f"{v:.6g}" if isinstance(v, float) else str(v))
        cells.append(line)
    return table([label for _, label in columns], cells)


def page(title: str, css: str, body: Sequence[str]) -> str:
    """A complete HTML document (UTF-8, styles inline)."""
    return "\n".join([f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{html.escape(title)}</title>",
                      f"<style>{css}</style></head><body>", *body, "</body></html>"])
