"""Small helpers shared by the command modules: output directories, JSON, plotting set-up, decorations that
may fail without losing the results."""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import traceback
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

T = TypeVar("T")


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


def debug_requested(args: argparse.Namespace | None = None) -> bool:
    """``shm --debug`` (on the parsed namespace) or ``SHM_DEBUG=1``: print tracebacks of unexpected errors."""
    return bool(getattr(args, "debug", False)) or os.environ.get("SHM_DEBUG", "") not in ("", "0")


class Decorations:
    """Figures and reports written *after* a command's numeric results: a failure in one of them is reported (which
    artefact, the exception, that it is a bug) and remembered, never allowed to lose the results already written.

    ``deco.attempt("fig11.png", lambda: plot(...))`` returns the callable's value or ``None`` when it failed;
    ``deco.failed`` maps artefact → ``"Type: message"``; the command exits 1 when it is not empty.
    """

    def __init__(self, command: str, args: argparse.Namespace | None = None) -> None:
        self.command = command
        self.debug = debug_requested(args)
        self.failed: dict[str, str] = {}

    def attempt(self, artefact: str, make: Callable[[], T]) -> T | None:
        try:
            return make()
        except Exception as exc:  # a figure or report failing must not lose the results
            if self.debug:
                traceback.print_exception(exc, file=sys.stderr)
            why = f"{type(exc).__name__}: {' '.join(str(exc).split()) or '(no message)'}"
            self.failed[artefact] = why
            print(f"shm {self.command}: could not write {artefact} ({why}) — a bug in mfc-shm; the numeric results "
                  "are written" + ("" if self.debug else "; rerun with 'shm --debug ...' for the traceback"),
                  file=sys.stderr)
            return None

    @property
    def ok(self) -> bool:
        return not self.failed
