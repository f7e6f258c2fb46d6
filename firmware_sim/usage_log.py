"""The board's usage and event log: an embedded SQLite database (schema below, also in ``docs/board.md``).

Durability: the database runs in WAL mode and every record is written in its own transaction, committed before
:meth:`UsageLog.write` returns. A process killed with SIGKILL at any instant therefore loses no record whose ``write``
had returned — the commit is in the WAL file, which SQLite replays on the next open (a test kills a real subprocess
and checks every acknowledged record is there). ``synchronous=NORMAL`` (default) is what that needs; ``FULL`` also
survives an operating-system crash or a power cut, at the price of one fsync per record (~5 ms on this project's
virtual machines, which would dominate a virtual-time run). Several runs can share one database (``runs`` table).

The file is marked as ours (``PRAGMA application_id`` = 0x4D464353 "MFCS", ``PRAGMA user_version`` = the schema
version); opening an existing file that is not a usage log of this schema raises :class:`ForeignLogError` before
anything is written to it.

Schema (version 1; every time in s of board time, every voltage in V — units are in the column names)::

    meta(key TEXT PRIMARY KEY, value TEXT)                         -- schema_version, created_utc, software
    runs(run_id INTEGER PRIMARY KEY, started_utc TEXT, finished_utc TEXT, status TEXT, scenario TEXT,
         seed INTEGER, link_url TEXT, params TEXT, board_config_json TEXT, rig_json TEXT)
    regime_changes(id INTEGER PRIMARY KEY, run_id INTEGER, tick INTEGER, time_s REAL, from_regime TEXT,
         to_regime TEXT, trigger TEXT, causes TEXT, v_battery_V REAL)
    incidents(id INTEGER PRIMARY KEY, run_id INTEGER, tick INTEGER, time_s REAL, incident TEXT, regime TEXT,
         detail TEXT)
    usage_summaries(id INTEGER PRIMARY KEY, run_id INTEGER, tick INTEGER, time_s REAL, t_start_s REAL,
         t_end_s REAL, duration_s REAL, samples INTEGER, peak_z3_m REAL, peak_z3_pos_m REAL, peak_z3_neg_m REAL,
         peak_z0dd_m_s2 REAL, n_reversals INTEGER, n_cycles REAL, max_range_m REAL, reason TEXT,
         rainflow_json TEXT, exceedance_json TEXT)
    mbit_results(id INTEGER PRIMARY KEY, run_id INTEGER, tick INTEGER, time_s REAL, mbit TEXT, label TEXT,
         verdict TEXT, fault_time_s REAL, max_count INTEGER, max_eps REAL, n_samples INTEGER, n_exceed INTEGER,
         n_invalid INTEGER, clamp_json TEXT)
    maintenance_verdicts(id INTEGER PRIMARY KEY, run_id INTEGER, tick INTEGER, time_s REAL, verdict TEXT,
         mbits TEXT, detail TEXT)
    telemetry(id INTEGER PRIMARY KEY, run_id INTEGER, tick INTEGER, time_s REAL, regime TEXT, v_battery_V REAL,
         monitor_count INTEGER, charge_used_C REAL, incidents_total INTEGER)

Tables other parts of the project add to the same file (:data:`LINKED_TABLES`; schema in ``docs/health.md``):
``mbit_records`` (each MBIT result's measurement record file) and ``life_visits`` (the visits of a life). The
readers below (:func:`log_tables`, :func:`read_table`) list and read every table the file holds.

``rainflow_json``: ``[{"range_low_m", "range_high_m", "cycles"}, ...]``; ``exceedance_json``:
``[{"level_m", "time_s", "upcrossings"}, ...]``; ``clamp_json``: the MBIT generator's clamp report.
"""

from __future__ import annotations

import json
import sqlite3
from collections.abc import Iterator, Mapping
from datetime import UTC, datetime
from pathlib import Path
from types import TracebackType
from typing import Any

from board_config.errors import InputError
from firmware_sim.events import BoardEvent

