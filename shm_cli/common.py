"""Small helpers shared by the command modules: argparse value types, memory checks, output directories, JSON,
decorations (figures, reports) that may fail without losing the results."""

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

from board_config.errors import InputError
from board_config.json_values import to_jsonable
from reporting.csv_columns import write_csv as write_csv  # re-exported for the commands

T = TypeVar("T")


class OutputPathError(InputError):
    """An output path (``--out``, ``--save`` ...) the user gave cannot be used: names the path and why (exit 2)."""


# --- argparse value types: nonsense is refused at parse time with the allowed range (exit 2) ---------------
def _number(text: str, kind: type) -> float | int:
    raw = str(text).strip()
    try:
        value = kind(raw)
    except (TypeError, ValueError):
        what = "an integer" if kind is int else "a number"
        raise argparse.ArgumentTypeError(f"'{text}' is not {what}") from None
    if kind is float and not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"'{text}' is not a finite number")
    return value


def _fmt(x: float) -> str:
    return str(x) if isinstance(x, int) else f"{x:g}"


def _range_text(lo: float | None, hi: float | None, lo_open: bool, hi_open: bool) -> str:
    if lo is not None and hi is not None:
        return f"{'(' if lo_open else '['}{_fmt(lo)}, {_fmt(hi)}{')' if hi_open else ']'}"
    if lo is not None:
        return f"{'>' if lo_open else '>='} {_fmt(lo)}"
    if hi is not None:
        return f"{'<' if hi_open else '<='} {_fmt(hi)}"
    return "finite"


def number_in_range(lo: float | None = None, hi: float | None = None, *, integer: bool = False,
                    lo_open: bool = False, hi_open: bool = False, unit: str = "") -> Callable[[str], Any]:
    """An argparse ``type=``: a finite float (or an int) within ``[lo, hi]`` (open ends with ``lo_open``/
    ``hi_open``); anything else is refused naming the value and the allowed range (argparse: exit 2)."""
    kind = int if integer else float

    def parse(text: str) -> float | int:
        value = _number(text, kind)
        bad = ((lo is not None and (value < lo or (lo_open and value == lo)))
               or (hi is not None and (value > hi or (hi_open and value == hi))))
        if bad:
            rng = _range_text(lo, hi, lo_open, hi_open)
            raise argparse.ArgumentTypeError(f"{text} is out of range: must be {rng}{(' ' + unit) if unit else ''}")
        return value

    parse.__name__ = "int" if integer else "float"  # argparse names the type in its messages
    return parse


def finite_float(text: str) -> float:
    """argparse ``type=``: any finite float (NaN and ±inf refused)."""
    return float(_number(text, float))


def refuse_nonfinite_floats(parser: argparse.ArgumentParser) -> None:
    """Make every plain ``type=float`` option of ``parser`` and of its sub-commands refuse NaN and ±inf
    (:func:`finite_float`): no command has a use for them, and they slip through every range check."""
    for action in parser._actions:
        if action.type is float:
            action.type = finite_float
        if isinstance(action, argparse._SubParsersAction):
            for sub in {id(p): p for p in action.choices.values()}.values():
                refuse_nonfinite_floats(sub)


#: ready-made argparse types
positive_float = number_in_range(0.0, lo_open=True)
nonnegative_float = number_in_range(0.0)
positive_int = number_in_range(1, integer=True)
nonnegative_int = number_in_range(0, integer=True)
seed_int = number_in_range(0, 2**32 - 1, integer=True)


def even_int(lo: int = 2) -> Callable[[str], Any]:
    """argparse ``type=``: an even integer >= ``lo``."""
    base = number_in_range(lo, integer=True)

    def parse(text: str) -> int:
        value = base(text)
        if value % 2:
            raise argparse.ArgumentTypeError(f"{text} must be an even integer >= {lo}")
        return value

    parse.__name__ = "int"
    return parse


def int_in_range(lo: int | None = None, hi: int | None = None) -> Callable[[str], Any]:
    """argparse ``type=``: an integer within ``[lo, hi]``."""
    return number_in_range(lo, hi, integer=True)


def float_in_range(lo: float | None = None, hi: float | None = None, **kw: Any) -> Callable[[str], Any]:
    """argparse ``type=``: a finite float within ``[lo, hi]`` (see :func:`number_in_range`)."""
    return number_in_range(lo, hi, **kw)


