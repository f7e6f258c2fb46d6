"""``shm diagnose``: which physical effect is missing from the model — or which parameter is wrong?"""

from __future__ import annotations

import argparse
import functools
import sys

from shm_cli.batch_records import run_batch, wanted
from shm_cli.command_args import add_command, add_holdout_args, add_record_inputs
from shm_cli.common import Decorations, add_out_arg, dump_json, out_dir, seed_int
from shm_cli.output_guard import locked_out


def register(sub: argparse._SubParsersAction) -> None:
    p = add_command(
        sub, "diagnose", "rank missing effects and wrong parameters by how much held-out residual each explains",
        """For every candidate — each library effect and each core parameter (k_i, c_i, m_i, d_ep, R_ep, C_ep,
        alpha_h, beta_h, gamma_h) or group (stiffness, damping, mass scaled together; the electrical pair) to
        re-estimate — screen it cheaply, fit the promising ones on a training part of the records, score them on
        held-out blocks (or records), and rank by held-out error reduction with a BIC penalty per free parameter. A
        re-estimation that explains as well as an effect wins (no new physics). When the best leaves more than 1.5
        σ, forward selection adds the next best. Candidates whose free run diverges, goes flat or ends at its bounds
        lose their claim. A verdict names a member only when it is identifiable on the records, not at a bound,
        changes the prediction by more than the noise and costs more than the noise when removed; it says 'm3 is
        wrong: ... — re-estimate it', 'missing effect' or a combination only when that reaches 1.5 σ held out, else
        the share of the excess over the noise the library explains. Then, when the library falls short, it runs the
        discovery step (shm discover) itself, writes what it finds inside --out (discovered.py, never over an
        existing file) and ends with one verdict: what was found in words and formula and the shm fit --add command
        (--no-discover: print the shm discover command instead). Writes diagnosis.json, ranking.png, overlay.png and
        diagnosis.html.""")
    add_record_inputs(p, "time records (.csv or .tdms; docs/records.md)")
    p.add_argument("--candidates", action="append", default=None, metavar="NAME[,NAME...]",
                   help="candidates, comma-separated or repeated: effects (library names or pkg.mod:Class), core "
                        "parameters (m3, k2, ...) or groups (stiffness, damping, mass, electrical); default: the "
                        "whole library and every parameter")
    p.add_argument("--fit-top", type=int, default=3, metavar="N",
                   help="after screening, fit in full the best N effects and the best N parameter candidates "
                        "(default 3; 0: fit every candidate)")
    p.add_argument("--no-combine", action="store_true", help="do not look for combinations (forward selection)")
    add_holdout_args(p, " for fitting")
    p.add_argument("--min-reduction", type=float, default=0.02,
                   help="held-out residual-energy reduction a candidate must reach to be accepted (default 0.02)")
    p.add_argument("--workers", type=int, default=1, help="candidates fitted concurrently (threads; default 1)")
    p.add_argument("--seed", type=seed_int, default=0, help="seed of the multi-start design")
    p.add_argument("--no-discover", action="store_true",
                   help="when the library and the parameters fall short (more than 1.5 σ held out), do not run the "
                        "discovery step (shm discover) and only print its command")
    p.add_argument("--json", action="store_true", help="print the diagnosis as JSON on stdout")
    add_out_arg(p)
    p.set_defaults(func=cmd_diagnose)


def cmd_diagnose(args: argparse.Namespace) -> int:
    if wanted(args, args.records):  # a folder or 'glob': one task per record (docs/scale-out.md)
        return run_batch("diagnose", args, args.records)
    from workbench.records import check_distinct_records

    check_distinct_records(args.records)  # one record twice: training and held-out data would be the same
    with locked_out(out_dir(args.out), "diagnose"):
        return _diagnose(args)


def _candidates(args: argparse.Namespace) -> list[str] | None:
    """The option checks, and the --candidates list (None: the whole library and every parameter)."""
    from shm_cli.main import CliError

    if args.workers < 1 or args.max_rate_hz <= 0 or not 0 <= args.min_reduction < 1 or args.fit_top < 0:
        raise CliError("--workers must be >= 1, --max-rate-hz > 0, --min-reduction in [0, 1) and --fit-top >= 0")
    if not args.candidates:
        return None
    candidates = [c.strip() for item in args.candidates for c in item.split(",") if c.strip()]
    if not candidates:
        raise CliError("--candidates is empty")
    return candidates


