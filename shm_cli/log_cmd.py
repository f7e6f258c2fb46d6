"""``shm log show|export``: read the board's SQLite usage/event log.

    shm log show   --db FILE [--run N] [--table NAME | --tables] [--limit N] [--telemetry]
    shm log export --db FILE [--run N] [--table NAME] [--csv] [--out PATH]

``show`` prints the runs, then every record of the run (default: the last) in time order as a readable timeline;
``--tables`` lists every table the file holds (the board's own, ``meta``, and the ``mbit_records`` / ``life_visits``
tables ``shm run`` adds: the link from each verdict to its record, the visits of a life) with its row counts and
columns; ``--table NAME`` prints one of them. ``export`` writes every table (or one) as JSON (one object: table ->
list of rows; to stdout or ``--out FILE``) or, with ``--csv``, one CSV per table into ``--out DIR`` (a single
``--table`` goes to stdout when ``--out`` is not given); column names carry their units (``time_s``, ``v_battery_V``,
``operating_hours``). The database is opened read-only; a missing or foreign file is a clear error (exit 2).
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
from pathlib import Path
from typing import TextIO

from shm_cli.command_args import add_command_group
from shm_cli.common import nonnegative_int, out_dir, output_file_arg, positive_int


def register(sub: argparse._SubParsersAction) -> None:
    lsub = add_command_group(sub, "log", "show or export the board's SQLite usage/event log",
                             "Read the usage/event log written by `shm run` (schema in docs/board.md).")
    ps = lsub.add_parser("show", help="print the runs and a run's records as a timeline")
    _common(ps)
    ps.add_argument("--limit", type=nonnegative_int, default=0, help="print at most this many records (0 = all)")
    ps.add_argument("--telemetry", action="store_true",
                    help="include the periodic telemetry records (hidden by default: they are housekeeping)")
    ps.add_argument("--tables", action="store_true",
                    help="list every table of the log with its row counts (all runs, this run) and columns")
    ps.set_defaults(func=cmd_show)
    pe = lsub.add_parser("export", help="export tables as JSON (default) or CSV")
    _common(pe)
    pe.add_argument("--csv", action="store_true", help="CSV: one file per table in --out DIR")
    pe.add_argument("--out", default=None, metavar="PATH", help="output file (JSON) or directory (CSV)")
    pe.set_defaults(func=cmd_export)


def _common(p: argparse.ArgumentParser) -> None:
    p.add_argument("--db", required=True, metavar="FILE", help="usage log database (e.g. out/run/usage.db)")
    p.add_argument("--run", type=positive_int, default=None, metavar="N", help="run id (default: the last run)")
    p.add_argument("--table", default=None, metavar="NAME",
                   help="only this table (any table of the log: `shm log show --db FILE --tables` lists them)")


def _open(args: argparse.Namespace):
    from firmware_sim.usage_log import KNOWN_TABLES, log_tables, open_log_readonly, read_table
    from shm_cli.main import CliError

    try:
        db = open_log_readonly(args.db)
    except (FileNotFoundError, ValueError) as exc:
        raise CliError(str(exc)) from None
    tables = log_tables(db)
    if args.table is not None and args.table not in tables:
        why = ("this log has no such table (mbit_records comes with runs that store MBIT records, life_visits "
               "with a life)" if args.table in KNOWN_TABLES else "unknown table")
        raise CliError(f"--table {args.table!r}: {why} (tables in {args.db}: {', '.join(tables)})")
    cols, runs = read_table(db, "runs")
    run_ids = [r[0] for r in runs]
    run = args.run if args.run is not None else (run_ids[-1] if run_ids else None)
    if args.run is not None and args.run not in run_ids:
        raise CliError(f"--run {args.run}: no such run in {args.db} (runs: {run_ids or 'none'})")
    return db, cols, runs, run


def cmd_show(args: argparse.Namespace) -> int:
    from firmware_sim.usage_log import iter_records
    from shm_cli.main import CliError

    if args.tables and args.table is not None:
        raise CliError("--tables lists every table; --table NAME shows one: give one of them")
    db, cols, runs, run = _open(args)
    from studies.batch.runner import counted

    print(f"{args.db}: {counted(len(runs), 'run')}")
    for r in runs:
        d = dict(zip(cols, r))
        print(f"  run {d['run_id']}: {d['status']}, scenario {d['scenario']}, seed {d['seed']}, link {d['link_url']}, "
              f"params {d['params']}, started {d['started_utc']}, finished {d['finished_utc'] or '-'}")
    if args.tables:
        _print_tables(db, run)
        return 0
    if args.table is not None:
        _print_table(db, args.table, run, args.limit)
        return 0
    if run is None:
        return 0
    print(f"records of run {run}:")
    n = 0
    hidden = 0
    for t, table, d in iter_records(db, run):
        if table == "telemetry" and not args.telemetry:
            hidden += 1
            continue
        shown = {k: v for k, v in d.items() if k not in _ROW_KEYS and v is not None and not k.endswith("_json")}
        print(f"  {t:10.2f} s  {table:<20} " + ", ".join(f"{k}={_cell(v)}" for k, v in shown.items()))
        n += 1
        if args.limit and n >= args.limit:
            break
    if hidden:
        print(f"  ({hidden} telemetry records not shown; --telemetry shows them, --table telemetry lists them)")
    return 0


#: columns every timeline line already says (its time) or that only number rows
_ROW_KEYS = frozenset({"id", "run_id", "tick", "time_s"})


def _print_tables(db, run: int | None) -> None:
    from firmware_sim.usage_log import count_rows, log_tables, table_columns

    tables = log_tables(db)
    print(f"{len(tables)} tables (rows: all runs / run {run if run is not None else '-'}; "
          "`--table NAME` shows one, `shm log export` writes them all):")
    for t in tables:
        cols = table_columns(db, t)
        total = count_rows(db, t)
        mine = count_rows(db, t, run) if run is not None and "run_id" in cols else None
        rows = f"{total} / {mine}" if mine is not None else f"{total} (not per run)"
        print(f"  {t:<22} {rows:>16}  {', '.join(cols)}")


def _print_table(db, table: str, run: int | None, limit: int) -> None:
    from firmware_sim.usage_log import read_table, table_columns

    per_run = table != "runs" and "run_id" in table_columns(db, table)
    tcols, rows = read_table(db, table, run if per_run else None)
    print(f"table {table}" + (f" of run {run}" if per_run else "") + f": {len(rows)} row(s)")
    print("  " + " | ".join(tcols))
    for n, row in enumerate(rows, start=1):
        print("  " + " | ".join(_cell(v) for v in row))
        if limit and n >= limit:
            break


def _cell(v) -> str:
    if v is None:
        return "-"
    if isinstance(v, float):
        return f"{v:.6g}"
    return str(v)


def cmd_export(args: argparse.Namespace) -> int:
    from firmware_sim.usage_log import log_tables, read_table, table_columns
    from shm_cli.main import CliError

    db, _, _, run = _open(args)
    tables = [args.table] if args.table else log_tables(db)
    data = {}
    for t in tables:
        per_run = t != "runs" and "run_id" in table_columns(db, t)
        tcols, rows = read_table(db, t, run if per_run else None)
        if t == "runs" and run is not None:
            rows = [r for r in rows if r[0] == run]
        data[t] = (tcols, rows)
    if args.csv:
        if args.out is None:
            if len(tables) != 1:
                raise CliError("--csv without --out needs a single --table (several tables need a directory)")
            _write_csv(sys.stdout, *data[tables[0]])
            return 0
        d = Path(args.out)
        if d.exists() and not d.is_dir():
            raise CliError(f"--out {d}: exists and is not a directory (CSV export writes one file per table)")
        d = out_dir(d)
        for t, (tcols, rows) in data.items():
            with (d / f"{t}.csv").open("w", newline="") as fh:
                _write_csv(fh, tcols, rows)
        print(f"wrote {', '.join(f'{t}.csv' for t in data)} to {d}/", file=sys.stderr)
        return 0
    obj = {t: [dict(zip(tcols, r)) for r in rows] for t, (tcols, rows) in data.items()}
    text = json.dumps({"database": str(args.db), "run_id": run, "tables": obj}, indent=2, default=str)
    if args.out is None:
        print(text)
    else:
        try:
            output_file_arg(args.out)
        except argparse.ArgumentTypeError as exc:
            raise CliError(f"--out {exc} (JSON export writes one file)") from None
        out_dir(Path(args.out).parent, option="--out (its directory)")
        Path(args.out).write_text(text + "\n")
    return 0


def _write_csv(fh: TextIO, cols: list[str], rows: list[tuple]) -> None:
    w = csv.writer(fh)
    w.writerow(cols)
    w.writerows(rows)
