"""Columns of numbers as CSV (the numeric side of every report)."""

from __future__ import annotations

from pathlib import Path

import numpy as np


def write_csv(path: Path, columns: dict[str, np.ndarray]) -> None:
    """Write columns (names carry units, e.g. ``time_s``) as CSV."""
    names = list(columns)
    data = np.column_stack([np.asarray(columns[n], dtype=float) for n in names])
    np.savetxt(path, data, delimiter=",", header=",".join(names), comments="", fmt="%.10g")