def _diagnose(args: argparse.Namespace) -> int:
    from shm_cli.main import CliError
    from shm_cli.progress import StageReporter

    # progress on stderr: a bar per stage on a terminal, one line per stage in a log (shm_cli.progress); the first at
    # once, before the imports and the records (seconds on a loaded machine)
    reporter = StageReporter("diagnose")
    reporter.stage("loading", None, f"{len(args.records)} record(s)")
    from workbench.diagnose import diagnose, overlay_figure, ranking_figure, write_html
    from workbench.fit import FitError
    from workbench.records import gap_notes, load_record

    candidates = _candidates(args)
    out = out_dir(args.out)
    (out / "diagnosis.json").unlink(missing_ok=True)  # written at the end: an earlier one must not outlive a failure
    records = [load_record(p) for p in args.records]
    for note in gap_notes(records):  # lost samples are left out, said once (docs/records.md)
        print(f"shm diagnose: {note}", file=sys.stderr)
    try:
        with reporter:
            d = diagnose(records, args.params, candidates, holdout=args.holdout, n_blocks=args.blocks,
                         max_rate_Hz=args.max_rate_hz, min_reduction=args.min_reduction, workers=args.workers,
                         seed=args.seed, fit_top=args.fit_top or None, combine=not args.no_combine,
                         params_label=args.params, reporter=reporter,
                         emit_dir=None if args.no_discover else out,
                         on_discover=lambda m: reporter.write(f"diagnose: discover: {m}"))
    except FitError as exc:
        raise CliError(str(exc)) from None
    rows = []
    fitted = [c for c in d.ranking if c.outcome is not None]
    for rank, c in enumerate(fitted, start=1):
        status = ("accepted" if c.accepted else ("rejected: " + c.rejection if not c.stable else
                                                 (c.rejection or "not enough")))
        rows.append([str(rank), c.effect, c.kind, f"{c.held_rms_sigma:.4g}", f"{100 * c.held_reduction:+.2f}",
                     f"{c.delta_bic_held:.4g}", status, c.estimates_text()])
    header = ["rank", "candidate", "kind", "held-out RMS (σ)", "reduction %", "ΔBIC held", "status",
              "estimates (± std. error)"]
    screened = [c for c in d.ranking if c.outcome is None]
    # --json: stdout carries the JSON document only; the table and notes go to stderr
    say = functools.partial(print, file=sys.stderr) if args.json else print
    say(f"nominal model ({d.params_name}): training {d.baseline_train_rms_sigma:.4g} σ, held-out "
        f"{d.baseline_held_rms_sigma:.4g} σ")
    widths = [max(len(str(r[i])) for r in [header, *rows]) for i in range(len(header) - 1)]
    for r in [header, *rows]:
        say("  " + "  ".join(str(x).ljust(w) for x, w in zip(r[:-1], widths)) + "  " + str(r[-1]))
    if screened:
        say("  screened out (training RMS σ at the best screening point): "
            + ", ".join(f"{c.effect} {c.screen_train_rms_sigma:.3g}" for c in screened))
    if len(d.steps) > 1:
        say("  forward selection: " + " → ".join(f"{c.effect} ({c.held_rms_sigma:.3g} σ)" for c in d.steps))
    if args.no_discover and d.verdict in ("partial", "unexplained"):
        d.discover["reason"] = "--no-discover"
    say()
    say(d.message)
    for n in d.notes:
        say(f"note: {n}")
    # the numbers first (diagnosis.json), then the figures and the report: a plotting failure never loses them
    reporter.stage("writing the report", None, "diagnosis.json, ranking.png, overlay.png, diagnosis.html")
    result = d.to_dict() | {"figures": []}
    (out / "diagnosis.json").write_text(dump_json(result), encoding="utf-8")
    deco = Decorations("diagnose", args)
    rank_png = deco.attempt("ranking.png", lambda: ranking_figure(d, out / "ranking.png"))
    after = d.winner.outcome.sim if d.winner and d.winner.outcome else None
    ov_png = deco.attempt("overlay.png", lambda: overlay_figure(
        d.targets, d.baseline_sim, after, out / "overlay.png", label_after=_after_label(d)))
    figures = [f for f in (rank_png, ov_png) if f is not None]
    deco.attempt("diagnosis.html", lambda: write_html(
        out / "diagnosis.html", f"shm diagnose: {d.params_name}", d.message, [("Candidates", header, rows)], figures,
        [*d.notes, *("Where the nominal model fails: " + w for w in d.where_it_fails)]))
    result = d.to_dict() | {"figures": [str(f) for f in figures]} | ({"failed": deco.failed} if deco.failed else {})
    (out / "diagnosis.json").write_text(dump_json(result), encoding="utf-8")
    reporter.close()
    print(f"report: {out / 'diagnosis.html'}", file=sys.stderr)
    if args.json:
        print(dump_json(result))
    return 0 if deco.ok else 1


def _after_label(d) -> str:
    if d.winner is None:
        return ""
    return f"{d.winner.effect} re-estimated" if d.winner.kind == "parameter" else f"+ {d.winner.effect}"
