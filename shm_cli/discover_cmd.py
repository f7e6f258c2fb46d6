"""``shm discover``: search candidate correction terms beyond the effects library, name what is missing, emit it as
an effect file that ``shm fit --add FILE.py`` refits."""

from __future__ import annotations

import argparse
import functools
import sys
from pathlib import Path

from shm_cli.batch_records import run_batch, wanted
from shm_cli.command_args import add_command, add_holdout_args, add_record_inputs
from shm_cli.common import dump_json, out_dir
from shm_cli.output_guard import add_force_arg, check_new_file, locked_out, write_whole


def register(sub: argparse._SubParsersAction) -> None:
    p = add_command(
        sub, "discover", "find a missing term beyond the effects library and write it as an effect file",
        """Search a dictionary of candidate correction terms built from the model's own signals (forces on masses
        and sections, currents into the patches, changes of the drive and of the laser reading; linear, sign, |x|·x,
        polynomial, one-sided, dead-zone, clearance, saturating, time-weighted and delayed forms), keep the few that
        explain held-out data, refit them on the full nonlinear model, check the result runs free without diverging,
        and say what was found in words and units. --emit writes it as a PhysicalEffect module; refit it with `shm
        fit RECORD --add FILE.py`. 'Not found' is an allowed answer.""")
    add_record_inputs(p, "time records (.csv or .tdms; docs/records.md)")
    p.add_argument("--add", action="append", default=[], metavar="EFFECT",
                   help="effect already in the model (library name, pkg.mod:Class or FILE.py; repeatable)")
    p.add_argument("--emit", default=None, metavar="FILE.py",
                   help="write what was found as an effect module here (nothing is written when nothing is found)")
    p.add_argument("--out", required=True, metavar="DIR", help="directory for discover.json")
    add_force_arg(p, "the --emit file")
    p.add_argument("--max-terms", type=int, default=2, help="most terms to keep (forward selection; default 2)")
    p.add_argument("--refit", type=int, default=4, help="screened terms refitted per round (default 4)")
    add_holdout_args(p)
    p.add_argument("--json", action="store_true", help="print the result as one JSON document on stdout")
    p.set_defaults(func=cmd_discover)


def cmd_discover(args: argparse.Namespace) -> int:
    if wanted(args, args.records):  # a folder or 'glob': one task per record (docs/scale-out.md)
        return run_batch("discover", args, args.records)
    from shm_cli.main import CliError

    if args.emit is not None and Path(args.emit).suffix != ".py":
        raise CliError(f"--emit must name a .py file, got '{args.emit}'")
    if args.emit is not None and not Path(args.emit).stem.isidentifier():
        raise CliError(f"--emit {args.emit}: the file name must be a Python identifier (letters, digits, _)")
    if not 1 <= args.max_terms <= 4:
        raise CliError(f"--max-terms must be 1 … 4, got {args.max_terms}")
    if not 1 <= args.refit <= 20:
        raise CliError(f"--refit must be 1 … 20, got {args.refit}")
    if not args.max_rate_hz > 0:
        raise CliError(f"--max-rate-hz must be > 0, got {args.max_rate_hz}")
    if args.emit is not None:
        _check_emit(Path(args.emit), args.add, args.force)
    out = out_dir(args.out)
    with locked_out(out, "discover"):
        return _discover(args, out)


def _check_emit(emit: Path, add: list[str], force: bool) -> None:
    """--emit names a new file: never one of the --add effect files being refined (even with --force: the effect
    would be lost), never an existing file without --force, never the shipped configuration."""
    from plant.effect import is_file_spec, split_instance_spec
    from shm_cli.main import CliError

    for spec in add:
        inner = split_instance_spec(spec)[0]
        path = Path(inner if inner.endswith(".py") or ":" not in inner else inner.rpartition(":")[0])
        if is_file_spec(inner) and path.exists() and emit.exists() and path.resolve() == emit.resolve():
            raise CliError(f"--emit {emit} is the effect file given to --add {spec}: writing there would replace the "
                           f"effect being refined (--force does not apply); emit to another file (e.g. --emit "
                           f"{emit.with_name(emit.stem + '_more.py')}) and refit with --add {spec} --add <that file>")
    check_new_file(emit, "--emit", force)


def _discover(args: argparse.Namespace, out: Path) -> int:
    from board_config import load_parameter_set
    from shm_cli.main import CliError
    from workbench.discover import describe_units, discover
    from workbench.fit import FitError, probe_effects
    from workbench.records import check_distinct_records, gap_notes, load_record

    check_distinct_records(args.records)
    records = [load_record(p) for p in args.records]
    for note in gap_notes(records):  # lost samples are left out, said once (docs/records.md)
        print(f"shm discover: {note}", file=sys.stderr)
    base = load_parameter_set(args.params)
    probe_effects(args.add, base, "--add")
    say = functools.partial(print, file=sys.stderr) if args.json else print
    progress = functools.partial(print, file=sys.stderr, flush=True)
    progress(f"discover: {len(records)} record(s), parameter set {base.name}"
             + (f" + {', '.join(args.add)}" if args.add else ""))
    try:
        d = discover(records, base, args.add, max_terms=args.max_terms, n_refit=args.refit, holdout=args.holdout,
                     n_blocks=args.blocks, max_rate_Hz=args.max_rate_hz, on_progress=progress)
    except FitError as exc:
        raise CliError(str(exc)) from None
    say("")
    say(d.message)
    for line in describe_units(d.terms):
        say(f"  {line}")
    summary = d.to_dict() | {"emitted": None}
    if d.terms and args.emit:
        emit = Path(args.emit)
        emit.parent.mkdir(parents=True, exist_ok=True)
        src = d.effect_source(effect_name=f"discovered_{emit.stem}")
        assert src is not None
        write_whole(emit, lambda tmp: tmp.write_text(src, encoding="utf-8"), "--emit", args.force)
        # it must load through the documented seam, as `shm fit --add FILE.py` will load it
        from plant.effect import EffectError, resolve_effect

        try:
            cls = resolve_effect(str(emit))
        except EffectError as exc:  # a bug in the writer, not the user's input
            raise RuntimeError(f"the emitted effect does not load: {exc}") from exc
        summary["emitted"] = {"file": str(emit), "class": cls.__name__, "effect": cls.name}
        records_arg = " ".join(args.records)
        say(f"wrote {emit} ({cls.__name__}); refit it with:\n  shm fit {records_arg} --params {args.params} "
            f"--add {emit} --save refit.toml --out fit")
    elif args.emit:
        say(f"nothing written to {args.emit}: nothing was found")
    (out / "discover.json").write_text(dump_json(summary), encoding="utf-8")
    if args.json:
        print(dump_json(summary))
    return 0
