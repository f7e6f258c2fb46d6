"""Figures checked as pictures: render a matplotlib figure and list what a reader could not read.

* **text overlap**: two visible texts (tick labels, axis labels, titles, annotations, legend entries, the legend
  box itself) whose boxes on the rendered canvas overlap, or stand side by side less than :data:`MIN_GAP_PT`
  apart (they read as one: "596.0596.5");
* **text outside the figure**: a text cut off at the figure's edge;
* **legend covers data**: a legend box over more than a small share of a line's points, a collection's points or
  a bar;
* **bars hide each other**: bars of two series drawn over the same place (grouped bars without offsets);
* **non-finite number**: a text that prints ``nan`` or ``inf``;
* **fractional ticks on a count axis**: tick labels between whole numbers on an axis whose plotted data are all
  whole numbers (iterations, evaluations, counters).

Pure: the checker draws the figure on its own canvas (``fig.canvas.draw()``) and reads the renderer's boxes
(``artist.get_window_extent(renderer)``, display pixels); it writes nothing.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any

import numpy as np

#: overlaps smaller than this (pixels) are anti-aliasing neighbours, not overlapping text
MIN_OVERLAP_PX = 1.0
#: texts side by side (e.g. tick labels) closer than this (points) run together ("596.0596.5")
MIN_GAP_PT = 3.0
#: share of the smaller of two bars another bar of a different series may cover
MAX_BAR_OVERLAP = 0.5
#: share of a line's (or collection's) shown points a legend may cover
MAX_LEGEND_COVER = 0.05
#: share of one bar's shown area a legend may cover
MAX_BAR_COVER = 0.25
#: findings listed per kind before "... and N more"
MAX_LISTED = 6

_NON_FINITE = re.compile(r"(?<![A-Za-z])[+-]?(nan|inf)(?![A-Za-z])", re.IGNORECASE)


@dataclass(frozen=True)
class Finding:
    """One legibility problem: its kind and what it concerns, in words."""

    kind: str
    detail: str

    def __str__(self) -> str:
        return f"{self.kind}: {self.detail}"


@dataclass(frozen=True)
class _Box:
    text: str
    what: str
    group: int  # texts of one legend share a group (their own layout never collides); others are unique
    x0: float
    y0: float
    x1: float
    y1: float


def _short(s: str, n: int = 40) -> str:
    s = " ".join(s.split())
    return s if len(s) <= n else s[: n - 1] + "…"


def _axes_name(fig: Any, ax: Any) -> str:
    title = ax.get_title() or ax.get_title("left") or ax.get_ylabel()
    i = fig.axes.index(ax) + 1
    return f"axes {i}" + (f" ({_short(title, 30)!r})" if title else "")


def _in_view(axis: Any, loc: float) -> bool:
    lo, hi = sorted(axis.get_view_interval())
    tol = 1e-9 * max(1.0, abs(hi - lo))
    return bool(lo - tol <= loc <= hi + tol)


def _tick_labels(axis: Any) -> list[Any]:
    """The tick labels a reader sees: visible, non-empty, at ticks inside the view interval."""
    if not axis.get_visible():
        return []
    out = []
    for tick in axis.get_major_ticks() + axis.get_minor_ticks():
        if not _in_view(axis, tick.get_loc()):
            continue
        for lab in (tick.label1, tick.label2):
            if lab.get_visible() and lab.get_text().strip():
                out.append(lab)
    return out


def _texts(fig: Any) -> list[tuple[Any, str, int]]:
    """(text artist, description, group) of every visible text of ``fig``."""
    items: list[tuple[Any, str, int]] = []
    group = 0

    def add(t: Any, what: str, g: int | None = None) -> None:
        nonlocal group
        if t is None or not t.get_visible() or not t.get_text().strip():
            return
        group += 1
        items.append((t, what, group if g is None else g))

    for ax in fig.axes:
        if not ax.get_visible():
            continue
        name = _axes_name(fig, ax)
        for axis, xy in ((ax.xaxis, "x"), (ax.yaxis, "y")):
            for lab in _tick_labels(axis):
                add(lab, f"{name} {xy} tick label")
            if axis.get_visible():
                add(axis.label, f"{name} {xy} axis label")
                add(axis.get_offset_text(), f"{name} {xy} offset text")
        for t in _title_artists(ax):
            add(t, f"{name} title")
        for t in ax.texts:
            add(t, f"{name} annotation")
        leg = ax.get_legend()
        if leg is not None and leg.get_visible():
            group += 1
            g = group
            for t in [*leg.get_texts(), leg.get_title()]:
                add(t, f"{name} legend text", g)
    for t in fig.texts:
        add(t, "figure text")
    for leg in fig.legends:
        group += 1
        g = group
        for t in [*leg.get_texts(), leg.get_title()]:
            add(t, "figure legend text", g)
    return items


def _title_artists(ax: Any) -> list[Any]:
    return [ax.title, getattr(ax, "_left_title", None), getattr(ax, "_right_title", None)]


def _boxes(fig: Any, renderer: Any) -> list[_Box]:
    boxes = []
    for t, what, g in _texts(fig):
        bb = t.get_window_extent(renderer)
        if bb.width <= 0 or bb.height <= 0 or not np.all(np.isfinite(bb.extents)):
            continue
        boxes.append(_Box(t.get_text(), what, g, *bb.extents))
    legends = [(ax.get_legend(), _axes_name(fig, ax)) for ax in fig.axes if ax.get_visible()]
    legends += [(leg, "figure") for leg in fig.legends]
    for leg, name in legends:
        if leg is None or not leg.get_visible():
            continue
        bb = leg.get_window_extent(renderer)
        members = {b.group for b in boxes if b.what.endswith("legend text") and b.what.startswith(name)}
        g = next(iter(members)) if members else -1
        boxes.append(_Box("legend", f"{name} legend box", g, *bb.extents))
    return boxes


def _overlaps(boxes: list[_Box], gap_px: float) -> list[tuple[_Box, _Box, float, float]]:
    """Pairs of boxes (of different groups) that overlap, or overlap in height and stand closer than ``gap_px``
    side by side; with the overlap's width (negative: the gap) and height in pixels."""
    if len(boxes) < 2:
        return []
    e = np.array([[b.x0, b.y0, b.x1, b.y1] for b in boxes])
    g = np.array([b.group for b in boxes])
    w = np.minimum(e[:, None, 2], e[None, :, 2]) - np.maximum(e[:, None, 0], e[None, :, 0])
    h = np.minimum(e[:, None, 3], e[None, :, 3]) - np.maximum(e[:, None, 1], e[None, :, 1])
    hit = (w > -gap_px) & (h > MIN_OVERLAP_PX) & (g[:, None] != g[None, :])
    i, j = np.nonzero(np.triu(hit, 1))
    return [(boxes[a], boxes[b], float(w[a, b]), float(h[a, b])) for a, b in zip(i, j)]


