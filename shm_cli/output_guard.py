"""What the workbench commands may write (issue 33): only the files the user named, never over an existing file
without ``--force``, never over the project's shipped configuration, never into another command's finished run,
and always whole.

* :func:`check_new_file` — an output file the user named (``--emit``, ``--save``, synth's ``--out``): refused when it
  exists (unless ``--force``) or lies in the shipped ``board_config/`` or another of mfc-shm's own packages
  (always: those files are the project's).
* :func:`write_whole` — writes through a temporary file in the same directory and moves it into place: a reader
  never sees half a file, and two commands writing one name at once leave one whole file. Without ``--force`` the
  move refuses a file that appeared meanwhile (a hard link, which fails when the name exists).
* :func:`check_foreign_run` — an ``--out`` folder that holds another command's finished run (its marker file) is
  refused unless ``--force``: its report would be rewritten.
* :func:`locked_out` — the ``--out`` lock (:mod:`shm_cli.run_lock`): one command per folder at a time.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import secrets
import sys
from collections.abc import Callable, Iterator
from pathlib import Path

from shm_cli.common import OutputPathError
from shm_cli.run_lock import OutputLock

#: the project's shipped configuration (parameter sets, scenarios, board): never an output
SHIPPED_CONFIG = Path(__file__).resolve().parents[1] / "board_config"
#: mfc-shm's own packages (plant/effects holds the library effects): never an output either
OWN_PACKAGES = tuple(p for p in SHIPPED_CONFIG.parent.iterdir()
                     if (p / "__init__.py").is_file() and p.name != "bench")  # bench/ keeps results of its runs

#: a finished run's marker file -> the command that wrote it
RUN_MARKERS: dict[str, str] = {
    "summary.json": "shm run", "usage.db": "shm run", "life.json": "shm run (a life)", "health.json": "shm health",
    "compare.json": "shm compare", "diagnosis.json": "shm diagnose", "fit.json": "shm fit",
    "discover.json": "shm discover", "campaign.json": "shm campaign", "calibration.json": "shm calibrate",
    "harvest_summary.json": "shm harvest",
}


def add_force_arg(p: argparse._ActionsContainer, what: str) -> None:
    """``--force`` on ``p`` (a parser, or a group of options that exclude each other)."""
    p.add_argument("--force", action="store_true", help=f"replace {what} when it exists (refused otherwise)")


def _is_within(path: Path, folder: Path) -> bool:
    try:
        path.resolve().relative_to(folder.resolve())
    except (ValueError, OSError):
        return False
    return True


def check_new_file(path: Path, option: str, force: bool) -> None:
    """Refuse ``path`` as an output (exit 2, naming ``option``) when it is in the shipped configuration, or exists and
    ``force`` is not given; a symbolic link is refused too unless ``force`` (its target would be replaced)."""
    own = next((pkg for pkg in OWN_PACKAGES if _is_within(path, pkg)), None)
    if own is not None:
        what = "shipped configuration" if own == SHIPPED_CONFIG else f"own package '{own.name}'"
        raise OutputPathError(f"{option} {path}: inside the project's {what} ({own}); those files are part of mfc-shm "
                              "and are never written or replaced (--force does not apply): write your own file "
                              "elsewhere and load it by its path")
    if (path.exists() or path.is_symlink()) and not force:
        raise OutputPathError(f"{option} {path} already exists: it would be replaced; choose another name, or give "
                              "--force to replace it")


def write_whole(path: Path, write: Callable[[Path], object], option: str, force: bool) -> None:
    """Call ``write(tmp)`` on a temporary file beside ``path`` (same suffix) and move it to ``path``: replacing an
    existing file only with ``force``; a file that appeared meanwhile is refused (exit 2) and the temporary removed."""
    # a fresh name the writer creates itself (the file mode follows the umask, as a direct write would)
    tmp = path.parent / f".{path.stem}.{os.getpid()}.{secrets.token_hex(4)}.tmp{path.suffix}"
    try:
        write(tmp)
        if force:
            os.replace(tmp, path)
        else:
            try:
                os.link(tmp, path)  # fails when the name exists: a concurrent writer got there first
            except FileExistsError:
                raise OutputPathError(f"{option} {path} appeared while this command ran (another command wrote "
                                      "it): left as it is; give --force to replace it") from None
            except OSError:  # a file system without hard links: the check at the start is all there is
                os.replace(tmp, path)
    finally:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()


def check_foreign_run(out: Path, own_marker: str, force: bool, option: str = "--out") -> None:
    """Refuse an ``--out`` folder holding another command's finished run (a marker of :data:`RUN_MARKERS` other
    than ``own_marker``) unless ``force``: its report and files would be rewritten."""
    if force or not out.is_dir():
        return
    for marker, command in RUN_MARKERS.items():
        if marker != own_marker and (out / marker).exists():
            raise OutputPathError(f"{option} {out} holds a finished {command} run ({marker}): writing there would "
                                  f"rewrite its report; choose another {option}, or give --force to write into it")


@contextlib.contextmanager
def locked_out(out: Path, command: str, option: str = "--out") -> Iterator[OutputLock]:
    """Hold the ``--out`` lock of ``out`` while the block runs (a second command on it: exit 2 naming the first)."""
    words = " ".join(["shm", command, *sys.argv[2:]]) if len(sys.argv) > 1 else f"shm {command}"
    with OutputLock(out, command=words[:300], option=option) as lock:
        yield lock
