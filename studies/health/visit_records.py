"""Each completed MBIT's full-rate drive and response as a measurement record (docs/records.md), linked in the log.

The board's maintenance sequencer emits an ``mbit_record`` event (rows of board time, v_ch1, v_ch2, z3) just before
its ``mbit_result``. :class:`VisitRecordWriter` turns it into ``records/visit-NNN_mbit-X.csv`` (CSV with a TOML
header, read as is by ``shm compare``, ``shm fit``, ``shm diagnose`` and ``shm health``) and, once the verdict row is
in the usage log, adds a row to the log's ``mbit_records`` table linking the MBIT result (and so the visit's
verdict) to the file.

Header keys: ``test`` (``mbit-a``/``mbit-b``), ``sample_rate_Hz`` (the tick rate, 100 Hz), ``terminal =
"amplifier"``, ``inputs``, ``params`` (the board's nominal set), ``operating_hours`` (when known), ``[channels.z3_m]``
(laser noise σ), ``[[segments]]`` (settle, the MBIT) and ``[provenance]`` (``generator = "board"``, scenario, run id,
visit number, board time of the first row, MBIT label; for a life also ``run_uid`` and ``board_id``,
:func:`run_identity`, which ``shm health`` checks to keep records of different runs or boards apart).

A tick whose sample the link lost (or whose sample the board could not trust) keeps its row — time and the
commanded channels — with an empty ``z3_m`` cell; the header says ``missing = "empty"`` (docs/records.md, "Lost
samples"), so every reader leaves that row out of the comparison instead of refusing the record.

Storage: one row per tick of the MBIT and of its preceding settle — MBIT.a 22 s = 2 201 rows ≈ 95 kB, MBIT.b 5 s =
501 rows ≈ 22 kB with the shipped ``mbit.toml``: about 120 kB per visit, bounded by the fixed MBIT sequence (a visit
never writes more, however long HV stays connected).
"""

from __future__ import annotations

import hashlib
import json
import sqlite3
import uuid
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from firmware_sim.events import BoardEvent
from workbench.records import record_from_arrays, write_record

LINK_SCHEMA = """
CREATE TABLE IF NOT EXISTS mbit_records(
    id INTEGER PRIMARY KEY, run_id INTEGER NOT NULL, mbit_result_id INTEGER, tick INTEGER NOT NULL,
    time_s REAL NOT NULL, visit INTEGER NOT NULL, mbit TEXT NOT NULL, verdict TEXT, path TEXT NOT NULL,
    operating_hours REAL, n_samples INTEGER, bytes INTEGER);
CREATE TABLE IF NOT EXISTS life_visits(
    id INTEGER PRIMARY KEY, run_id INTEGER NOT NULL, visit INTEGER NOT NULL, operating_hours REAL NOT NULL,
    board_time_s REAL NOT NULL, flights_before INTEGER, verdict TEXT, truth_json TEXT, seed INTEGER);
"""


def record_file_name(visit: int, mbit: str) -> str:
    return f"visit-{visit:03d}_mbit-{mbit}.csv"


def run_identity(board_config: Mapping[str, Any]) -> dict[str, str]:
    """What makes a run's records belong together (``shm health`` checks it): ``run_uid``, a random id drawn once
    per run, and ``board_id``, the board's identity — the first 12 hex digits of the SHA-256 of its configuration
    (a simulated board has no serial number; two boards configured differently never share it)."""
    text = json.dumps(dict(board_config), sort_keys=True, default=str)
    return {"run_uid": uuid.uuid4().hex, "board_id": "cfg-" + hashlib.sha256(text.encode()).hexdigest()[:12]}


