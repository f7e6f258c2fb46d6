"""``shm campaign`` — the Monte-Carlo MBIT campaign of the seed paper's Fig. 11 — and ``shm campaign-roc``, the
threshold sweep over a finished campaign's stored error traces.

``shm campaign --mbit both --ranges 0:50:10 --n 100 --seed 1 --params table2 --out out/campaign`` writes (in --out):
``fig11.png/.svg`` (detected faults and probability per range, 95 % Wilson bars, paper values in red),
``fig11_table.csv/.md``, ``paper_comparison.csv``, ``runs.csv`` (one row per unit), ``traces.npz`` (error traces),
``error_traces.png``, ``roc.png``/``roc.csv`` (default grids), ``campaign.json`` and the resumable store
(``manifest.json``, ``batches/``). Rerunning the same command into the same --out reuses finished batches.

The numbers (tables, runs, traces, ROC table, ``campaign.json``) are written before the figures; ``campaign.json``
exists only for a finished campaign and says which figures were written (``"figures": "written"`` or the ones that
failed). Exit codes: 0 done; 1 some batches did not finish (worker crash; finished ones are kept — rerun to
resume), some degraded units failed to integrate, or a figure could not be drawn (named; the numbers are written);
2 bad input (ranges, --n, MBIT, parameter set, unreachable scheduler ...).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from board_config.errors import InputError
from board_config.json_values import to_jsonable
from shm_cli.command_args import add_command
from shm_cli.common import (
    Decorations,
    add_out_arg,
    add_params_arg,
    check_memory,
    dump_json,
    out_dir,
    positive_float,
    seed_int,
)

if TYPE_CHECKING:
    from studies.campaign.results import CampaignResult
    from studies.campaign.roc import RocTable
    from studies.campaign.runner import CampaignOutcome
    from studies.campaign.spec import CampaignSpec

DEFAULT_EPS_GRID = "0.025:0.6:0.025"
DEFAULT_COUNT_GRID = "25,50,100,200,300,400"


def register(sub: argparse._SubParsersAction) -> None:
    p = add_command(
        sub, "campaign", "Monte-Carlo MBIT campaign: fault detection probability per deviation range (Fig. 11)",
        """Simulate degraded laminates (uniform random deviations of k3, alpha_h, beta_h within each range) through
        MBIT.a / MBIT.b, run the condition monitor (Eq. 11, Table 3) and report detected faults and fault
        probability per range with 95 % Wilson intervals.""")
    p.add_argument("--mbit", default="both", metavar="a|b|both",
                   help="which built-in test(s): a, b, both (default), all, or a comma list of keys in the MBIT file")
    p.add_argument("--ranges", default="0:50:10", metavar="SPEC",
                   help="deviation ranges in percent: START:STOP:STEP (default 0:50:10 = 0-10,...,40-50), LO:HI, "
                        "or LO-HI,LO-HI")
    p.add_argument("--n", type=int, default=100, help="runs (degraded units) per range (default 100)")
    p.add_argument("--seed", type=seed_int, default=1, help="random seed (default 1); results are bit-for-bit "
                   "reproducible for a seed whatever the workers")
    add_params_arg(p)
    ex = p.add_mutually_exclusive_group()
    ex.add_argument("--workers", type=int, default=None,
                    help="local worker processes (default: CPU count; 1 = in this process)")
    ex.add_argument("--dask-scheduler", default=None, metavar="ADDRESS",
                    help="run the same tasks on a Dask cluster (e.g. tcp://10.0.0.5:8786)")
    p.add_argument("--dask-timeout-s", type=positive_float, default=10.0, help="time to wait for the scheduler (s)")
    p.add_argument("--sign", choices=("both", "minus", "plus"), default="both",
                   help="sign of the deviations: both (default, +/- with equal probability per parameter), "
                        "minus (parameters only decrease), plus")
    p.add_argument("--deviate", default="k3,alpha_h,beta_h", metavar="NAMES",
                   help="comma list of deviated model parameters (default: the paper's k3,alpha_h,beta_h)")
    p.add_argument("--noise-um", type=float, default=0.0,
                   help="white measurement noise on the hardware's z3, standard deviation in micrometres "
                        "(default 0, as in the paper)")
    p.add_argument("--batch-size", type=int, default=25, help="runs per task (default 25)")
    p.add_argument("--mbit-config", default=None, metavar="FILE", help="MBIT definitions (default: shipped mbit.toml)")
    p.add_argument("--monitor-config", default=None, metavar="FILE",
                   help="monitor settings TOML (default: shipped monitor.toml, Table 3)")
    p.add_argument("--fresh", action="store_true",
                   help="discard batches stored in --out by a different or earlier campaign instead of resuming")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--no-figures", action="store_true",
                   help="skip the figures (tables, traces, ROC table and JSON are still written)")
    p.add_argument("--json", action="store_true", help="print the summary as JSON on stdout")
    add_out_arg(p)
    p.set_defaults(func=cmd_campaign)

    r = add_command(
        sub, "campaign-roc", "ROC view: sweep eps_th and count_max over a campaign's stored error traces",
        """Detection probability (units beyond --faulty-min-pct) against false-alarm probability (units within
        --healthy-max-pct) for a grid of thresholds, without re-simulating.""")
    r.add_argument("--from", dest="source", required=True, metavar="DIR",
                   help="a finished campaign's output directory (or its traces.npz)")
    r.add_argument("--eps-th", default=DEFAULT_EPS_GRID, metavar="GRID",
                   help=f"thresholds: START:STOP:STEP (inclusive) or a comma list (default {DEFAULT_EPS_GRID})")
    r.add_argument("--count-max", default=DEFAULT_COUNT_GRID, metavar="LIST",
                   help=f"counter limits, comma list (default {DEFAULT_COUNT_GRID})")
    r.add_argument("--healthy-max-pct", type=float, default=10.0,
                   help="units whose range ends at or below this are acceptable: a fault is a false alarm")
    r.add_argument("--faulty-min-pct", type=float, default=10.0,
                   help="units whose range starts at or above this are degraded: a fault is a detection")
    r.add_argument("--json", action="store_true", help="print the ROC table as JSON on stdout")
    r.add_argument("--out", default=None, metavar="DIR",
                   help="where roc.png/roc.csv go (default: the --from directory)")
    r.set_defaults(func=cmd_roc)


def parse_grid(text: str, what: str, integer: bool = False) -> np.ndarray:
    """``START:STOP:STEP`` (STOP included) or a comma list; clear errors naming the option."""
    try:
        if ":" in text:
            a, b, s = (float(v) for v in text.split(":"))
            if s <= 0 or b < a:
                raise InputError
            values = a + s * np.arange(int(np.floor((b - a) / s + 1e-9)) + 1)
        else:
            values = np.array([float(v) for v in text.split(",") if v.strip()])
    except ValueError:
        raise InputError(f"{what} {text!r}: expected START:STOP:STEP with STEP > 0 and STOP >= START, "
                         "or a comma list of numbers") from None
    if values.size == 0 or not np.all(np.isfinite(values)):
        raise InputError(f"{what} {text!r}: no valid values")
    if integer:
        if np.any(values != np.round(values)) or np.any(values < 1):
            raise InputError(f"{what} {text!r}: expected integers >= 1")
        return np.unique(values.astype(np.int64))
    if np.any(values <= 0):
        raise InputError(f"{what} {text!r}: thresholds must be positive")
    return np.unique(np.round(values, 12))


def _roc_tables(traces, eps_grid, count_grid, healthy_max, faulty_min):
    from studies.campaign import roc_sweep

    return [roc_sweep(traces.eps[k], traces.range_lo, traces.range_hi, traces.status[k] == 0, eps_grid, count_grid,
                      traces.monitor, mbit=k, label=traces.labels[k], healthy_max=healthy_max,
                      faulty_min=faulty_min) for k in traces.eps]


def _write_roc(tables, directory: Path, mark, figure: bool = True) -> dict[str, Path]:
    from studies.campaign import figures as campaign_figures
    from studies.campaign.results import write_rows

    csv_path = directory / "roc.csv"
    write_rows(csv_path, [row for t in tables for row in t.rows()])
    if not figure:
        return {"roc_csv": csv_path}
    return {"roc_csv": csv_path, "roc_png": campaign_figures.roc(tables, directory / "roc", mark=mark)[0]}


def cmd_campaign(args: argparse.Namespace) -> int:
    from shm_cli.main import CliError
    from shm_cli.run_lock import OutputLock
    from studies.campaign import build_spec

    if args.n <= 0:
        raise CliError(f"--n must be a positive integer (runs per range), got {args.n}")
    if args.workers is not None and args.workers < 1:
        raise CliError(f"--workers must be >= 1, got {args.workers}")
    if args.batch_size < 1:
        raise CliError(f"--batch-size must be >= 1, got {args.batch_size}")
    if not np.isfinite(args.noise_um) or args.noise_um < 0:
        raise CliError(f"--noise-um must be >= 0, got {args.noise_um}")
    deviated = tuple(n.strip() for n in args.deviate.split(",") if n.strip())
    spec = build_spec(args.params, args.mbit, args.ranges, args.n, args.seed, deviated=deviated, sign=args.sign,
                      noise_std=args.noise_um * 1e-6, batch_size=args.batch_size, mbit_config=args.mbit_config,
                      monitor=args.monitor_config)
    runs = len(spec.ranges) * spec.n_runs
    per_run = sum(16.0 * m.n_samples + 256.0 for m in spec.mbits)  # z3 and eps traces, scalars (bytes)
    check_memory(f"--n {args.n} x {len(spec.ranges)} ranges = {runs:.3g} units", 2.0 * runs * per_run,
                 hint="use a smaller --n or fewer --ranges")
    out = out_dir(args.out)
    # one campaign per --out at a time: a second one would mix its batches into this store (issue 12)
    with OutputLock(out, command=f"shm campaign --out {args.out}"):
        return _campaign_in(args, spec, out)


def _campaign_in(args: argparse.Namespace, spec: CampaignSpec, out: Path) -> int:
    """The campaign proper, run while ``out`` is locked: the batches, then the numbers, then the figures."""
    # campaign.json marks a finished campaign: an earlier one must not survive a run that fails
    (out / "campaign.json").unlink(missing_ok=True)
    outcome = _run_batches(args, spec, out)
    if not outcome.complete:
        print(f"shm campaign: {outcome.failure_message()}", file=sys.stderr)
        if args.json:
            print(dump_json({"complete": False, "fingerprint": spec.fingerprint(), "batches": {
                "total": outcome.n_batches, "reused": outcome.n_reused, "computed": outcome.n_computed,
                "failed": [{"key": f.key, "message": f.message} for f in outcome.failures]}}))
        return 1
    result = outcome.result
    assert result is not None
    # results first (tables, runs, traces, ROC table, campaign.json), then the figures: a plotting failure must never
    # lose the numbers, and campaign.json says which figures exist
    summary, tables = _write_numbers(args, spec, outcome, out)
    deco = Decorations("campaign", args)
    if not args.no_figures:
        _draw_figures(result, tables, (spec.monitor.eps_th, spec.monitor.count_max), out, summary, deco)
    if args.json:
        print(dump_json(summary))
    else:
        print(result.markdown_table())
        print(f"\n{len(spec.ranges) * spec.n_runs} units x {len(spec.mbits)} MBITs in {outcome.wall_s:.1f} s "
              f"({outcome.executor}); files in {out}/")
    if result.n_failed:
        print(f"shm campaign: {result.n_failed} degraded-unit simulations failed to integrate (excluded from the "
              "probabilities; see status_* in runs.csv)", file=sys.stderr)
    return 1 if result.n_failed or not deco.ok else 0


def _run_batches(args: argparse.Namespace, spec: CampaignSpec, out: Path) -> CampaignOutcome:
    """Run (or resume) the campaign's batches into ``out`` with a progress bar; say what was noted and reused."""
    from tqdm import tqdm

    from studies.campaign import run_campaign

    total = len(spec.ranges) * spec.n_runs
    tqdm.monitor_interval = 0  # no tqdm monitor thread: lets the process pool fork (see campaign.runner)
    bar = tqdm(total=total, unit="run", desc=f"campaign {'+'.join(m.label for m in spec.mbits)}", file=sys.stderr,
               disable=True if args.no_progress else None, dynamic_ncols=True)
    try:
        outcome = run_campaign(spec, out, workers=args.workers, dask_scheduler=args.dask_scheduler,
                               dask_timeout_s=args.dask_timeout_s, fresh=args.fresh, progress=bar.update)
    finally:
        bar.close()
    for note in outcome.notes:
        print(f"shm campaign: note: {note}", file=sys.stderr)
    if outcome.n_reused:
        print(f"shm campaign: resumed: {outcome.n_reused} of {outcome.n_batches} batches reused from {out}/batches",
              file=sys.stderr)
    return outcome


