"""``shm run`` on a scenario with ``[life]``: every visit a Dask task (local worker processes, or ``--scheduler
tcp://HOST:PORT``), one usage.db, the visit records.

What the user gets wrong is refused before any worker starts (:func:`studies.health.life_check.check_life`, and the
options that mean nothing for a life: ``--duration-s``, ``--realtime``, ``--append``, a hardware ``--link``); an
error inside a visit reaches the user as the same one line (:mod:`studies.board_run.life_pool`).

The new life is built in ``DIR/.shm-life-new/`` and moved into ``DIR`` at the end, so an earlier life replaced with
``--force`` stays whole until the new one has at least one finished visit to replace it with. SIGTERM or Ctrl-C
stop the life cleanly: no new visit starts, the workers are terminated and joined, the visits finished so far are
written (usage.db with status ``interrupted``, their records, life.json, summary.json ``status: interrupted``,
timeline, report) and the exit code is 143 (SIGTERM) or 130 (Ctrl-C). Stopped before any visit finished, nothing
is written and an earlier life in ``DIR`` is left as it was. A second signal stops at once (the workers are still
terminated).
"""

from __future__ import annotations

import argparse
import contextlib
import os
import shutil
import sqlite3
import sys
from pathlib import Path
from typing import Any

from shm_cli.common import dump_json, out_dir
from shm_cli.stop_signal import StopOnSignal

STAGE_NAME = ".shm-life-new"


def refuse_life_options(args: argparse.Namespace) -> None:
    """Options of ``shm run`` that mean nothing for a life: one line naming the option (exit 2)."""
    from shm_cli.main import CliError

    if args.link != "sim":
        raise CliError(f"--link {args.link}: a [life] scenario runs on the simulated rig only (--link sim): each "
                       "visit is a fresh rig with that visit's degradation")
    if getattr(args, "append", False):
        raise CliError("--append does not apply to a [life] scenario (a life is one run in its own usage.db; "
                       "--force replaces an earlier one)")
    if args.duration_s is not None:
        raise CliError(f"--duration-s {args.duration_s:g} does not apply to a [life] scenario: every visit plays "
                       "the scenario's phases in full (change the phases, or [life] visits)")
    if getattr(args, "realtime", False):
        raise CliError("--realtime does not apply to a [life] scenario: its visits run in virtual time on worker "
                       "processes (a paced board needs a single run: a scenario without [life])")


def run_life_command(args: argparse.Namespace, scenario: Any) -> int:
    from board_config.board import load_board_config
    from shm_cli.main import CliError
    from shm_cli.output_folder import previous_run
    from shm_cli.run_lock import OutputLock
    from studies.health.life_check import check_life

    refuse_life_options(args)
    from studies.batch.runner import check_scheduler

    args.scheduler = check_scheduler(getattr(args, "scheduler", None))  # where the visits run (docs/scale-out.md)
    seed = args.seed if args.seed is not None else scenario.seed
    if not 0 <= seed < 2**32:
        raise CliError(f"--seed must be in [0, 2^32-1], got {seed}")
    params = args.params or scenario.rig.params
    cfg = load_board_config(args.board_config, overrides=scenario.board_overrides, overrides_source=scenario.source)
    check_life(scenario, params, "--params" if args.params else None)
    out = out_dir(args.out)
    lock = OutputLock(out, command=f"shm run --scenario {args.scenario} --out {args.out}")
    lock.acquire()
    try:
        previous = previous_run(out)
        if previous is not None and not args.force:
            raise CliError(f"--out {out} holds an earlier run ({previous}); not overwriting it: use --force to "
                           "replace it (kept until the new life has a finished visit), or choose another --out")
        stage = out / STAGE_NAME
        shutil.rmtree(stage, ignore_errors=True)  # a killed earlier attempt's leftovers (we hold the lock)
        stage.mkdir()
        try:
            with StopOnSignal() as stopper:
                return _run_life_staged(args, scenario, seed, params, cfg, out, stage, stopper)
        finally:
            shutil.rmtree(stage, ignore_errors=True)
    finally:
        lock.release()


