"""Placing what a figure writes so that it reads (the rules :mod:`reporting.figure_legibility` checks): a legend in
head-room above the data, labels that would collide left out, whole-number ticks on count axes, few enough tick
labels to stand apart.

Call these after the axes' data are drawn and their layout is (nearly) final: they measure on the figure's renderer.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

#: space between a legend's lower edge and the highest data (fraction of the axes' height)
LEGEND_HEADROOM_PAD = 0.03
#: a legend never takes more than this share of an axes' height (a taller one goes beside the axes)
LEGEND_MAX_SHARE = 0.6


def legend_clear_of_data(ax: Any, loc: str = "upper right", **legend_kw: Any) -> Any:
    """A legend in a top corner of ``ax`` with the y range raised so that the data sit below it (linear or log
    y axis): the data keep their current limits in the lower part of the axes. Returns the legend."""
    leg = ax.legend(loc=loc, **legend_kw)
    renderer = ax.figure.canvas.get_renderer()
    share = leg.get_window_extent(renderer).height / max(ax.bbox.height, 1.0) + LEGEND_HEADROOM_PAD
    if share > LEGEND_MAX_SHARE:
        leg.remove()
        return ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, **legend_kw)
    lo, hi = ax.get_ylim()
    inverted = lo > hi
    lo, hi = min(lo, hi), max(lo, hi)
    if ax.get_yscale() == "log" and lo > 0:
        top = 10 ** (np.log10(lo) + (np.log10(hi) - np.log10(lo)) / (1.0 - share))
    else:
        top = lo + (hi - lo) / (1.0 - share)
    ax.set_ylim((top, lo) if inverted else (lo, top))
    return leg


def hide_colliding_texts(texts: Sequence[Any], gap_pt: float = 2.0) -> list[Any]:
    """Hide every text of ``texts`` (in priority order, most important first) whose box comes within ``gap_pt`` of a
    text kept before it; returns the texts kept."""
    if not texts:
        return []
    fig = texts[0].figure
    renderer = fig.canvas.get_renderer()
    pad = gap_pt * fig.dpi / 72.0 / 2.0
    kept: list[Any] = []
    boxes: list[np.ndarray] = []
    for t in texts:
        e = np.array(t.get_window_extent(renderer).extents) + np.array([-pad, -pad, pad, pad])
        if any(e[0] < b[2] and b[0] < e[2] and e[1] < b[3] and b[1] < e[3] for b in boxes):
            t.set_visible(False)
            continue
        kept.append(t)
        boxes.append(e)
    return kept


def count_axis(axis: Any) -> None:
    """Whole-number ticks only (iterations, evaluations, counters)."""
    from matplotlib.ticker import MaxNLocator

    axis.set_major_locator(MaxNLocator(integer=True))


def few_ticks(axis: Any, n: int = 5) -> None:
    """At most about ``n`` tick labels, so that long labels ("596.5") stand apart in a narrow panel."""
    from matplotlib.ticker import MaxNLocator

    axis.set_major_locator(MaxNLocator(nbins=n))