def _listed(kind: str, details: list[str]) -> list[Finding]:
    out = [Finding(kind, d) for d in details[:MAX_LISTED]]
    if len(details) > MAX_LISTED:
        out.append(Finding(kind, f"... and {len(details) - MAX_LISTED} more"))
    return out


def text_findings(fig: Any, renderer: Any) -> list[Finding]:
    """Overlapping texts, texts cut off at the figure's edge and texts printing nan/inf."""
    boxes = _boxes(fig, renderer)
    gap_px = MIN_GAP_PT * fig.dpi / 72.0
    over = [f"{a.what} {_short(a.text)!r} and {b.what} {_short(b.text)!r} "
            + (f"({w:.0f}×{h:.0f} px)" if w > MIN_OVERLAP_PX else f"(side by side, {-w * 72 / fig.dpi:.1f} pt apart)")
            for a, b, w, h in _overlaps(boxes, gap_px)]
    fw, fh = fig.bbox.width, fig.bbox.height
    cut = [f"{b.what} {_short(b.text)!r}" for b in boxes
           if b.x0 < -MIN_OVERLAP_PX or b.y0 < -MIN_OVERLAP_PX or b.x1 > fw + MIN_OVERLAP_PX
           or b.y1 > fh + MIN_OVERLAP_PX]
    bad = [f"{b.what} {_short(b.text)!r}" for b in boxes if _NON_FINITE.search(b.text)]
    return (_listed("text overlap", over) + _listed("text outside the figure", cut)
            + _listed("non-finite number", bad))


