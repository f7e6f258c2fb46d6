"""Small helpers shared by the command modules: output directories, JSON, plotting set-up."""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import Any

import numpy as np


def add_out_arg(p: argparse.ArgumentParser, default: str | None = None) -> None:
    p.add_argument("--out", default=default, required=default is None, metavar="DIR",
                   help="output directory (created if missing)" + (f"; default {default}" if default else ""))


def add_params_arg(p: argparse.ArgumentParser) -> None:
    p.add_argument("--params", default="table2", metavar="NAME",
                   help="parameter set: a shipped name (table2, calibrated) or a path to a .toml file")


def out_dir(path: str | Path) -> Path:
    d = Path(path)
    d.mkdir(parents=True, exist_ok=True)
    return d


def to_jsonable(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return to_jsonable(obj.tolist())
    if isinstance(obj, (np.floating, float)):
        v = float(obj)
        return v if math.isfinite(v) else None
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.bool_):
        return bool(obj)
    return obj


def dump_json(obj: Any) -> str:
    return json.dumps(to_jsonable(obj), indent=2, sort_keys=False)


def pyplot():
    """matplotlib.pyplot with the non-interactive Agg backend."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def write_csv(path: Path, columns: dict[str, np.ndarray]) -> None:
    """Write columns (names carry units, e.g. ``time_s``) as CSV."""
    names = list(columns)
    data = np.column_stack([np.asarray(columns[n], dtype=float) for n in names])
    np.savetxt(path, data, delimiter=",", header=",".join(names), comments="", fmt="%.10g")