SCHEMA_VERSION = 1
#: SQLite ``PRAGMA application_id`` of a usage log ("MFCS"); ``PRAGMA user_version`` holds SCHEMA_VERSION
APPLICATION_ID = 0x4D464353
_SQLITE_MAGIC = b"SQLite format 3\x00"

_SCHEMA = """
CREATE TABLE IF NOT EXISTS meta(key TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS runs(
    run_id INTEGER PRIMARY KEY, started_utc TEXT NOT NULL, finished_utc TEXT, status TEXT NOT NULL,
    scenario TEXT, seed INTEGER, link_url TEXT, params TEXT, board_config_json TEXT, rig_json TEXT);
CREATE TABLE IF NOT EXISTS regime_changes(
    id INTEGER PRIMARY KEY, run_id INTEGER NOT NULL REFERENCES runs(run_id), tick INTEGER NOT NULL,
    time_s REAL NOT NULL, from_regime TEXT NOT NULL, to_regime TEXT NOT NULL, trigger TEXT NOT NULL, causes TEXT,
    v_battery_V REAL);
CREATE TABLE IF NOT EXISTS incidents(
    id INTEGER PRIMARY KEY, run_id INTEGER NOT NULL REFERENCES runs(run_id), tick INTEGER NOT NULL,
    time_s REAL NOT NULL, incident TEXT NOT NULL, regime TEXT, detail TEXT);
CREATE TABLE IF NOT EXISTS usage_summaries(
    id INTEGER PRIMARY KEY, run_id INTEGER NOT NULL REFERENCES runs(run_id), tick INTEGER NOT NULL,
    time_s REAL NOT NULL, t_start_s REAL NOT NULL, t_end_s REAL NOT NULL, duration_s REAL NOT NULL,
    samples INTEGER NOT NULL, peak_z3_m REAL, peak_z3_pos_m REAL, peak_z3_neg_m REAL, peak_z0dd_m_s2 REAL,
    n_reversals INTEGER, n_cycles REAL, max_range_m REAL, reason TEXT, rainflow_json TEXT, exceedance_json TEXT);
CREATE TABLE IF NOT EXISTS mbit_results(
    id INTEGER PRIMARY KEY, run_id INTEGER NOT NULL REFERENCES runs(run_id), tick INTEGER NOT NULL,
    time_s REAL NOT NULL, mbit TEXT NOT NULL, label TEXT, verdict TEXT NOT NULL, fault_time_s REAL,
    max_count INTEGER, max_eps REAL, n_samples INTEGER, n_exceed INTEGER, n_invalid INTEGER, clamp_json TEXT);
CREATE TABLE IF NOT EXISTS maintenance_verdicts(
    id INTEGER PRIMARY KEY, run_id INTEGER NOT NULL REFERENCES runs(run_id), tick INTEGER NOT NULL,
    time_s REAL NOT NULL, verdict TEXT NOT NULL, mbits TEXT, detail TEXT);
CREATE TABLE IF NOT EXISTS telemetry(
    id INTEGER PRIMARY KEY, run_id INTEGER NOT NULL REFERENCES runs(run_id), tick INTEGER NOT NULL,
    time_s REAL NOT NULL, regime TEXT, v_battery_V REAL, monitor_count INTEGER, charge_used_C REAL,
    incidents_total INTEGER);
"""