def _shown(points: np.ndarray, ax: Any) -> np.ndarray:
    p = points[np.all(np.isfinite(points), axis=1)] if points.size else points.reshape(0, 2)
    x0, y0, x1, y1 = ax.bbox.extents
    keep = (p[:, 0] >= x0) & (p[:, 0] <= x1) & (p[:, 1] >= y0) & (p[:, 1] <= y1)
    return p[keep]


def _inside(points: np.ndarray, ext: np.ndarray) -> int:
    x0, y0, x1, y1 = ext
    return int(np.count_nonzero((points[:, 0] >= x0) & (points[:, 0] <= x1) & (points[:, 1] >= y0)
                                & (points[:, 1] <= y1)))


def _data_point_sets(ax: Any) -> list[tuple[str, np.ndarray]]:
    """(description, display points) of every line and collection of ``ax`` drawn in data coordinates."""
    out = []
    for line in ax.get_lines():
        if not line.get_visible() or line.get_transform() != ax.transData:
            continue  # axhline/axvline and other reference lines live partly in axes coordinates
        xy = np.asarray(line.get_xydata(), dtype=float)
        if xy.size:
            with np.errstate(all="ignore"):
                out.append((f"line {_short(line.get_label())!r}", line.get_transform().transform(xy)))
    for coll in ax.collections:
        if not coll.get_visible():
            continue
        offsets = np.asarray(coll.get_offsets(), dtype=float)
        if offsets.size > 2:  # scatter: the markers' positions
            pts = coll.get_offset_transform().transform(offsets)
        else:  # fill_between, vlines, error bars: the paths' vertices
            paths = coll.get_paths()
            if not paths:
                continue
            verts = np.concatenate([p.vertices for p in paths])
            with np.errstate(all="ignore"):
                pts = coll.get_transform().transform(verts)
        out.append((f"{type(coll).__name__} {_short(coll.get_label())!r}", pts))
    return out


def _legend_boxes(fig: Any, renderer: Any) -> list[tuple[str, np.ndarray, list[Any]]]:
    out = []
    for ax in fig.axes:
        leg = ax.get_legend()
        if ax.get_visible() and leg is not None and leg.get_visible():
            out.append((_axes_name(fig, ax), np.array(leg.get_window_extent(renderer).extents), [ax]))
    for leg in fig.legends:
        out.append(("figure", np.array(leg.get_window_extent(renderer).extents), list(fig.axes)))
    return out


def legend_findings(fig: Any, renderer: Any) -> list[Finding]:
    """Legends over more than :data:`MAX_LEGEND_COVER` of a line's or collection's shown points, or over more
    than :data:`MAX_BAR_COVER` of one bar."""
    from matplotlib.container import BarContainer

    found = []
    for name, ext, axes in _legend_boxes(fig, renderer):
        for ax in axes:
            for what, pts in _data_point_sets(ax):
                shown = _shown(pts, ax)
                if shown.shape[0] < 3:
                    continue
                share = _inside(shown, ext) / shown.shape[0]
                if share > MAX_LEGEND_COVER:
                    found.append(f"{name} legend covers {100 * share:.0f} % of {what}")
            for cont in ax.containers:
                if isinstance(cont, BarContainer):
                    found += _bars_under_legend(name, ax, cont, ext, renderer)
    return _listed("legend covers data", found)


def _bars_under_legend(name: str, ax: Any, cont: Any, ext: np.ndarray, renderer: Any) -> list[str]:
    """Bars of ``cont`` whose value end (the top of an upright bar, the far end of a lying one) the legend box
    ``ext`` covers, or more than :data:`MAX_BAR_COVER` of whose shown area it covers."""
    found = []
    x0, y0, x1, y1 = ext
    ax_e = np.array(ax.bbox.extents)
    lying = getattr(cont, "orientation", "vertical") == "horizontal"
    for k, bar in enumerate(cont.patches):
        bx = np.array(bar.get_window_extent(renderer).extents)
        bx = np.r_[np.maximum(bx[:2], ax_e[:2]), np.minimum(bx[2:], ax_e[2:])]
        area = max(bx[2] - bx[0], 0) * max(bx[3] - bx[1], 0)
        if area <= 0:
            continue
        w = max(min(bx[2], x1) - max(bx[0], x0), 0)
        h = max(min(bx[3], y1) - max(bx[1], y0), 0)
        bx_, by_, bw, bh = bar.get_x(), bar.get_y(), bar.get_width(), bar.get_height()
        end = (bx_ + bw, by_ + bh / 2) if lying else (bx_ + bw / 2, by_ + bh)
        with np.errstate(all="ignore"):
            ex, ey = ax.transData.transform(end)
        end_hidden = bool(x0 <= ex <= x1 and y0 <= ey <= y1 and ax_e[0] <= ex <= ax_e[2] and ax_e[1] <= ey <= ax_e[3])
        if end_hidden or w * h / area > MAX_BAR_COVER:
            what = "the value end" if end_hidden else f"{100 * w * h / area:.0f} %"
            found.append(f"{name} legend covers {what} of bar {k + 1} ({_short(cont.get_label() or '')!r})")
    return found


