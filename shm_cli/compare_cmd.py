"""``shm compare``: hold the model against measurement records and report where it fails."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from board_config.assignments import parse_assignments
from board_config.errors import InputError
from shm_cli.batch_records import run_batch, wanted
from shm_cli.command_args import add_command, add_record_inputs
from shm_cli.common import add_out_arg, dump_json, out_dir, positive_float
from shm_cli.output_guard import add_force_arg, check_foreign_run, locked_out


def register(sub: argparse._SubParsersAction) -> None:
    p = add_command(
        sub, "compare", "compare the model with measurement records: fit, residual tests, where it fails (HTML)",
        """Replay each record's inputs through the model (free run, and a labelled k-step-ahead prediction), then
        report fit % per channel, the paper's normalised error (Eq. 4-5), residual tests with bands and verdicts
        (bias, whiteness, input cross-correlation, the five Billings-Voon tests) and where the model fails (time
        windows by regime, error-carrying bands, residual vs drive amplitude and rate, rising vs falling branches).
        Writes PNGs, a self-contained report.html and compare.json into --out. Records: see docs/records.md.""")
    add_record_inputs(p, "record files (.csv time record or FRF table, .tdms)")
    p.add_argument("--add", action="append", default=[], metavar="EFFECT",
                   help="add a physical effect to the model (registered name or pkg.mod:Class); repeatable")
    p.add_argument("--set", action="append", default=[], metavar="NAME=VALUE", dest="set_values",
                   help="value of a model parameter (core or an added effect's), SI; repeatable")
    g = p.add_argument_group("analysis")
    g.add_argument("--skip-s", type=float, default=0.0, help="transient skip at the start of each record (s)")
    g.add_argument("--level", type=float, default=0.01, help="residual-test level α per test (default 0.01 = 99 %%)")
    g.add_argument("--lags", type=int, default=25, help="lags per correlation test (default 25)")
    g.add_argument("--decimate", type=int, default=1, help="residual tests on every k-th sample (default 1)")
    g.add_argument("--threshold-sigma", type=float, default=3.0,
                   help="flag windows whose rolling RMS residual exceeds this many noise σ (default 3)")
    g.add_argument("--window-s", type=positive_float, default=None,
                   help="rolling window (s; default 1 %% of the record)")
    g.add_argument("--no-predict", action="store_true", help="skip the k-step-ahead prediction")
    g.add_argument("--horizon-s", type=float, default=0.05, help="prediction horizon (s, default 0.05)")
    g.add_argument("--interval-s", type=float, default=0.01, help="observer correction interval (s, default 0.01)")
    g.add_argument("--eq4", action="append", default=[], metavar="CH=E0,KERR",
                   help="given Eq. 4 constants for a channel, SI (default for z3: the paper's 0.75e-3,0.075)")
    fq = g.add_mutually_exclusive_group()
    fq.add_argument("--frf", action="store_true", default=None,
                    help="also compare in the frequency domain: H1 and coherence of each channel against the drive, "
                         "measured vs the model's free run, with the resonance peaks (default: on for sweep records)")
    fq.add_argument("--no-frf", action="store_false", dest="frf", help="no frequency-domain panel, even for a sweep")
    p.add_argument("--json", action="store_true", help="also print the report's numbers as JSON on stdout")
    add_out_arg(p)
    add_force_arg(p, "another command's finished run in --out (its report is rewritten)")
    p.set_defaults(func=cmd_compare)


def _eq4(items: list[str]) -> dict[str, tuple[float, float]]:
    out = {}
    for item in items:
        ch, sep, rest = item.partition("=")
        parts = rest.split(",")
        try:
            if not sep or len(parts) != 2:
                raise InputError
            e0, k = float(parts[0]), float(parts[1])
        except ValueError:
            raise InputError(f"--eq4 expects CH=E0,KERR (SI), got '{item}'") from None
        if e0 < 0 or k <= 0:
            raise InputError(f"--eq4 {ch}: need e0 >= 0 and kerr > 0, got {e0}, {k}")
        out[ch.strip()] = (e0, k)
    return out


def cmd_compare(args: argparse.Namespace) -> int:
    if wanted(args, args.records):  # a folder or 'glob': one task per record (docs/scale-out.md)
        return run_batch("compare", args, args.records)
    from workbench.compare import CompareOptions
    from workbench.fit import probe_effects
    from workbench.records import gap_notes, load_record

    if args.lags < 1 or args.decimate < 1:
        raise InputError("--lags and --decimate must be at least 1")
    if not 0 < args.level < 1:
        raise InputError(f"--level must be in (0, 1), got {args.level}")
    if args.skip_s < 0 or args.threshold_sigma <= 0 or args.horizon_s <= 0 or args.interval_s <= 0:
        raise InputError("--skip-s must be >= 0; --threshold-sigma, --horizon-s and --interval-s must be > 0")
    options = CompareOptions(skip_s=args.skip_s, level=args.level, max_lag=args.lags, decimate=args.decimate,
                             threshold_sigma=args.threshold_sigma, window_s=args.window_s,
                             predict=not args.no_predict, horizon_s=args.horizon_s, interval_s=args.interval_s,
                             eq4_given=_eq4(args.eq4) or None, frf=args.frf)
    values = parse_assignments("--set", args.set_values, comma_lists=False)
    check_foreign_run(Path(args.out), "compare.json", args.force)
    records = [load_record(Path(r)) for r in args.records]  # validate every file before any work
    for note in gap_notes(records):  # lost samples are left out, said once (docs/records.md)
        print(f"shm compare: {note}", file=sys.stderr)
    probe_effects(args.add, args.params, "--add")
    with locked_out(out_dir(args.out), "compare"):
        return _compare(args, records, values, options)


def _compare(args: argparse.Namespace, records: list, values: dict[str, float], options) -> int:
    from tqdm import tqdm

    from workbench.compare import compare, report_json, write_report
    from workbench.simulation import SimulationFailed

    comparisons = []
    failures = []
    for rec in tqdm(records, desc="compare", unit="record", file=sys.stderr, disable=len(records) < 2):
        model = _model(rec, args.params, args.add, values)
        try:
            comparisons.append(compare(model, rec, options))
        except SimulationFailed as exc:
            failures.append(str(exc))
            print(f"shm compare: {exc}", file=sys.stderr)
    if not comparisons:
        return 1
    paths = write_report(comparisons, args.out)
    for c in comparisons:
        verdicts = ", ".join(f"{ch} {v}" for ch, v in c.verdicts().items())
        print(f"{c.record.name}: {verdicts}", file=sys.stderr)
    print(f"report: {paths['html']}", file=sys.stderr)
    if args.json:
        print(dump_json({**report_json(comparisons), "failures": failures}))
    return 1 if failures else 0


def _model(record, params: str, add: list[str], values: dict[str, float]):
    from board_config import CORE_PARAMETER_NAMES, load_parameter_set
    from workbench.simulation import model_for

    pset = load_parameter_set(params)
    core = {k: v for k, v in values.items() if k in CORE_PARAMETER_NAMES}
    if core:
        pset = pset.with_values(None, **core)  # (the set's name kept)
    rest = {k: v for k, v in values.items() if k not in CORE_PARAMETER_NAMES}
    return model_for(record, pset, effects=add, effect_params=rest)
