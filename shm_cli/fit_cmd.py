"""``shm fit``: add physical effects to the model, refit, watch the error fall, save a parameter set."""

from __future__ import annotations

import argparse
import functools
import sys
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from shm_cli.batch_records import run_batch, wanted
from shm_cli.command_args import add_command, add_holdout_args, add_record_inputs
from shm_cli.common import Decorations, dump_json, out_dir, output_file_arg, seed_int
from shm_cli.output_guard import add_force_arg, check_new_file, locked_out, write_whole

if TYPE_CHECKING:
    from board_config import ParameterSet
    from workbench.diagnose import ProgressPlot
    from workbench.fit import FitHistoryPoint, FitOutcome, FitReport, FitStatistics

#: fit.html's tables: (title, header, rows)
Table = tuple[str, list[str], list[list[str]]]


def register(sub: argparse._SubParsersAction) -> None:
    p = add_command(
        sub, "fit", "add physical effects, refit their parameters on records, report the fit, save a parameter set",
        """Add one or more physical effects (library names, see `shm diagnose`, or your own pkg.mod:Class or
        FILE.py) to the model, fit their parameters (and any --free ones) on the training part of the records with
        least squares, and show the error falling per iteration (terminal and fit_progress.png). Prints a
        before/after table on training and held-out data and a fit report as lmfit prints it (chi-square, reduced
        chi-square, AIC, BIC; estimates with standard errors; correlations; warnings for parameters at a bound, not
        identifiable or strongly correlated), also in fit.json; with --save, writes a parameter set (TOML with
        [[effects]]) that `shm run` and the board's monitor load at once.""")
    add_record_inputs(p, "time records (.csv or .tdms; docs/records.md)")
    p.add_argument("--add", action="append", default=[], metavar="EFFECT",
                   help="effect to add: a library name, pkg.mod:Class, or a file FILE.py / FILE.py:Class (e.g. the one "
                        "`shm discover --emit` wrote; repeatable)")
    p.add_argument("--free", action="append", default=[], metavar="PARAM[:LO:HI]",
                   help="also fit this parameter (core, e.g. k3, or an effect's), optionally with its range in SI "
                        "units (repeatable)")
    p.add_argument("--save", default=None, metavar="NAME.toml", type=output_file_arg,
                   help="write the fitted parameter set here (its name is the file's stem); without it the fit is "
                        "evaluated and reported, nothing is saved")
    add_holdout_args(p, " for fitting")
    p.add_argument("--max-nfev", type=int, default=40, help="optimiser evaluations per start (default 40)")
    p.add_argument("--seed", type=seed_int, default=0, help="seed of the multi-start design")
    p.add_argument("--out", default=None, metavar="DIR",
                   help="directory for fit.json, fit_progress.png, fit_overlay.png, fit.html (default: beside --save, "
                        "else the current directory)")
    p.add_argument("--json", action="store_true", help="print the summary as JSON on stdout")
    add_force_arg(p, "the --save file")
    p.set_defaults(func=cmd_fit)


def _load_records(paths: list[str]):
    from workbench.records import check_distinct_records, gap_notes, load_record

    check_distinct_records(paths)
    records = [load_record(p) for p in paths]
    for note in gap_notes(records):  # lost samples are left out, said once (docs/records.md)
        print(f"shm fit: {note}", file=sys.stderr)
    return records


def cmd_fit(args: argparse.Namespace) -> int:
    if wanted(args, args.records):  # a folder or 'glob': one task per record (docs/scale-out.md)
        return run_batch("fit", args, args.records)
    from shm_cli.main import CliError

    save = Path(args.save) if args.save is not None else None
    if save is not None and save.suffix.lower() != ".toml":
        raise CliError(f"--save must name a .toml file, got '{args.save}'")
    if not args.add and not args.free:
        raise CliError("nothing to fit: give --add EFFECT and/or --free PARAM")
    if args.max_rate_hz <= 0 or args.max_nfev < 1:
        raise CliError("--max-rate-hz must be > 0 and --max-nfev >= 1")
    if save is not None:  # checked before the fit: never over the shipped sets, never over a file without --force
        check_new_file(save, "--save", args.force)
    out = _output_dir(args.out, save)
    if not args.out:  # the report beside --save or in the current directory: no lock file left among the user's
        return _fit(args, out, save)
    with locked_out(out, "fit"):
        return _fit(args, out, save)