def _bar_extents(ax: Any, renderer: Any) -> list[tuple[int, int, str, np.ndarray]]:
    from matplotlib.container import BarContainer

    out = []
    for c, cont in enumerate(ax.containers):
        if isinstance(cont, BarContainer):
            for k, bar in enumerate(cont.patches):
                e = np.array(bar.get_window_extent(renderer).extents)
                if bar.get_visible() and np.all(np.isfinite(e)) and e[2] > e[0] and e[3] > e[1]:
                    out.append((c, k, cont.get_label() or f"series {c + 1}", e))
    return out


def bar_findings(fig: Any, renderer: Any) -> list[Finding]:
    """Bars of different series over the same place: more than :data:`MAX_BAR_OVERLAP` of the smaller covered."""
    found = []
    for ax in fig.axes:
        bars = _bar_extents(ax, renderer)
        for i, (c1, k1, l1, e1) in enumerate(bars):
            for c2, k2, l2, e2 in bars[i + 1:]:
                if c1 == c2:
                    continue
                w = min(e1[2], e2[2]) - max(e1[0], e2[0])
                h = min(e1[3], e2[3]) - max(e1[1], e2[1])
                if w <= 0 or h <= 0:
                    continue
                smaller = min((e1[2] - e1[0]) * (e1[3] - e1[1]), (e2[2] - e2[0]) * (e2[3] - e2[1]))
                if w * h > MAX_BAR_OVERLAP * smaller:
                    found.append(f"{_axes_name(fig, ax)}: bar {k1 + 1} of {_short(l1)!r} and bar {k2 + 1} of "
                                 f"{_short(l2)!r} drawn over each other")
    return _listed("bars hide each other", found)


def _integer_data(ax: Any, which: int) -> bool:
    """Every line of ``ax`` in data coordinates has whole-number values along axis ``which`` (0: x, 1: y)."""
    values = []
    for line in ax.get_lines():
        if line.get_visible() and line.get_transform() == ax.transData:
            v = np.asarray(line.get_xydata(), dtype=float)[:, which]
            values.append(v[np.isfinite(v)])
    if not values:
        return False
    v = np.concatenate(values)
    return bool(v.size >= 3 and np.ptp(v) > 0 and np.all(np.abs(v - np.round(v)) < 1e-9))


def tick_findings(fig: Any) -> list[Finding]:
    """Tick labels between whole numbers on an axis that plots whole numbers only."""
    found = []
    for ax in fig.axes:
        for which, axis, xy in ((0, ax.xaxis, "x"), (1, ax.yaxis, "y")):
            if axis.get_scale() != "linear" or not _integer_data(ax, which):
                continue
            frac = [lab.get_text() for lab, tick in ((t.label1, t) for t in axis.get_major_ticks())
                    if lab.get_visible() and lab.get_text().strip() and _in_view(axis, tick.get_loc())
                    and abs(tick.get_loc() - round(tick.get_loc())) > 1e-9]
            if frac:
                found.append(f"{_axes_name(fig, ax)} {xy} ticks {', '.join(frac[:5])} on whole-number data "
                             f"({_short(axis.label.get_text()) or 'no label'!r})")
    return _listed("fractional ticks on a count axis", found)


def check_figure(fig: Any) -> list[Finding]:
    """Draw ``fig`` and return every legibility finding (empty: the figure reads)."""
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    return (text_findings(fig, renderer) + legend_findings(fig, renderer) + bar_findings(fig, renderer)
            + tick_findings(fig))


def describe(name: str, findings: list[Finding]) -> str:
    """A report of one figure's findings, one line each."""
    return "\n".join([f"{name}:", *(f"  - {f}" for f in findings)])