def _write_numbers(args: argparse.Namespace, spec: CampaignSpec, outcome: CampaignOutcome,
                   out: Path) -> tuple[dict[str, Any], list[RocTable]]:
    """A finished campaign's numbers into ``out`` (tables, runs, traces, the ROC table at the default grids,
    campaign.json): the summary written and the ROC tables (for the figure)."""
    from studies.campaign import load_traces
    from studies.campaign.results import save_json

    result = outcome.result
    assert result is not None
    files = {k: str(v) for k, v in result.save(out).items()}
    tables = _roc_tables(load_traces(out), parse_grid(DEFAULT_EPS_GRID, "--eps-th"),
                         parse_grid(DEFAULT_COUNT_GRID, "--count-max", integer=True), 0.10, 0.10)
    mark = (spec.monitor.eps_th, spec.monitor.count_max)
    files.update({k: str(v) for k, v in _write_roc(tables, out, mark, figure=False).items()})
    summary = {
        "complete": True,
        "spec": spec.describe(),
        "fingerprint": spec.fingerprint(),
        "summary": [s.row() for s in result.summary()],
        "paper_comparison": result.paper_comparison(),
        "integration_failures": result.n_failed,
        "clamp": {key: report.describe() for key, report in outcome.clamp.items()},
        "executor": outcome.executor,
        "wall_s": outcome.wall_s,
        "task_time_s": outcome.compute_s,
        "task_cpu_s": outcome.cpu_s,
        "batches": {"total": outcome.n_batches, "reused": outcome.n_reused, "computed": outcome.n_computed},
        "files": files,
        "figures": "skipped (--no-figures)" if args.no_figures else "not written yet",
    }
    save_json(out / "campaign.json", to_jsonable(summary))
    return summary, tables


