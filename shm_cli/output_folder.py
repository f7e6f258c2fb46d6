"""The ``--out`` folder of ``shm run`` (a single run or a life): the files a run writes there, what an earlier run
left, and their removal — so that two runs' files never mix and nothing a user made is replaced by accident."""

from __future__ import annotations

import json
import shutil
import sqlite3
from pathlib import Path

#: files a run writes into --out (removed by --force before a new run, so that two runs' files never mix)
RUN_OUTPUTS: tuple[str, ...] = ("usage.db", "usage.db-wal", "usage.db-shm", "timeline.txt", "trace.csv",
                                "trace.npz", "summary.json", "report.html", "overview.png", "maintenance.png",
                                "usage.png", "records", "life.json", "life.png")


def previous_run(out: Path) -> str | None:
    """What an earlier run left in ``out``, in words (None: nothing of a run)."""
    present = [n for n in RUN_OUTPUTS if (out / n).exists()]
    if not present:
        return None
    what = ""
    summary = out / "summary.json"
    if summary.exists():
        try:
            d = json.loads(summary.read_text())
            what = f"scenario '{d.get('scenario')}', {d.get('ticks')} ticks, status {d.get('status', 'finished')}"
        except (OSError, ValueError):
            what = ""
    if not what and (out / "usage.db").exists():
        from studies.batch.runner import counted

        try:
            db = sqlite3.connect(f"file:{out / 'usage.db'}?mode=ro", uri=True)
            try:
                row = db.execute("SELECT count(*), max(started_utc), "
                                 "(SELECT status FROM runs ORDER BY run_id DESC LIMIT 1) FROM runs").fetchone()
            finally:
                db.close()
            what = f"{counted(row[0], 'run')} in usage.db, the last started {row[1]}, status {row[2]}"
        except sqlite3.DatabaseError:
            what = "usage.db"
    return what or ", ".join(present)


def remove_run_outputs(out: Path) -> None:
    """Remove every file (and the ``records/`` folder) a run writes from ``out``; anything else stays."""
    for name in RUN_OUTPUTS:
        target = out / name
        if target.is_dir() and not target.is_symlink():
            shutil.rmtree(target)
        else:
            target.unlink(missing_ok=True)


def last_visit_number(records: Path) -> int:
    """Highest NNN of the ``visit-NNN_mbit-X.csv`` files in ``records`` (0: none)."""
    best = 0
    for f in records.glob("visit-*_mbit-*.csv") if records.is_dir() else ():
        num = f.name[len("visit-"):].split("_", 1)[0]
        if num.isdigit():
            best = max(best, int(num))
    return best
