"""``shm health``: from the board's visit records to severity, location and remaining life (issue 17).

    shm health SOURCE... --params P [--as-of HOURS] [--free NAME ...] [--follow auto|never] [--locate auto|always|never]
               [--locate-diagnose] [--workers N] [--json] --out DIR

A SOURCE is a run directory of ``shm run`` (its ``records/`` and ``usage.db``), its ``usage.db``, or record files
carrying ``operating_hours`` (the life runner behind ``shm run --scenario aging`` is :mod:`shm_cli.life_cmd`).
Exit 0 when the assessment was made, 2 for bad input, 1 when the job failed.
"""

from __future__ import annotations

import argparse
import contextlib
import errno
import os
import shutil
import sys
import time
from pathlib import Path
from typing import Any

from shm_cli.command_args import add_command
from shm_cli.common import add_out_arg, out_dir, seed_int


def register(sub: argparse._SubParsersAction) -> None:
    p = add_command(
        sub, "health", "health over time: per-visit re-estimation, trends, forecast of the board's first FAULT",
        """Re-estimate the health parameters at every maintenance visit from the board's records, trend them against
        operating time, and forecast when the board's own monitor will first say FAULT (trip time with a 90 %
        interval, remaining useful life). Prints the four levels (detected? where? how much? how long?); plots and
        report.html go to --out. docs/health.md.""")
    p.add_argument("sources", nargs="+", metavar="SOURCE",
                   help="a run directory of 'shm run', its usage.db, or record files (CSV/TDMS) with operating_hours")
    p.add_argument("--params", default="table2", metavar="NAME|FILE",
                   help="the nominal parameter set (the board's; default table2)")
    p.add_argument("--as-of", type=float, default=None, metavar="HOURS",
                   help="use only the visits up to this operating time (h): a forecast to check against what came "
                        "after")
    p.add_argument("--free", action="append", default=None, metavar="NAME",
                   help="health parameters to re-estimate (repeatable; default: k3, alpha_h, beta_h — those the "
                        "monitor watches)")
    p.add_argument("--workers", type=int, default=None, help="fit processes (default: CPU count)")
    p.add_argument("--dask-scheduler", default=None, metavar="ADDRESS",
                   help="fit the visits on this Dask cluster (as shm campaign; extra mfc-shm[cluster]; the workers "
                        "must see the record files)")
    p.add_argument("--locate", choices=("auto", "always", "never"), default="auto",
                   help="where? place a stiffness loss in its section by freeing k1, k2, k3 one at a time on the "
                        "latest visit and scoring them on held-out data (auto: when a stiffness changed or trends, "
                        "or the health fit leaves excess residual; default auto)")
    p.add_argument("--follow", choices=("auto", "never"), default="auto",
                   help="what changes? when a visit's default fit leaves more than the noise or runs to a bound, "
                        "ask shm diagnose on the latest such visit which parameters or effects changed and "
                        "re-estimate and trend those on every visit (auto, default) or never")
    p.add_argument("--locate-diagnose", action="store_true",
                   help="also run shm diagnose on the latest visit and add what it names first to the candidates "
                        "(slower)")
    p.add_argument("--locate-visits", type=int, default=1, metavar="N",
                   help="place the stiffness loss on the last N visits, not only the latest (location.history; "
                        "about 6 s of CPU per visit; default 1)")
    p.add_argument("--evaluate", action="store_true",
                   help="score the prognosis on a life whose truth is known (the board's verdicts in a run's "
                        "usage.db, or true parameters in synthetic records): the forecast rebuilt as of every visit "
                        "before the true first FAULT, alpha-lambda accuracy, prognostic horizon, relative accuracy "
                        "(ProgPy / Saxena et al.) and a remaining-life-vs-time plot with its alpha-lambda cone")
    p.add_argument("--alpha", type=float, default=0.2,
                   help="--evaluate: the alpha of alpha-lambda and the prognostic horizon (share of the true "
                        "remaining life; default 0.2)")
    p.add_argument("--lambda", dest="lambdas", type=float, action="append", default=None, metavar="LAMBDA",
                   help="--evaluate: a lambda point in [0, 1) (repeatable; default 0.25, 0.5, 0.75)")
    p.add_argument("--seed", type=seed_int, default=1, help="seed of the forecast's Monte Carlo (default 1)")
    p.add_argument("--json", action="store_true", help="print one JSON document (also written to DIR/health.json)")
    p.add_argument("--force", action="store_true",
                   help="write into an --out holding another command's results (its report.html is replaced)")
    from shm_cli.fleet_cmd import add_fleet_args

    add_fleet_args(p, boards=False)
    add_out_arg(p, default="out/health")
    p.set_defaults(func=cmd_health)


def cmd_health(args: argparse.Namespace) -> int:
    if args.fleet:  # each SOURCE a board: one task per board (docs/scale-out.md)
        from shm_cli.fleet_cmd import run_fleet_health

        return run_fleet_health(args)
    from shm_cli.main import CliError

    if args.scheduler is not None:  # it would be ignored: the fits of one board go to --dask-scheduler
        raise CliError("--scheduler runs one task per board with --fleet; one board's assessment runs here (its fits "
                       "on a cluster: --dask-scheduler ADDRESS)")
    if args.as_of is not None and not args.as_of >= 0:
        raise CliError(f"--as-of must be a number of hours >= 0, got {args.as_of!r}")
    if args.seed < 0:
        raise CliError(f"--seed must be >= 0, got {args.seed}")
    if args.locate_visits < 1:
        raise CliError(f"--locate-visits must be >= 1, got {args.locate_visits}")
    if args.workers is not None and args.workers < 1:
        raise CliError(f"--workers must be >= 1, got {args.workers}")
    if not 0 < args.alpha < 1:
        raise CliError(f"--alpha must be in (0, 1), got {args.alpha}")
    bad = [x for x in (args.lambdas or []) if not 0 <= x < 1]
    if bad:
        raise CliError(f"--lambda must be in [0, 1), got {bad[0]}")
    _check_params(args.params)
    from studies.health.sources import check_sources

    check_sources(args.sources)  # records that belong together, before any fit (issue 33)
    out = out_dir(args.out)
    from shm_cli.run_lock import OutputLock

    lock = OutputLock(out, command=f"shm health --out {args.out}")
    lock.acquire()
    try:
        _check_out_is_health(out, args.force)
        return _health_locked(args, out)
    finally:
        lock.release()


