"""A fleet of boards on one scheduler (issue 31): ``shm health --fleet DIR...`` (one task per board's ``shm run``
output, a fleet table ranked by forecast first FAULT) and ``shm run --scenario aging --boards N --seed S`` (N boards
whose degradation rates scatter around the scenario's, seeded per board). docs/scale-out.md.

A fleet's ``boards.json`` lists the files each board's run wrote (``task_files``, as a batch's ``batch.json`` does:
:mod:`shm_cli.batch_out`); ``--force`` replaces those files only, and a file of the user's in a board's folder stays.
A pattern given to ``--fleet`` names the boards among what it matches: a match that holds no run is skipped (said)."""

from __future__ import annotations

import argparse
import contextlib
import functools
import glob
import io
import sys
from pathlib import Path
from typing import Any

from board_config.errors import InputError
from shm_cli.batch_out import TASK_FILES, check_batch_out, earlier_task_files, files_in, write_task_folders
from shm_cli.batch_records import REPORT_NAME, run_command_task, warm_workbench
from shm_cli.common import dump_json, out_dir
from shm_cli.output_folder import RUN_OUTPUTS
from shm_cli.output_guard import locked_out

#: the boards of a ``shm run --boards`` output, as a shell pattern (``board*`` would also match boards.csv/.html)
BOARD_GLOB = "board[0-9]*"
#: what ``shm run --boards`` writes beside its boards' folders: its table, and its manifest (each board's files)
BOARDS_TABLES = ("boards.csv", "boards.html", "boards.json")
#: a board's files that a fleet kept no list of (one written before boards.json) are its own only when a board's
#: life writes them: a file of RUN_OUTPUTS, the task's log, a visit record in records/ (studies.health.life)
BOARD_LOG, VISIT_RECORD = "log.txt", "records/visit-[0-9]*_mbit-*.csv"
FLEET_COLUMNS = ("rank", "board", "first_fault_h", "first_fault_90_lo_h", "first_fault_90_hi_h", "rul_h",
                 "where", "last_verdict")