# --- memory: absurd sizes are refused up front with what they would need -----------------------------------
def available_memory_bytes() -> int | None:
    """Memory the system could give this process now (``MemAvailable``), or None when unknown."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return int(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        return None


def _gib(n: float) -> str:
    return f"{n / 2**30:.3g} GiB" if n >= 2**27 else f"{n / 2**20:.3g} MiB"


def check_memory(what: str, need_bytes: float, *, fraction: float = 0.8, hint: str = "") -> None:
    """Refuse (:class:`InputError`, exit 2) a job whose arrays would need more than ``fraction`` of the available
    memory, saying what it would need: ``what`` names the option(s), e.g. ``"--duration-s 1e9 (1e11 ticks)"``."""
    avail = available_memory_bytes()
    limit = fraction * avail if avail is not None else 2.0**40
    if not math.isfinite(need_bytes) or need_bytes > limit:
        have = f"{_gib(avail)} available" if avail is not None else "more than this machine can hold"
        need = _gib(need_bytes) if math.isfinite(need_bytes) else "unbounded memory"
        raise InputError(f"{what} would need about {need} of memory ({have}); "
                         f"{hint or 'choose a smaller value'}")


def add_out_arg(p: argparse.ArgumentParser, default: str | None = None) -> None:
    p.add_argument("--out", default=default, required=default is None, metavar="DIR", type=output_dir_arg,
                   help="output directory (created if missing)" + (f"; default {default}" if default else ""))


def _writable_target(path: Path, want_dir: bool) -> str | None:
    """Why ``path`` cannot be used as an output directory (``want_dir``) or file, or None if it can (nothing
    is created)."""
    text = str(path)
    if not text.strip():
        return "empty path"
    if "\x00" in text:
        return "the path contains a NUL character"
    if path.exists():
        if want_dir and not path.is_dir():
            return "exists and is not a directory"
        if not want_dir and path.is_dir():
            return "is a directory (a file name is expected)"
        if not os.access(path if path.is_dir() else path.parent if str(path.parent) else Path("."), os.W_OK):
            return "is not writable (permission denied)"
        return None
    parent = path.parent
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    if not parent.is_dir():
        return f"cannot be created: '{parent}' is a file, not a directory"
    if not os.access(parent, os.W_OK | os.X_OK):
        return f"cannot be created: '{parent}' is not writable (permission denied)"
    return None


def _output_path(text: str, want_dir: bool) -> str:
    """``text`` as an output directory (``want_dir``) or file path, or :class:`argparse.ArgumentTypeError` saying
    why it cannot be one (empty, a file where a directory is wanted or the reverse, not writable)."""
    if not text.strip():
        raise argparse.ArgumentTypeError(f"empty path: give a {'directory' if want_dir else 'file name'}")
    why = _writable_target(Path(text), want_dir=want_dir)
    if why is not None:
        raise argparse.ArgumentTypeError(f"'{text}' {why}")
    return text


def output_dir_arg(text: str) -> str:
    """argparse ``type=`` of an output directory: refused at parse time when it is a file or cannot be created."""
    return _output_path(text, want_dir=True)


def output_file_arg(text: str) -> str:
    """argparse ``type=`` of an output file: refused at parse time when it is a directory or cannot be written."""
    return _output_path(text, want_dir=False)


def add_params_arg(p: argparse.ArgumentParser) -> None:
    p.add_argument("--params", default="table2", metavar="NAME",
                   help="parameter set: a shipped name (table2, calibrated) or a path to a .toml file")


def out_dir(path: str | Path, option: str = "--out") -> Path:
    """Create (if missing) and return an output directory; a path that is a file, or a directory that cannot be
    created or written, is an :class:`OutputPathError` naming ``option``, the path and the reason (exit 2)."""
    d = Path(path)
    why = "empty path" if not str(path).strip() else _writable_target(d, want_dir=True)
    if why is None:
        try:
            d.mkdir(parents=True, exist_ok=True)
        except FileExistsError:
            why = "exists and is not a directory"
        except NotADirectoryError:
            why = "cannot be created: a parent is a file, not a directory"
        except PermissionError:
            why = "cannot be created (permission denied)"
        except OSError as exc:
            why = f"cannot be created ({exc.strerror or exc})"
    if why is not None:
        raise OutputPathError(f"{option} {d}: {why}")
    return d


def dump_json(obj: Any) -> str:
    return json.dumps(to_jsonable(obj), indent=2, sort_keys=False)


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