#: table -> columns written from an event's data (besides id, run_id, tick, time_s)
TABLE_COLUMNS: dict[str, tuple[str, ...]] = {
    "regime_changes": ("from_regime", "to_regime", "trigger", "causes", "v_battery_V"),
    "incidents": ("incident", "regime", "detail"),
    "usage_summaries": ("t_start_s", "t_end_s", "duration_s", "samples", "peak_z3_m", "peak_z3_pos_m",
                        "peak_z3_neg_m", "peak_z0dd_m_s2", "n_reversals", "n_cycles", "max_range_m", "reason",
                        "rainflow_json", "exceedance_json"),
    "mbit_results": ("mbit", "label", "verdict", "fault_time_s", "max_count", "max_eps", "n_samples", "n_exceed",
                     "n_invalid", "clamp_json"),
    "maintenance_verdicts": ("verdict", "mbits", "detail"),
    "telemetry": ("regime", "v_battery_V", "monitor_count", "charge_used_C", "incidents_total"),
}
#: event kind -> table
KIND_TABLE: dict[str, str] = {
    "regime_change": "regime_changes", "incident": "incidents", "usage_summary": "usage_summaries",
    "mbit_result": "mbit_results", "maintenance_verdict": "maintenance_verdicts", "telemetry": "telemetry",
}
LOG_TABLES: tuple[str, ...] = ("runs", *TABLE_COLUMNS)
#: tables other parts of the project add to the same file: ``mbit_records`` links each MBIT result (and so the
#: visit's verdict) to its measurement record, ``life_visits`` lists the visits of a life (both written by
#: ``studies.health``: ``visit_records.py``, ``life.py``; schema in docs/health.md)
LINKED_TABLES: tuple[str, ...] = ("mbit_records", "life_visits")
#: every table a usage log may hold, in the order they are listed and exported
KNOWN_TABLES: tuple[str, ...] = ("meta", *LOG_TABLES, *LINKED_TABLES)


class LogError(RuntimeError):
    """The usage log cannot be opened or written (names the file and the reason)."""


class ForeignLogError(InputError):
    """The file given as a usage log is not one of ours (another application's database, not SQLite at all, or a
    newer schema): it is refused before anything is written to it."""


def check_is_usage_log(path: str | Path) -> None:
    """Refuse (:class:`ForeignLogError`) an existing, non-empty file that is not an mfc-shm usage log, without
    writing to it: it must be SQLite with our ``application_id`` (or, for logs written before it was set, a
    ``meta`` table with our ``schema_version`` and nothing but our tables) and a supported schema version."""
    p = Path(path)
    if not p.exists() or p.stat().st_size == 0:
        return
    if p.is_dir():
        raise ForeignLogError(f"{p}: is a directory, not a usage log")
    try:
        with p.open("rb") as fh:
            head = fh.read(len(_SQLITE_MAGIC))
    except OSError as exc:
        raise LogError(f"{p}: cannot read: {exc}") from None
    if head != _SQLITE_MAGIC:
        raise ForeignLogError(f"{p}: not an SQLite database, so not a usage log of mfc-shm; refusing to append "
                              "to it (move it away or choose another --out)")
    try:
        db = sqlite3.connect(f"file:{p}?mode=ro", uri=True)
        try:
            app_id = int(db.execute("PRAGMA application_id").fetchone()[0])
            tables = {r[0] for r in db.execute("SELECT name FROM sqlite_master WHERE type='table'")}
            version = None
            if "meta" in tables:
                row = db.execute("SELECT value FROM meta WHERE key='schema_version'").fetchone()
                version = None if row is None else row[0]
        finally:
            db.close()
    except sqlite3.DatabaseError as exc:
        raise ForeignLogError(f"{p}: not a readable SQLite database ({exc}); refusing to append to it") from None
    ours = set(KNOWN_TABLES)
    if app_id != APPLICATION_ID and not (app_id == 0 and version is not None and tables <= ours):
        other = f"application_id {app_id:#x}" if app_id else f"tables {', '.join(sorted(tables - ours)) or 'none'}"
        raise ForeignLogError(f"{p}: an SQLite database of another application ({other}), not an mfc-shm usage "
                              "log; refusing to append to it (move it away or choose another --out)")
    try:
        v = int(version) if version is not None else None
    except ValueError:
        v = -1
    if v != SCHEMA_VERSION:
        raise ForeignLogError(f"{p}: usage-log schema version {version!r} is not the supported {SCHEMA_VERSION}; "
                              "refusing to append to it")


def _now_utc() -> str:
    return datetime.now(UTC).isoformat(timespec="seconds")


def _row_id(cur: sqlite3.Cursor) -> int:
    """The id of the row an INSERT just stored (sqlite3 always sets it after an INSERT)."""
    row_id = cur.lastrowid
    if row_id is None:
        raise LogError("the usage log did not report the id of the row just written")
    return row_id