def _fit(args: argparse.Namespace, out: Path, save: Path | None) -> int:
    from board_config import load_parameter_set
    from shm_cli.main import CliError
    from workbench.diagnose import ProgressPlot
    from workbench.fit import (
        FitError,
        fit_records,
        other_notes,
        probe_effects,
        report_dict,
        resolve_candidates,
    )

    records = _load_records(args.records)
    base = load_parameter_set(args.params)
    resolve_candidates(args.add)  # each loads and has something to fit (EffectError), before a probe compiles it
    probe_effects(args.add, base, "--add")
    (out / "fit.json").unlink(missing_ok=True)  # written at the end: an earlier one must not outlive a failure
    progress: list[ProgressPlot] = []
    deco = Decorations("fit", args)

    def on_baseline(train: float, held: float) -> None:
        print(f"before: training error {train:.4g} σ, held-out {held:.4g} σ (σ: noise level of each channel)",
              file=sys.stderr)
        print(f"{'iter':>5} {'sims':>6} {'train error (σ)':>16}  parameters", file=sys.stderr)
        progress.append(ProgressPlot(out / "fit_progress.png", train, held))

    def on_iteration(pt: FitHistoryPoint) -> None:
        vals = "  ".join(f"{k}={v:.4g}" for k, v in pt.values.items())
        print(f"{pt.iteration:5d} {pt.n_sims:6d} {pt.train_rms_sigma:16.4g}  {vals}", file=sys.stderr, flush=True)
        if progress and "fit_progress.png" not in deco.failed:  # a live figure that fails must not stop the fit
            deco.attempt("fit_progress.png", lambda: progress[0].add(pt))

    print(f"fitting {', '.join(args.add) or '-'}" + (f" + free {', '.join(args.free)}" if args.free else "")
          + f" on {len(records)} record(s), parameter set {base.name}", file=sys.stderr)
    try:
        rep = fit_records(records, base, add=args.add, free=args.free,
                          save_name=save.stem if save is not None else f"{base.name}_fitted", holdout=args.holdout,
                          n_blocks=args.blocks, max_rate_Hz=args.max_rate_hz, max_nfev=args.max_nfev,
                          seed=args.seed, on_iteration=on_iteration, on_baseline=on_baseline)
    except FitError as exc:
        raise CliError(str(exc)) from None
    o = rep.outcome
    # --json: stdout carries the JSON document only; the tables and notes go to stderr
    say = functools.partial(print, file=sys.stderr) if args.json else print
    pset = _save_set(rep, save, args.force) if save is not None else None
    header, rows = _before_after(rep)
    notes = other_notes(rep.notes, o.estimates)  # what [[Warnings]] does not already say
    _print_results(say, rep, header, rows, notes)
    if pset is not None:
        say(f"saved parameter set '{pset.name}' to {save} (load it with --params {save})")
    else:
        say("no parameter set saved (give --save NAME.toml to keep the fitted values)")
    summary = rep.summary() | {"fit_report": report_dict(o, rep.initial),
                               "saved": str(save) if save is not None else None, "figures": []}
    (out / "fit.json").write_text(dump_json(summary), encoding="utf-8")

    figures = _write_figures_and_page(out, rep, base.name, progress, deco, [("Before / after", header, rows)], notes)
    summary = summary | {"figures": [str(f) for f in figures]} | ({"failed": deco.failed} if deco.failed else {})
    (out / "fit.json").write_text(dump_json(summary), encoding="utf-8")
    if args.json:
        print(dump_json(summary))
    return 0 if deco.ok else 1



def _write_figures_and_page(out: Path, rep: FitReport, base_name: str, progress: list[ProgressPlot],
                            deco: Decorations, tables: list[Table], notes: list[str]) -> list[Path]:
    """The fit's progress and overlay figures and its HTML page (a failure is recorded in ``deco``, not raised)."""
    from workbench.diagnose import ProgressPlot, overlay_figure, write_html
    from workbench.fit import fit_warnings

    o = rep.outcome

    def progress_figure() -> Path:
        plot = progress[0] if progress else ProgressPlot(out / "fit_progress.png", rep.before_train_rms_sigma,
                                                             rep.before_held_rms_sigma)
        plot.draw(held_after=o.held_rms_sigma)
        return plot.path

    figures = [f for f in (
        None if "fit_progress.png" in deco.failed else deco.attempt("fit_progress.png", progress_figure),
        deco.attempt("fit_overlay.png", lambda: overlay_figure(
            rep.targets, rep.baseline_sim, o.sim, out / "fit_overlay.png",
            label_after=f"+ {', '.join(rep.added) or 'refit'}")),
    ) if f is not None]
    verdict = (f"Added {', '.join(rep.added) or 'nothing'}; training error {rep.before_train_rms_sigma:.4g} σ → "
               f"{o.train_rms_sigma:.4g} σ, held-out {rep.before_held_rms_sigma:.4g} σ → {o.held_rms_sigma:.4g} σ.")
    deco.attempt("fit.html", lambda: write_html(
        out / "fit.html", f"shm fit: {base_name} + {', '.join(rep.added) or 'refit'}", verdict,
        [*tables, *_report_tables(o)],
        figures, [w.message for w in fit_warnings(o.estimates, o.correlation)] + notes))
    return figures