def _run_life_staged(args: argparse.Namespace, scenario: Any, seed: int, params: str, cfg: Any, out: Path,
                     stage: Path, stopper: StopOnSignal) -> int:
    from studies.batch.runner import counted
    from studies.health.life import run_life, visit_line

    lines: list[str] = []
    to = sys.stderr if args.json else sys.stdout
    life = scenario.life

    def say(s: str) -> None:
        lines.append(s)
        if not args.quiet:
            print(s, file=to, flush=True)

    say(f"shm run: life scenario '{scenario.name}' ({scenario.source}), seed {seed}, params {params}: "
        f"{life.visits} visits every {life.visit_interval:g} h ({life.flights_between_visits} flights between "
        + (f"visits, {life.tick_flights} of them ticked before each visit from the 2nd ({life.flight_scenario}'s "
           "flight phases), the rest summarised)" if life.tick_flights else "visits, summarised)"))
    try:
        # life_workers: 1 for a board of shm run --boards (a Dask task: the worker is the parallelism)
        result = run_life(scenario, seed=seed, params=params, board_config=args.board_config,
                          workers=getattr(args, "life_workers", None), scheduler=args.scheduler,
                          on_visit=lambda v: say(visit_line(v)), should_stop=lambda: stopper.requested)
    except KeyboardInterrupt:  # a second signal: stop at once (the pool has terminated its workers)
        print(f"shm run: stopped at once by a second signal; nothing of this life written, {out}/ as it was",
              file=sys.stderr)
        return stopper.exit_code
    if result.interrupted and not result.visits:
        print(f"shm run: interrupted by {stopper.name} before any visit finished; nothing written, {out}/ left as "
              "it was", file=sys.stderr)
        return stopper.exit_code
    status = "interrupted" if result.interrupted else "finished"
    if result.interrupted:
        say(f"interrupted by {stopper.name}: {len(result.visits)} of {result.planned} visits finished and kept")
    try:
        summary, failed = _write_life(args, scenario, seed, params, cfg, out, stage, result, status, lines, say)
    except (OSError, sqlite3.DatabaseError, RuntimeError) as exc:
        raise _write_error(exc, out) from None
    for artefact, why in failed.items():
        print(f"shm run: could not write {artefact} ({why})", file=sys.stderr)
    if args.json:
        print(dump_json(summary))
    elif not args.quiet:
        print(f"results in {out}/ (usage.db, records/, life.json, timeline.txt, report.html, life.png)")
    if stopper.requested:
        return stopper.report(result.interrupted, f"; status 'interrupted' recorded in {out / 'usage.db'}, "
                              f"{counted(len(result.visits), 'finished visit')} in {out}/", "the life", f"{out}/")
    return 1 if failed else 0


def _write_life(args: argparse.Namespace, scenario: Any, seed: int, params: str, cfg: Any, out: Path, stage: Path,
                result: Any, status: str, lines: list[str], say: Any) -> tuple[dict[str, Any], dict[str, str]]:
    """Every file of the life into ``stage``, then moved into ``out`` (an earlier run's files replaced)."""
    from shm_cli.output_folder import remove_run_outputs
    from studies.batch.runner import counted
    from studies.health.life import write_life_log
    from studies.health.life_report import write_life_report

    summary = write_life_log(result, scenario, stage, seed=seed, params=params, board_config=cfg.as_dict(),
                             status=status, final_dir=out)
    first = summary["first_fault_visit"]
    say(f"end: {counted(len(result.visits), 'visit')} in {result.wall_s:.1f} s wall "
        f"({counted(result.workers, 'worker')}); first FAULT "
        + (f"at visit {first} ({summary['first_fault_operating_hours']:g} h)" if first else "never"))
    (stage / "timeline.txt").write_text("\n".join(lines) + "\n")
    (stage / "summary.json").write_text(dump_json(summary))
    failed = write_life_report(summary, stage, str(args.out))
    for name in failed:  # a half-written artefact is not moved into --out
        (stage / name).unlink(missing_ok=True)
    remove_run_outputs(out)  # the earlier run's files go only now, when the new ones are complete
    for entry in sorted(stage.iterdir()):
        os.replace(entry, out / entry.name)
    return summary, failed


def _write_error(exc: BaseException, out: Path) -> OSError:
    """A failed write of the life's results as one line naming the path and the disk (exit 1)."""
    free = ""
    with contextlib.suppress(OSError):
        free = f"; the file system holding {out} has {shutil.disk_usage(out).free / 1e6:.1f} MB free"
    why = " ".join(str(exc).split())
    full = "disk is full" in why or "No space left" in why or getattr(exc, "errno", None) == 28
    hint = " (the disk is full: free some space or choose another --out)" if full else ""
    return OSError(f"could not write the life's results into {out}/: {why}{hint}{free}; nothing of this life "
                   f"was moved into {out}/ (an earlier run there is kept)")