def _sql_value(v: Any) -> Any:
    if isinstance(v, (list, tuple, dict)):
        return json.dumps(v)
    if hasattr(v, "value") and isinstance(v.value, str):  # enums
        return v.value
    return v


class UsageLog:
    """Append-only writer of the usage/event log (one SQLite file). ``with UsageLog(path) as log: ...``.

    ``synchronous``: ``"NORMAL"`` (default: every committed record survives a process crash / SIGKILL) or ``"FULL"``
    (also an OS crash or power cut; one fsync per record).
    """

    def __init__(self, path: str | Path, synchronous: str = "NORMAL") -> None:
        self.path = Path(path)
        if synchronous not in ("FULL", "NORMAL"):
            raise ValueError(f"synchronous must be FULL or NORMAL, got {synchronous!r}")
        check_is_usage_log(self.path)
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._db = sqlite3.connect(str(self.path), isolation_level=None, check_same_thread=False)
            mode = self._db.execute("PRAGMA journal_mode=WAL").fetchone()[0]
            if str(mode).lower() != "wal":
                raise LogError(f"{self.path}: cannot switch the database to WAL mode (got {mode!r})")
            self._db.execute(f"PRAGMA synchronous={synchronous}")
            self._db.execute("PRAGMA foreign_keys=ON")
            self._db.executescript("BEGIN;" + _SCHEMA + "COMMIT;")
            row = self._db.execute("SELECT value FROM meta WHERE key='schema_version'").fetchone()
            if row is None:
                self._db.execute("INSERT INTO meta(key, value) VALUES ('schema_version', ?), ('created_utc', ?), "
                                 "('software', 'mfc-shm firmware_sim')", (str(SCHEMA_VERSION), _now_utc()))
            elif int(row[0]) != SCHEMA_VERSION:
                raise LogError(f"{self.path}: schema version {row[0]} is not the supported {SCHEMA_VERSION}")
            self._db.execute(f"PRAGMA application_id={APPLICATION_ID}")
            self._db.execute(f"PRAGMA user_version={SCHEMA_VERSION}")
        except sqlite3.DatabaseError as exc:
            raise LogError(f"{self.path}: cannot open the usage log: {exc}") from None
        self.run_id: int | None = None
        self._sql = {t: f"INSERT INTO {t}(run_id, tick, time_s, {', '.join(c)}) VALUES (?, ?, ?, "
                        f"{', '.join('?' * len(c))})" for t, c in TABLE_COLUMNS.items()}
        self.records = 0

    # --- runs ---------------------------------------------------------------------------------------
    def start_run(self, *, scenario: str = "", seed: int | None = None, link_url: str = "", params: str = "",
                  board_config: Mapping[str, Any] | None = None, rig: Mapping[str, Any] | None = None) -> int:
        cur = self._db.execute(
            "INSERT INTO runs(started_utc, status, scenario, seed, link_url, params, board_config_json, rig_json) "
            "VALUES (?, 'running', ?, ?, ?, ?, ?, ?)",
            (_now_utc(), scenario, seed, link_url, params, json.dumps(dict(board_config or {}), default=str),
             json.dumps(dict(rig or {}), default=str)))
        self.run_id = _row_id(cur)
        return self.run_id

    def finish_run(self, status: str = "finished") -> None:
        if self.run_id is not None:
            self._db.execute("UPDATE runs SET finished_utc=?, status=? WHERE run_id=?",
                             (_now_utc(), status, self.run_id))

    # --- records ------------------------------------------------------------------------------------
    def write(self, event: BoardEvent) -> int | None:
        """Store one board event (committed on return); returns its row id, or None for kinds not stored."""
        table = KIND_TABLE.get(event.kind)
        if table is None:
            return None
        if self.run_id is None:
            self.start_run()
        data = event.data
        values = [self.run_id, int(event.tick), float(event.time)]
        values += [_sql_value(data.get(c)) for c in TABLE_COLUMNS[table]]
        try:
            cur = self._db.execute(self._sql[table], values)
        except sqlite3.DatabaseError as exc:
            raise LogError(f"{self.path}: cannot write a {event.kind} record: {exc}") from None
        self.records += 1
        return _row_id(cur)

    def close(self, status: str | None = "finished") -> None:
        if status is not None:
            self.finish_run(status)
        self._db.close()

    def __enter__(self) -> UsageLog:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
                 ) -> None:
        self.close("failed" if exc_type is not None else "finished")