def mbit_record(event: BoardEvent, *, visit: int, operating_hours: float | None, params: str,
                z3_noise_m: float, scenario: str = "", run_id: int | None = None, time_offset_s: float = 0.0,
                identity: Mapping[str, str] | None = None):
    """The :class:`workbench.records._io.Record` of an ``mbit_record`` event (time from 0 at the settle's start)."""
    d = event.data
    rows = np.asarray(d["rows"], dtype=float).reshape(-1, 4)
    t = np.round(rows[:, 0] - rows[0, 0], 9)  # board time differences, without their float residue
    meta: dict[str, Any] = {  # the record file's JSON header (the format's edge)
        "test": d["test"], "description": f"{d['label']} as the board ran it (visit {visit})",
        "sample_rate_Hz": float(d["rate_Hz"]), "terminal": "amplifier", "inputs": ["v_ch1_V", "v_ch2_V"],
        "params": params, "channels": {"z3_m": {"sensor": "laser (tip)", "noise_std": float(z3_noise_m)}},
        "missing": "empty",  # a sample the link lost is an empty z3 cell (docs/records.md, Lost samples)
        "provenance": {"generator": "board", "scenario": scenario, "visit": int(visit), "mbit": d["mbit"],
                       "label": d["label"], "board_time_s": float(rows[0, 0] + time_offset_s)},
    }
    if run_id is not None:
        meta["provenance"]["run_id"] = int(run_id)
    meta["provenance"].update(identity or {})
    if operating_hours is not None:
        meta["operating_hours"] = float(operating_hours)
    n_mbit = int(d.get("mbit_ticks", len(rows) - 1))
    settle_end = float(t[max(0, len(rows) - n_mbit - 1)])  # the slew to the MBIT's first command starts here
    if settle_end > 0:
        meta["segments"] = [{"start_s": 0.0, "end_s": settle_end, "label": "settle"},
                            {"start_s": settle_end, "end_s": float(t[-1]), "label": d["label"]}]
    cols = {"v_ch1_V": rows[:, 1], "v_ch2_V": rows[:, 2], "z3_m": rows[:, 3]}
    return record_from_arrays(t, cols, meta, path=record_file_name(visit, d["mbit"]))


@dataclass
class _Pending:
    path: Path
    tick: int
    time_s: float
    mbit: str
    n: int
    bytes: int


class VisitRecordWriter:
    """Writes each ``mbit_record`` to ``out_dir/records/`` and links it in ``db_path`` once its result is logged.

    Feed it every event *after* the usage log has stored it (``on_event`` of the runner); ``visit`` and
    ``operating_hours`` are those of the current visit (:meth:`set_visit`; a plain run counts its visits).
    """

    def __init__(self, out_dir: str | Path, db_path: str | Path, *, params: str, z3_noise_m: float = 2e-6,
                 scenario: str = "", run_id: int | None = None, identity: Mapping[str, str] | None = None) -> None:
        self.dir = Path(out_dir) / "records"
        self.dir.mkdir(parents=True, exist_ok=True)
        self.db = sqlite3.connect(str(db_path), isolation_level=None)
        self.db.executescript("BEGIN;" + LINK_SCHEMA + "COMMIT;")
        self.params = params
        self.z3_noise = float(z3_noise_m)
        self.scenario = scenario
        self.run_id = run_id
        self.identity = dict(identity or {})
        self.visit = 0
        self.operating_hours: float | None = None
        self.time_offset_s = 0.0
        self._auto_visit = True
        self._pending: list[_Pending] = []
        self.written: list[Path] = []

    def set_visit(self, visit: int, operating_hours: float | None, time_offset_s: float = 0.0) -> None:
        self.visit = int(visit)
        self.operating_hours = operating_hours
        self.time_offset_s = float(time_offset_s)
        self._auto_visit = False

    def __call__(self, ev: BoardEvent) -> None:
        if ev.kind == "mbit_start" and self._auto_visit and ev.data.get("mbit") == "a":
            self.visit += 1
        if ev.kind == "mbit_record":
            if self._auto_visit and self.visit == 0:
                self.visit = 1
            rec = mbit_record(ev, visit=self.visit, operating_hours=self.operating_hours, params=self.params,
                              z3_noise_m=self.z3_noise, scenario=self.scenario, run_id=self.run_id,
                              time_offset_s=self.time_offset_s, identity=self.identity)
            path = self.dir / record_file_name(self.visit, ev.data["mbit"])
            write_record(rec, path)
            self.written.append(path)
            self._pending.append(_Pending(path, ev.tick, ev.time + self.time_offset_s, ev.data["mbit"],
                                          rec.n_samples, path.stat().st_size))
        elif ev.kind == "mbit_result" and self._pending:
            p = self._pending.pop(0)
            run = self.run_id if self.run_id is not None else self._last_run()
            row = self.db.execute("SELECT max(id) FROM mbit_results WHERE run_id=?", (run,)).fetchone()
            rel = str(p.path.relative_to(self.dir.parent))
            self.db.execute(
                "INSERT INTO mbit_records(run_id, mbit_result_id, tick, time_s, visit, mbit, verdict, path, "
                "operating_hours, n_samples, bytes) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                (run, row[0] if row else None, p.tick, p.time_s, self.visit, p.mbit, ev.data.get("verdict"), rel,
                 self.operating_hours, p.n, p.bytes))

    def _last_run(self) -> int | None:
        row = self.db.execute("SELECT max(run_id) FROM runs").fetchone()
        return row[0] if row else None

    def close(self) -> None:
        self.db.close()
