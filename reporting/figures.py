"""Figure helpers shared by every report: pyplot on the non-interactive Agg backend, saving (and closing), display
units for SI quantities, and decimation of long traces that keeps their peaks."""

from __future__ import annotations

import warnings
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

#: SI unit -> (factor, display unit) for axes and tables
SI_DISPLAY: dict[str, tuple[float, str]] = {"m": (1e3, "mm"), "V": (1.0, "V"), "C": (1e6, "µC"),
                                            "m/s^2": (1.0, "m/s²")}


def pyplot() -> Any:
    """matplotlib.pyplot with the non-interactive Agg backend."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def warm_up() -> None:
    """Draw one small figure with text and math text and save it in memory: the fonts and the math-text parser a
    process's first report otherwise loads (a Dask worker's warm-up before its first task; about 0.8 s of CPU)."""
    import io

    plt = pyplot()
    fig, ax = plt.subplots(figsize=(2.0, 1.5))
    ax.plot([0.0, 1.0], [0.0, 1.0], label=r"$\sigma$")
    ax.set(title=r"held-out RMS ($\sigma$)", xlabel="t (s)", ylabel=r"$z_3$ (mm)")
    ax.legend()
    fig.tight_layout()
    fig.savefig(io.BytesIO(), format="png")
    plt.close(fig)


def display_scale(unit: str) -> tuple[float, str]:
    """(factor, display unit) of an SI ``unit`` (unknown units are shown as they are)."""
    return SI_DISPLAY.get(unit, (1.0, unit))


#: callbacks ``(figure, path)`` run on every figure just before :func:`save_figure` writes it
_BEFORE_SAVE: list[Callable[[Any, Path], None]] = []


@contextmanager
def observing_saved_figures(callback: Callable[[Any, Path], None]) -> Iterator[None]:
    """Within the block, call ``callback(fig, path)`` with every figure :func:`save_figure` is about to write, laid
    out as it will be saved (the figure tests check each one as a picture)."""
    _BEFORE_SAVE.append(callback)
    try:
        yield
    finally:
        _BEFORE_SAVE.remove(callback)


def save_figure(fig: Any, path: Path, dpi: float, *, tight: bool = False,
                adjust: Mapping[str, float] | None = None, also: Sequence[Path] = ()) -> Path:
    """Save ``fig`` to ``path`` and close it. ``tight``: ``tight_layout`` first; ``adjust``: ``subplots_adjust``
    margins instead (cheaper than tight_layout on long reports); ``also``: further files (e.g. an SVG copy, its
    format from the suffix, default dpi). Every figure a report writes goes through here."""
    if tight:
        fig.tight_layout()
    if adjust:
        fig.subplots_adjust(**adjust)
    for callback in list(_BEFORE_SAVE):
        callback(fig, Path(path))
    fig.savefig(path, dpi=dpi)
    for extra in also:
        fig.savefig(extra)
    pyplot().close(fig)
    return Path(path)


def minmax_decimate(t: np.ndarray, y: np.ndarray, n_max: int = 4000) -> tuple[np.ndarray, np.ndarray]:
    """At most ``n_max`` points of a long record for a line plot: each bucket's minimum and maximum in time order
    (no peak is lost)."""
    if t.size <= n_max:
        return t, y
    k = int(np.ceil(t.size / (n_max / 2)))
    m = (t.size // k) * k
    tb = t[:m].reshape(-1, k)
    yb = y[:m].reshape(-1, k)
    lo, hi = yb.argmin(axis=1), yb.argmax(axis=1)
    first = np.minimum(lo, hi)
    second = np.maximum(lo, hi)
    rows = np.arange(tb.shape[0])
    tt = np.column_stack([tb[rows, first], tb[rows, second]]).ravel()
    yy = np.column_stack([yb[rows, first], yb[rows, second]]).ravel()
    return tt, yy


def minmax_envelope(t: np.ndarray, y: np.ndarray, max_points: int = 4000) -> tuple[np.ndarray, np.ndarray,
                                                                                     np.ndarray]:
    """(t, lower, upper): the min/max envelope of ``y`` in ``max_points`` buckets for a filled band (NaN buckets,
    e.g. while a link was down, stay NaN)."""
    n = y.size
    if n <= max_points:
        return t, y, y
    k = n // max_points
    m = (n // k) * k
    tt = t[:m].reshape(-1, k)[:, 0]
    yy = y[:m].reshape(-1, k)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN buckets stay NaN
        return tt, np.nanmin(yy, axis=1), np.nanmax(yy, axis=1)


def logspaced_max(f: np.ndarray, p: np.ndarray, n: int = 1500) -> tuple[np.ndarray, np.ndarray]:
    """Thin a long spectrum for plotting: the maximum in each of ``n`` log-spaced bins (keeps peaks)."""
    if f.size <= n:
        return f, p
    edges = np.geomspace(f[0], f[-1] * (1 + 1e-12), n + 1)
    idx = np.clip(np.searchsorted(edges, f, side="right") - 1, 0, n - 1)
    out = np.full(n, np.nan)
    np.fmax.at(out, idx, p)
    centres = np.sqrt(edges[:-1] * edges[1:])
    k = np.isfinite(out)
    return centres[k], out[k]