# --- reading ------------------------------------------------------------------------------------------
def open_log_readonly(path: str | Path) -> sqlite3.Connection:
    """Open an existing log for reading (a clear error if it is missing or not a usage log)."""
    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(f"{p}: no such usage log")
    try:
        db = sqlite3.connect(f"file:{p}?mode=ro", uri=True)
        row = db.execute("SELECT value FROM meta WHERE key='schema_version'").fetchone()
    except sqlite3.DatabaseError as exc:
        raise InputError(f"{p}: not a usage log database ({exc})") from None
    if row is None:
        raise InputError(f"{p}: not a usage log database (no schema_version)")
    return db


def log_tables(db: sqlite3.Connection) -> list[str]:
    """The tables this log holds: the known ones (:data:`KNOWN_TABLES`) in their order, then any other
    (SQLite's own ``sqlite_*`` tables left out) by name."""
    present = {r[0] for r in db.execute("SELECT name FROM sqlite_master WHERE type='table'")
               if not str(r[0]).startswith("sqlite_")}
    return [t for t in KNOWN_TABLES if t in present] + sorted(present - set(KNOWN_TABLES))


def table_columns(db: sqlite3.Connection, table: str) -> list[str]:
    """The column names of ``table`` (which must be one of :func:`log_tables`)."""
    return [str(r[1]) for r in db.execute(f'PRAGMA table_info("{table}")')]


def read_table(db: sqlite3.Connection, table: str, run_id: int | None = None
               ) -> tuple[list[str], list[tuple[Any, ...]]]:
    """Columns and rows of one log table in insertion order; with ``run_id``, only that run's rows when the table
    has a ``run_id`` column (``meta`` has none: all of it). An unknown table is an :class:`InputError` listing the
    tables of this log."""
    tables = log_tables(db)
    if table not in tables:
        raise InputError(f"unknown log table {table!r} (tables in this log: {', '.join(tables)})")
    where = " WHERE run_id=?" if run_id is not None and "run_id" in table_columns(db, table) else ""
    cur = db.execute(f'SELECT * FROM "{table}"{where} ORDER BY rowid', ((run_id,) if where else ()))
    cols = [d[0] for d in cur.description]
    return cols, cur.fetchall()


def count_rows(db: sqlite3.Connection, table: str, run_id: int | None = None) -> int:
    """How many rows ``table`` holds (of run ``run_id`` when given and the table has a ``run_id`` column)."""
    if table not in log_tables(db):
        raise InputError(f"unknown log table {table!r}")
    if run_id is not None and "run_id" in table_columns(db, table):
        return int(db.execute(f'SELECT count(*) FROM "{table}" WHERE run_id=?', (run_id,)).fetchone()[0])
    return int(db.execute(f'SELECT count(*) FROM "{table}"').fetchone()[0])


def iter_records(db: sqlite3.Connection, run_id: int | None = None) -> Iterator[tuple[float, str, dict[str, Any]]]:
    """Every stored record (except runs) as (time_s, table, row dict), ordered by time then table order: the
    board's records and, when the log has it, ``mbit_records`` (each MBIT's record file, after its result)."""
    rows = []
    present = log_tables(db)
    timed = [*TABLE_COLUMNS, *(t for t in LINKED_TABLES if t in present and "time_s" in table_columns(db, t))]
    for order, table in enumerate(timed):
        cols, data = read_table(db, table, run_id)
        for r in data:
            d = dict(zip(cols, r))
            rows.append((d["time_s"], order, d["id"], table, d))
    for t, _, _, table, d in sorted(rows, key=lambda x: (x[0], x[1], x[2])):
        yield t, table, d