def _save_set(rep: FitReport, save: Path, force: bool) -> ParameterSet:
    """Write the fitted parameter set to ``save`` (atomically) and check that it loads as `shm run` will load it."""
    from board_config import load_parameter_set
    from plant import PlantModel
    from shm_cli.main import CliError
    from workbench.fit import FitError

    try:
        pset = rep.parameter_set
    except FitError as exc:
        raise CliError(str(exc)) from None
    # the results first (the saved set, fit.json), then the figures and the report: a plotting failure never
    # loses them
    text = pset.to_toml()
    write_whole(save, lambda tmp: tmp.write_text(text, encoding="utf-8"), "--save", force)
    PlantModel(load_parameter_set(save))
    return pset


def _print_results(say: Callable[[str], None], rep: FitReport, header: list[str], rows: list[list[str]],
                   notes: list[str]) -> None:
    """The before/after table and the error change (``say``), then the fit report as lmfit prints it (statistics,
    variables, correlations, warnings; always on stderr) and the notes."""
    from workbench.fit import format_report

    o = rep.outcome
    say("\nbefore / after (residual RMS; σ = noise level of the channel):")
    widths = [max(len(str(r[i])) for r in [header, *rows]) for i in range(len(header))]
    for r in [header, *rows]:
        say("  " + "  ".join(str(x).ljust(w) for x, w in zip(r, widths)))
    say(f"\ntraining: {rep.before_train_rms_sigma:.4g} σ → {o.train_rms_sigma:.4g} σ;  held-out: "
        f"{rep.before_held_rms_sigma:.4g} σ → {o.held_rms_sigma:.4g} σ")
    print("\n" + format_report(o, rep.initial), file=sys.stderr, flush=True)
    for n in notes:
        say(f"  note: {n}")


def _output_dir(out: str | None, save: Path | None) -> Path:
    """--out, else beside --save, else the current directory (created if missing)."""
    if out:
        return out_dir(out)
    if save is not None:
        return out_dir(save.parent if str(save.parent) else ".", option="--save (its directory)")
    return out_dir(".", option="--out (default: the current directory)")


def _before_after(rep: FitReport) -> tuple[list[str], list[list[str]]]:
    header = ["record", "channel", "part", "RMS before", "before (σ)", "RMS after", "after (σ)", "fit %"]
    rows = [[b.record, b.channel, b.part, f"{b.rms:.4g} {b.unit}", f"{b.rms_sigma:.3g}", f"{a.rms:.4g} {a.unit}",
             f"{a.rms_sigma:.3g}", f"{b.fit_pct:.2f} → {a.fit_pct:.2f}"] for b, a in zip(rep.before, rep.after)]
    return header, rows


def _report_tables(o: FitOutcome) -> list[Table]:
    """fit.html's tables of the fit report: statistics, estimates, the correlation matrix."""
    from workbench.fit import fit_statistics

    names = [e.name for e in o.estimates]
    return [
        ("Fit statistics", ["quantity", "value"], _statistics_rows(fit_statistics(o))),
        ("Estimates", ["parameter", "value", "std. error", "relative", "unit", "range", "effect"],
         [[e.name, f"{e.value:.5g}", f"{e.stderr:.3g}", f"{100 * e.stderr / abs(e.value):.2f} %" if e.value else "—",
           e.unit, f"[{e.lower:.4g}, {e.upper:.4g}]" + (" at a bound" if e.at_bound else ""), e.owner]
          for e in o.estimates]),
        ("Correlations of the estimates", ["", *names],
         [[n, *[f"{o.correlation[i, j]:+.3f}" for j in range(len(names))]] for i, n in enumerate(names)]),
    ]


def _statistics_rows(s: FitStatistics) -> list[list[str]]:
    return [["# data points (training samples × channels)", f"{s.n_data}"], ["# variables", f"{s.n_variables}"],
            ["chi-square (Σ r², r in noise σ)", f"{s.chi_square:.6g}"],
            ["reduced chi-square (≈ 1 at the noise floor)", f"{s.reduced_chi_square:.6g}"],
            ["Akaike info crit", f"{s.aic:.6g}"], ["Bayesian info crit", f"{s.bic:.6g}"],
            ["held-out χ²/N", f"{s.held_out_reduced_chi_square:.6g} ({s.held_out_n} samples)"],
            ["residual lag-1 autocorrelation", f"{s.residual_lag1:.3f}"]]