def _draw_figures(result: CampaignResult, tables: list[RocTable], mark: tuple[float, int], out: Path,
                  summary: dict[str, Any], deco: Decorations) -> None:
    """Fig. 11, the error traces and the ROC figure into ``out``; campaign.json then says which were written."""
    from studies.campaign import figures as campaign_figures
    from studies.campaign.results import save_json

    files = summary["files"]
    for key, name, make in (
        ("fig11", "fig11.png", lambda: campaign_figures.fig11(result, out / "fig11")[0]),
        ("error_traces", "error_traces.png", lambda: campaign_figures.error_traces(result, out / "error_traces")[0]),
        ("roc_png", "roc.png", lambda: campaign_figures.roc(tables, out / "roc", mark=mark)[0]),
    ):
        path = deco.attempt(name, make)
        if path is not None:
            files[key] = str(path)
    summary["figures"] = "written" if deco.ok else {"failed": deco.failed}
    save_json(out / "campaign.json", to_jsonable(summary))


def cmd_roc(args: argparse.Namespace) -> int:
    from studies.campaign import load_traces

    eps_grid = parse_grid(args.eps_th, "--eps-th")
    count_grid = parse_grid(args.count_max, "--count-max", integer=True)
    if not 0 <= args.healthy_max_pct <= args.faulty_min_pct <= 100:
        raise InputError(f"need 0 <= --healthy-max-pct <= --faulty-min-pct <= 100, got {args.healthy_max_pct:g} "
                         f"and {args.faulty_min_pct:g}")
    traces = load_traces(Path(args.source))
    tables = _roc_tables(traces, eps_grid, count_grid, args.healthy_max_pct / 100, args.faulty_min_pct / 100)
    for t in tables:
        if t.n_healthy == 0 or t.n_degraded == 0:
            print(f"shm campaign-roc: warning: {t.label}: {t.n_healthy} acceptable and {t.n_degraded} degraded "
                  "units — the campaign's ranges do not populate both classes", file=sys.stderr)
    src = Path(args.source)
    dest = out_dir(args.out if args.out else (src if src.is_dir() else src.parent))
    files = _write_roc(tables, dest, (traces.monitor.eps_th, traces.monitor.count_max))
    if args.json:
        print(dump_json({"roc": [row for t in tables for row in t.rows()],
                         "files": {k: str(v) for k, v in files.items()}}))
    else:
        for t in tables:
            j = int(np.argmin(np.abs(t.count_max - traces.monitor.count_max)))
            print(f"{t.label} (count_max {t.count_max[j]}; {t.n_healthy} acceptable, {t.n_degraded} degraded units):")
            for i, e in enumerate(t.eps_th):
                print(f"  eps_th {e:6.3f}: P_fa {100 * t.p_false_alarm[i, j]:5.1f} %   "
                      f"P_d {100 * t.p_detection[i, j]:5.1f} %")
        print(f"files: {', '.join(str(v) for v in files.values())}")
    return 0
