"""What a batch or a fleet may write into its ``--out`` (issue 31): its table files (``summary.csv``/``.html`` and
``batch.json``, or ``fleet.csv``/``.html``/``.json``) and one folder per task — never over the user's own files or
another command's run.

Allowed without ``--force``: a new or empty folder, or one holding an earlier batch of the same command (its
``batch.json``/``fleet.json``), whose task folders hold that command's reports. Refused (exit 2, naming the file or
folder): a table file that no earlier batch of the command wrote (the user's own ``summary.csv``), a task folder
holding another command's run (``shm health --fleet fleet/board* --out fleet`` would have rewritten each board's own
``report.html`` and ``log.txt``) or files of no earlier batch, a file where a task's folder goes, and an ``--out``
that holds another command's finished run.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path

from shm_cli.common import OutputPathError
from shm_cli.output_guard import RUN_MARKERS, check_foreign_run


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
