"""What a batch or a fleet may write into its ``--out`` (issue 31): its table files (``summary.csv``/``.html`` and
``batch.json``, or ``fleet.csv``/``.html``/``.json``) and one folder per task — never over the user's own files or
another command's run.

Allowed without ``--force``: a new or empty folder, or one holding an earlier batch of the same command (its
``batch.json``/``fleet.json``), whose task folders hold that command's reports. Refused (exit 2, naming the file or
folder): a table file that no earlier batch of the command wrote (the user's own ``summary.csv``), a task folder
holding another command's run (``shm health --fleet fleet/board* --out fleet`` would have rewritten each board's own
``report.html`` and ``log.txt``) or files of no earlier batch, a file where a task's folder goes, and an ``--out``
that holds another command's finished run.

A re-run writes each task's folder afresh (:func:`write_task_folders`): the files an earlier batch wrote there that
this run does not write are removed — the earlier batch's marker lists each task's files (``task_files``) — and
nothing else is: a file of the user's in a task's folder stays, and is named on stderr.
"""

from __future__ import annotations

import json
import os
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path, PurePosixPath

from shm_cli.common import OutputPathError
from shm_cli.output_guard import RUN_MARKERS, check_foreign_run
from shm_cli.run_lock import LOCK_NAME


def _earlier_command(out: Path, marker: str) -> str | None:
    """The command of the earlier batch whose ``marker`` (batch.json / fleet.json) is in ``out`` (None: none)."""
    path = out / marker
    if not path.is_file():
        return None
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return "an unreadable batch"
    return str(doc.get("command", "health")) if isinstance(doc, dict) else "an unreadable batch"


def _refuse(what: str, force_hint: bool) -> OutputPathError:
    tail = "choose another --out" + (", or give --force to write there anyway" if force_hint else "")
    return OutputPathError(f"{what}: not overwriting it; {tail}")


def check_batch_out(out: Path, command: str, keys: Sequence[str], tables: Sequence[str], task_marker: str,
                    force: bool, force_hint: bool = True) -> None:
    """Refuse ``out`` for a batch of ``command`` whose tasks are ``keys`` (see the module docstring). ``tables``:
    the files written at the top, the last one the batch's own marker; ``task_marker``: the JSON document a task of
    ``command`` writes into its folder. Nothing is checked with ``force``."""
    if force or not out.is_dir():
        return
    marker = tables[-1]
    check_foreign_run(out, marker, force)
    earlier = _earlier_command(out, marker)
    if earlier is not None and earlier != command:
        raise _refuse(f"--out {out} holds an earlier 'shm {earlier}' batch ({marker})", force_hint)
    if earlier is None:
        for name in tables:
            if (out / name).exists():
                raise _refuse(f"--out {out}: {name} is there and no earlier 'shm {command}' batch wrote it "
                              f"(no {marker} beside it)", force_hint)
    for key in keys:
        folder = out / key
        if not folder.exists() and not folder.is_symlink():
            continue
        if not folder.is_dir():
            raise _refuse(f"--out {out}: {key} is a file, and task {key}'s report goes into a folder of that name",
                          force_hint)
        foreign = [m for m in RUN_MARKERS if m != task_marker and (folder / m).exists()]
        if foreign:
            raise _refuse(f"--out {out}: {folder} holds {RUN_MARKERS[foreign[0]]}'s output ({foreign[0]}), and task "
                          f"{key}'s report would be written over it", force_hint)
        if earlier is None and any(folder.iterdir()):
            raise _refuse(f"--out {out}: {folder} holds files of no earlier 'shm {command}' batch, and task {key}'s "
                          "report would be written into it", force_hint)


#: the key of a batch's marker (batch.json / fleet.json) listing the files it wrote into each task's folder
TASK_FILES = "task_files"


def earlier_task_files(out: Path, marker: str) -> dict[str, list[str]]:
    """The files each task's folder got from the earlier batch in ``out`` (its ``marker``'s :data:`TASK_FILES`,
    paths relative to the task's folder); empty when there is none, or it was written before the list was kept
    (its files are then not known to be the tool's, and none is removed)."""
    try:
        doc = json.loads((out / marker).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    files = doc.get(TASK_FILES) if isinstance(doc, dict) else None
    if not isinstance(files, dict):
        return {}
    return {str(k): [str(f) for f in v if isinstance(f, str)] for k, v in files.items() if isinstance(v, list)}


def _within(folder: Path, rel: str) -> Path | None:
    """``folder/rel`` when ``rel`` is a plain relative path that stays inside ``folder`` (no ``..``, not absolute,
    no symbolic link on the way); None otherwise (a marker edited by hand names nothing outside the task)."""
    parts = PurePosixPath(rel).parts
    if not parts or PurePosixPath(rel).is_absolute() or any(p in ("", ".", "..") for p in parts):
        return None
    path = folder.joinpath(*parts)
    for parent in [folder, *list(path.parents)[: len(parts) - 1]]:
        if parent.is_symlink():
            return None
    return path


def files_in(folder: Path) -> list[str]:
    """Every file under ``folder`` (symbolic links not followed), relative, sorted; not an ``--out`` lock file
    (an empty one that earlier batches copied from the task's command is left, never removed: it may be held)."""
    found = []
    for root, dirs, names in os.walk(folder):
        here = Path(root)
        found += [str((here / n).relative_to(folder)) for n in names if n != LOCK_NAME]
        found += [str((here / d).relative_to(folder)) for d in dirs if (here / d).is_symlink()]
    return sorted(found)


def write_task_folders(out: Path, written: Mapping[str, Mapping[str, bytes]], earlier: Mapping[str, Sequence[str]],
                       what: str) -> dict[str, list[str]]:
    """Write each task's files (``written``: task key -> relative name -> bytes) into ``out/<key>/`` and remove the
    files the earlier batch wrote there (``earlier``, from :func:`earlier_task_files`) that this run does not write:
    a task's folder then holds this run's report, not an earlier run's figure or page beside it. A file no batch
    listed (the user's own, or of a batch that kept no list) is left and named on stderr (``what``: ``shm
    diagnose``); so is the folder of an earlier task that this run did not run. The new :data:`TASK_FILES`: this
    run's files, and the earlier tasks' files that are still there."""
    from studies.batch.runner import counted

    listed: dict[str, list[str]] = {}
    for key, files in written.items():
        folder = out / key
        for rel, data in files.items():
            dest = folder / rel
            dest.parent.mkdir(parents=True, exist_ok=True)
            dest.write_bytes(data)
        for rel in earlier.get(key, ()):
            path = _within(folder, rel) if rel not in files and PurePosixPath(rel).name != LOCK_NAME else None
            if path is not None and path.is_file() and not path.is_symlink():
                path.unlink()
                for parent in list(path.parents)[: len(PurePosixPath(rel).parts) - 1]:
                    if any(parent.iterdir()):
                        break
                    parent.rmdir()
        listed[key] = sorted(files)
        others = [f for f in files_in(folder) if f not in files]
        if others:
            names = ", ".join(others[:3]) + (f" and {len(others) - 3} more" if len(others) > 3 else "")
            print(f"{what}: note: {folder} also holds {counted(len(others), 'file')} this run did not write, left as "
                  f"they are: {names}", file=sys.stderr)
    for key in sorted(set(earlier) - set(written)):
        still = [rel for rel in earlier[key] if (p := _within(out / key, rel)) is not None and p.is_file()]
        if still:
            listed[key] = still
            print(f"{what}: note: {out / key} is a task of an earlier batch, not of this one: left as it is (not "
                  "in this run's table)", file=sys.stderr)
    return dict(sorted(listed.items()))