def add_fleet_args(p: argparse.ArgumentParser, boards: bool) -> None:
    if boards:
        p.add_argument("--boards", type=int, default=None, metavar="N",
                       help="a fleet: N boards through a [life] scenario, each with its degradation rates scattered "
                            "(log-normal, seeded per board by --seed), in parallel on --scheduler; --out/boardNNN/")
    else:
        p.add_argument("--fleet", action="store_true",
                       help="each SOURCE is one board (a 'shm run' output): one task per board on --scheduler, a "
                            "fleet table and page ranked by forecast first FAULT (fleet.csv, fleet.html)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help=("with --boards or a [life] scenario" if boards else "with --fleet") + ": local (default: "
                        "local worker processes), tcp://HOST:PORT (a Dask cluster) or synchronous (this process)")


def board_folders(sources: list[str], skipped: list[Path] | None = None) -> list[Path]:
    """The boards of ``--fleet SOURCE...``: each SOURCE a folder, or a quoted pattern (``'fleet/board[0-9]*'``,
    as the record commands take) expanded here. A pattern names the boards among what it matches: a match that holds
    no run (no usage.db: a board folder a replaced fleet left with only the user's files in it, boards.csv) is left
    out, and added to ``skipped``; a pattern that matches no run is an error naming it."""
    from studies.batch.runner import counted

    folders = []
    for source in sources:
        if set("*?[") & set(source) and not Path(source).exists():
            matches = [Path(m) for m in sorted(glob.glob(source))]
            if not matches:
                raise InputError(f"--fleet: the pattern {source!r} matches no board folder")
            runs = [m for m in matches if (m / "usage.db").is_file()]
            if not runs:
                many = counted(len(matches), "match", "matches")
                raise InputError(f"--fleet: the pattern {source!r} matches no board's run ({many}, none with a "
                                 f"usage.db in it: {_names(matches)})")
            folders += runs
            if skipped is not None:
                skipped += [m for m in matches if m not in runs]
        else:
            folders.append(Path(source))
    return folders


def _names(paths: list[Path], most: int = 3) -> str:
    """The first ``most`` of ``paths`` and how many more."""
    shown = ", ".join(str(p) for p in paths[:most])
    return shown + (f" and {len(paths) - most} more" if len(paths) > most else "")


def _board_files(folder: Path) -> dict[str, bytes]:
    if not folder.exists():
        raise InputError(f"--fleet: {folder}: no such board folder")
    if not folder.is_dir():
        raise InputError(f"--fleet: {folder} is a file; each board is a 'shm run' output folder (of a 'shm run "
                         f"--boards' output: its {BOARD_GLOB} folders)")
    if not (folder / "usage.db").is_file():
        raise InputError(f"--fleet: {folder} is not a 'shm run' output (no usage.db in it)")
    files = {"usage.db": (folder / "usage.db").read_bytes()}
    for p in sorted((folder / "records").rglob("*")) if (folder / "records").is_dir() else []:
        if p.is_file():
            files[str(p.relative_to(folder))] = p.read_bytes()
    return files


def _report_of(results: list[Any]) -> dict[str, str]:
    return {r.key: f"{r.key}/report.html" for r in results
            if REPORT_NAME["health" if "health.json" in r.files else "run"] in r.files}


def _progress(what: str):
    last = [""]

    def show(p) -> None:
        line = p.line(what)
        if line != last[0]:
            print(line, file=sys.stderr, flush=True)
            last[0] = line
    return show


def run_fleet_health(args: argparse.Namespace) -> int:
    """``shm health --fleet DIR...``: each board's assessment as one task, the fleet ranked by first FAULT."""
    from studies.batch import run_tasks
    from studies.batch.fleet import fleet_row, rank_fleet
    from studies.batch.runner import check_scheduler, counted, reach_scheduler
    from studies.batch.summary import write_summary

    scheduler = check_scheduler(args.scheduler)
    skipped: list[Path] = []
    folders = board_folders(args.sources, skipped)
    names = [f.resolve().name for f in folders]
    twice = sorted({str(f) for f, n in zip(folders, names, strict=True) if names.count(n) > 1})
    if twice:
        raise InputError(f"--fleet: boards with the same folder name ({', '.join(twice)}); each board's folder "
                         "name names it in the fleet table: give each board once, under its own name")
    tasks = sorted(((n, _board_files(f)) for n, f in zip(names, folders, strict=True)), key=lambda t: t[0])
    if Path(args.out).resolve() in {f.resolve() for f in folders}:
        raise InputError(f"--out {args.out} is one of the --fleet boards: the fleet table would be written into a "
                         "board's own run; choose another --out")
    check_batch_out(Path(args.out), "health", [n for n, _ in tasks], ("fleet.csv", "fleet.html", "fleet.json"),
                    "health.json", bool(getattr(args, "force", False)))
    reach_scheduler(scheduler)
    out = out_dir(args.out)
    with locked_out(out, "health"):
        args.command = "health"
        if skipped:
            print(f"shm health --fleet: note: skipped {counted(len(skipped), 'match', 'matches')} of a pattern "
                  f"without a run (no usage.db in it): {_names(skipped)}", file=sys.stderr, flush=True)
        print(f"shm health: fleet of {counted(len(tasks), 'board')} on {scheduler or 'local'}", file=sys.stderr,
              flush=True)
        outcome = run_tasks(tasks, run_command_task, args, scheduler=scheduler,
                            warm=functools.partial(warm_workbench, "health"),
                            progress=_progress("shm health --fleet"), longest_first=True)
        task_files = write_task_folders(out, {r.key: r.files for r in outcome.results},
                                        earlier_task_files(out, "fleet.json"), "shm health --fleet")
        report_of = _report_of(outcome.results)
        rows = rank_fleet([fleet_row(r.key, r.doc, r.code, r.message) for r in outcome.results])
        paths = write_summary(out, f"Fleet: {counted(len(rows), 'board')} ranked by forecast first FAULT", rows,
                              report_of, stem="fleet", key="board")
        doc = {"fleet": rows, "files": {k: str(v) for k, v in paths.items()}, "cost": outcome.cost()}
        (out / "fleet.json").write_text(dump_json({**doc, TASK_FILES: task_files}), encoding="utf-8")
    say = (lambda s: print(s, file=sys.stderr)) if args.json else print
    for r in rows:
        fault = "-" if r["first_fault_h"] is None else (
            f"{r['first_fault_h']:.0f} h (90 %: {r['first_fault_90_lo_h']:.0f}-{r['first_fault_90_hi_h']:.0f} h), "
            f"RUL {r['rul_h']:.0f} h")
        say(f"{r['rank']:3d}  {r['board']}: first FAULT {fault}; where: {r['where'] or '-'}; last verdict "
            f"{r['last_verdict'] or '-'}" + (f"; exit {r['exit_code']}: {r['message']}" if r["exit_code"] else ""))
    say(f"fleet table {paths['csv']}, page {paths['html']} ({outcome.wall_s:.1f} s, {outcome.scheduler})")
    if args.json:
        print(dump_json(doc))
    return 1 if any(r["exit_code"] for r in rows) else 0


def run_fleet_boards(args: argparse.Namespace) -> int:
    """``shm run --scenario S --boards N --seed S``: N lives in parallel, each board's rates scaled by its factor."""
    from board_config.scenario import load_scenario
    from studies.batch import run_tasks
    from studies.batch.fleet import board_rate_factor, scaled_life
    from studies.batch.runner import check_scheduler, counted, reach_scheduler
    from studies.batch.summary import scalar_columns, write_summary

    if args.boards < 1:
        raise InputError(f"--boards must be >= 1, got {args.boards}")
    scheduler = check_scheduler(args.scheduler)
    scenario = load_scenario(args.scenario)
    if scenario.life is None:
        raise InputError(f"--boards needs a scenario with a [life] section ({scenario.source} has none)")
    _check_fleet_life(args, scenario)
    reach_scheduler(scheduler)  # an unknown host or a closed port: one line, before --out is made
    seed = args.seed if args.seed is not None else scenario.seed
    text = Path(scenario.source).read_text(encoding="utf-8")
    factors = [board_rate_factor(seed, i) for i in range(args.boards)]
    tasks = [(f"board{i:03d}", {"scenario.toml": scaled_life(text, f).encode()}) for i, f in enumerate(factors)]
    out = out_dir(args.out)
    args.command = "run"
    args.quiet = True
    with locked_out(out, "run"):
        earlier, listed = _earlier_fleet(out, bool(args.force))
        outcome = run_tasks(tasks, _board_life_task, (args, seed), scheduler=scheduler, warm=warm_workbench,
                            progress=_progress("shm run --boards"))
        # --force: the earlier fleet's own files replaced, once the new fleet is in; the user's stay
        task_files = _replace_boards(out, {r.key: r.files for r in outcome.results}, earlier, listed)
        report_of = _report_of(outcome.results)
        rows = [{"board": r.key, "exit_code": r.code, "rate_factor": factors[i], "seed": seed + i,
                 **scalar_columns(r.doc, skip=("wall_s",)), "first_fault_visit": r.doc.get("first_fault_visit"),
                 "message": "" if r.code == 0 else r.message} for i, r in enumerate(outcome.results)]
        paths = write_summary(out, f"{counted(len(rows), 'board')} through '{scenario.name}'", rows, report_of,
                              stem="boards", key="board")
        _write_manifest(out, {"boards": rows, "files": {k: str(v) for k, v in paths.items()},
                              "cost": outcome.cost()}, task_files)
    print(f"shm run: {counted(len(rows), 'board')} in {outcome.wall_s:.1f} s ({outcome.scheduler}); {paths['html']}; "
          "next: "
          f"shm health --fleet {out}/{BOARD_GLOB} --out {out}/fleet", file=sys.stderr)
    if args.json:
        print(dump_json({"boards": rows, "cost": outcome.cost()}))
    return 1 if any(r["exit_code"] for r in rows) else 0


def _earlier_fleet(out: Path, force: bool) -> tuple[dict[str, list[str]], bool]:
    """The files an earlier ``shm run --boards`` in ``out`` wrote into each board's folder (board -> paths in it),
    which ``--force`` replaces: left there (a longer life's later visits, a larger fleet's last boards) they would
    mix into the new fleet and its ``shm health --fleet``. And whether the fleet listed them (its boards.json's
    task_files) — a fleet written before the list was kept: the files a board's life is known to write
    (:func:`_known_board_files`). Anything else in a board's folder is the user's and stays. Without ``force`` an
    earlier fleet, or a boards table no fleet wrote, is refused; a board-named folder that no fleet listed and that
    holds no run (usage.db or life.json) is refused even with ``force``."""
    listed = earlier_task_files(out, BOARDS_TABLES[-1])
    boards = sorted(p for p in out.glob("board[0-9][0-9][0-9]"))
    stray = [p for p in boards if not p.is_dir() or p.is_symlink() or (
        p.name not in listed and not (p / "usage.db").is_file() and not (p / "life.json").is_file())]
    if stray:
        why = ("a symbolic link" if stray[0].is_symlink() else "a file" if not stray[0].is_dir()
               else "no usage.db or life.json in it")
        raise InputError(f"--out {out}: {stray[0]} is not a board of an earlier fleet ({why}): not writing over it, "
                         "--force or not; choose another --out")
    if not force and boards:
        raise InputError(f"--out {out} holds an earlier fleet (board### folders): not overwriting it; use "
                         "--force to replace it, or choose another --out")
    table = next((out / n for n in BOARDS_TABLES if (out / n).exists()), None)
    if not force and table is not None:
        raise InputError(f"--out {out}: {table.name} is there and no earlier fleet's boards are beside it: not "
                         "overwriting it; choose another --out, or --force to replace it")
    return {p.name: listed[p.name] if p.name in listed else _known_board_files(p) for p in boards}, bool(listed)


def _known_board_files(folder: Path) -> list[str]:
    """The files in ``folder`` that a board's life writes (:data:`RUN_OUTPUTS`, :data:`BOARD_LOG`,
    :data:`VISIT_RECORD`): an earlier fleet's own, when it kept no list of them."""
    top = [n for n in (*RUN_OUTPUTS, BOARD_LOG) if (folder / n).is_file()]
    records = [str(p.relative_to(folder)) for p in folder.glob(VISIT_RECORD) if p.is_file()]
    return sorted(top + records)


def _write_manifest(out: Path, doc: dict[str, Any], task_files: dict[str, list[str]]) -> None:
    """boards.json: the fleet's document and the files each board's folder got from it (``task_files``)."""
    (out / BOARDS_TABLES[-1]).write_text(dump_json({"command": "run", **doc, TASK_FILES: task_files}),
                                         encoding="utf-8")


def _replace_boards(out: Path, written: dict[str, dict[str, bytes]], earlier: dict[str, list[str]],
                    listed: bool) -> dict[str, list[str]]:
    """Each board's files into ``out/<board>/`` (:func:`write_task_folders`), and the earlier fleet's files
    (``earlier``) that this one does not write removed — all of them in a board this fleet has not (a larger
    fleet's last boards), and that board's folder when nothing is left in it. The user's files stay, said in one
    line. Returns the new task_files (a board kept for the user's files: an empty list, so it is the fleet's). The
    manifest first lists both fleets' files: a run stopped half-way leaves none of them looking like the user's."""
    from studies.batch.runner import counted

    gone: dict[str, dict[str, bytes]] = {key: {} for key in earlier if key not in written}
    both = {k: sorted({*earlier.get(k, ()), *written.get(k, {})}) for k in sorted({*earlier, *written})}
    _write_manifest(out, {"status": "writing"}, both)
    with contextlib.redirect_stderr(io.StringIO()):  # its note for each folder holding the user's files: one below
        task_files = write_task_folders(out, {**written, **gone}, earlier, "shm run --boards")
    kept: dict[Path, list[str]] = {}
    for key in list(task_files):
        folder = out / key
        if key in gone and folder.is_dir() and not any(folder.iterdir()):
            folder.rmdir()
        if not folder.is_dir():
            del task_files[key]
        elif mine := [f for f in files_in(folder) if f not in task_files[key]]:
            kept[folder] = mine
    if kept:
        where = [f"{folder} ({', '.join(files[:2])}{', ...' if len(files) > 2 else ''}"
                 + ("; no run in it now: shm health --fleet skips it)" if folder.name in gone else ")")
                 for folder, files in kept.items()]
        print(f"shm run --boards: --force kept {counted(sum(len(f) for f in kept.values()), 'file')} that no fleet "
              f"wrote{'' if listed else ' (the earlier fleet kept no list: a board run writes none of them)'}, as "
              f"they were: {', '.join(where[:3])}" + (f" and {counted(len(where) - 3, 'folder')} more"
                                                      if len(where) > 3 else ""), file=sys.stderr)
    return task_files


def _check_fleet_life(args: argparse.Namespace, scenario: Any) -> None:
    """What a single life refuses in its parent, refused once for the whole fleet before any task (exit 2):
    options that mean nothing for a life (``--live`` included), a bad seed, and the life's own checks."""
    from shm_cli.life_cmd import refuse_life_options
    from studies.health.life_check import check_life

    if getattr(args, "live", None) is not None:
        raise InputError("--live follows one board run; a fleet (--boards) runs many lives in parallel tasks")
    refuse_life_options(args)
    seed = args.seed if args.seed is not None else scenario.seed
    if not 0 <= seed <= 2**32 - 1 - args.boards:
        raise InputError(f"--seed must be in [0, 2^32-1-N] for --boards N={args.boards}, got {seed}")
    params = args.params or scenario.rig.params
    check_life(scenario, params, "--params" if args.params else None)


def _board_life_task(key: str, files: dict[str, bytes], shared: dict[str, bytes], options: Any) -> Any:
    """One board's life: the single-board ``shm run`` on its scaled scenario, its rig seeded seed + board index."""
    args, seed = options
    board_args = argparse.Namespace(**vars(args))
    board_args.seed = seed + int(key.removeprefix("board"))
    return run_command_task(key, files, shared, board_args)