#: what shm health writes into --out
HEALTH_OUTPUTS = ("health.json", "levels.txt", "health.png", "forecast.png", "remaining_life.png", "report.html")
STAGE_NAME = ".shm-health-new"


def _check_params(params: str) -> None:
    """--params loads (a name or a file) before any visit is read or fitted: one line naming it (exit 2)."""
    from board_config.errors import InputError
    from board_config.parameter_sets import load_parameter_set
    from shm_cli.main import CliError

    if not str(params).strip():
        raise CliError("--params is empty: give a parameter set's name or a path")
    try:
        load_parameter_set(params)
    except InputError as exc:
        text = " ".join(str(exc).split())
        raise CliError(text if text.startswith("--params") else f"--params {params}: {text}") from None


def _check_out_is_health(out: Path, force: bool) -> None:
    """A folder holding another command's results (a run's usage.db, a compare's report.html ...) is refused
    without --force; an earlier shm health's outputs (health.json beside them) are replaced."""
    from shm_cli.main import CliError

    if (out / "health.json").exists() or force:
        return
    foreign = [n for n in ("report.html", "summary.json", "usage.db", "life.json", "records", "levels.txt")
               if (out / n).exists()]
    if foreign:
        raise CliError(f"--out {out} holds another command's results ({', '.join(foreign)}; no health.json), not an "
                       "earlier shm health: not overwriting them; choose another --out, or --force to write the "
                       "health outputs there anyway")


def _health_locked(args: argparse.Namespace, out: Path) -> int:
    """The assessment, its outputs written into ``out`` (locked), the four levels printed; the exit code."""
    from studies.health.assess import assess_health
    from studies.health.evaluate import LAMBDAS
    from studies.health.report import evaluation_text, four_levels_text, health_json, write_health_outputs

    log = (lambda s: print(s, file=sys.stderr, flush=True)) if args.json else (lambda s: print(s, flush=True))
    t0 = time.perf_counter()
    result = assess_health(args.sources, params=args.params, as_of=args.as_of, free=args.free or None,
                           workers=args.workers, seed=args.seed, progress=log, dask_scheduler=args.dask_scheduler,
                           locate=args.locate, locate_diagnose=args.locate_diagnose,
                           locate_visits=args.locate_visits, evaluate=args.evaluate, alpha=args.alpha,
                           lambdas=tuple(args.lambdas) if args.lambdas else LAMBDAS, follow=args.follow)
    result.doc["wall_s"] = time.perf_counter() - t0
    text = four_levels_text(result)
    if result.doc.get("evaluation"):
        text += "\n" + evaluation_text(result.doc["evaluation"])
    failed = write_staged(out, lambda d: write_health_outputs(result, d, text))
    for artefact, why in failed.items():
        print(f"shm health: could not write {artefact} into {out}/ ({why}); not replaced", file=sys.stderr)
    if args.json:
        print(health_json(result))
        print(text, file=sys.stderr)
    else:
        print(text)
        written = [n for n in ("health.json", "report.html") if n not in failed]
        print(f"results in {out}/ ({', '.join([*written, 'figures'])})")
    return 1 if failed else 0


def write_staged(out: Path, write: Any) -> dict[str, str]:
    """Every output written into ``out/.shm-health-new/`` first, then each complete file moved into ``out``
    (``os.replace``): a full disk never leaves a cut-off report.html. A failure to write health.json or levels.txt
    is one line naming the path and the disk (OSError, exit 1); a failed figure or page is reported and skipped."""
    stage = out / STAGE_NAME
    shutil.rmtree(stage, ignore_errors=True)
    try:
        stage.mkdir()
        try:
            failed: dict[str, str] = write(stage)
        except OSError as exc:
            raise OSError(_disk_text(out, exc)) from None
        for name in failed:
            (stage / name).unlink(missing_ok=True)
        for name in HEALTH_OUTPUTS:
            if (stage / name).exists():
                os.replace(stage / name, out / name)
        return {k: (_disk_text(out, v, whole=False) if "No space" in v or "disk" in v else v)
                for k, v in failed.items()}
    finally:
        shutil.rmtree(stage, ignore_errors=True)


def _disk_text(out: Path, exc: object, whole: bool = True) -> str:
    why = " ".join(str(exc).split())
    free = ""
    with contextlib.suppress(OSError):
        free = f"; the file system holding {out} has {shutil.disk_usage(out).free / 1e6:.1f} MB free"
    full = "No space left" in why or getattr(exc, "errno", None) == errno.ENOSPC
    if not whole:  # one artefact: the caller names it and the folder
        return why + (" (the disk is full)" if full else "") + free
    return (f"could not write the health outputs into {out}/: {why}" + (" (the disk is full)" if full else "")
            + free + "; nothing half-written was left there")
