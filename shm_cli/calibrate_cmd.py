"""``shm calibrate``: identify a parameter set against the paper's stated numbers (resonances, RC pole, harvesting
gains), keeping the quasi-static actuation gain of the starting set."""

from __future__ import annotations

import argparse
import sys
import tomllib
from pathlib import Path
from typing import TYPE_CHECKING

from board_config.errors import InputError
from shm_cli.common import Decorations, add_out_arg, add_params_arg, dump_json, out_dir, output_file_arg
from shm_cli.output_guard import add_force_arg, check_foreign_run, check_new_file, locked_out, write_whole

if TYPE_CHECKING:
    from board_config import ParameterSet
    from workbench.fit import ClaimTarget


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("calibrate", help="fit a parameter set to the paper's stated numbers (paper_claims.toml)",
                       description=__doc__)
    add_params_arg(p)
    p.add_argument("--claims", default=None, metavar="FILE",
                   help="claims TOML (default: the shipped copy of the paper's stated numbers)")
    p.add_argument("--free", nargs="+", default=None, metavar="PARAM",
                   help="core parameters to fit (default: the MEM-identified ones: k1 k2 k3 c1 c2 c3 d_ep)")
    p.add_argument("--min-damping", type=float, default=0.01,
                   help="soft floor on every bending mode's damping ratio (default 0.01)")
    p.add_argument("--no-keep-actuation", action="store_true",
                   help="do not hold the quasi-static tip gain z3/v_a at the starting set's value")
    p.add_argument("--name", default="calibrated", help="name written into the saved set")
    p.add_argument("--save", default=None, metavar="FILE.toml", type=output_file_arg,
                   help="write the calibrated parameter set here (an existing file only with --force)")
    p.add_argument("--json", action="store_true", help="print the result table as JSON")
    add_out_arg(p)
    add_force_arg(p, "the --save file, and another command's finished run in --out (its report is rewritten)")
    p.set_defaults(func=cmd_calibrate)


def cmd_calibrate(args: argparse.Namespace) -> int:
    from board_config import load_parameter_set
    from plant import PlantModel
    from plant.linear import static_tip_gain_closed_form
    from workbench.fit import CLAIMS_FILE, load_claim_targets

    if not args.name.strip():
        raise InputError("--name is empty: the saved parameter set needs a name")
    if not 0.0 <= args.min_damping < 1.0:
        raise InputError(f"--min-damping must be in [0, 1), got {args.min_damping}")
    base = load_parameter_set(args.params)
    claims = Path(args.claims) if args.claims else CLAIMS_FILE
    if not claims.is_file():
        raise InputError(f"--claims {claims}: file not found" + (" (a directory)" if claims.is_dir() else ""))
    keep = None if args.no_keep_actuation else static_tip_gain_closed_form(PlantModel(base))
    try:
        targets = load_claim_targets(claims, static_gain_m_per_v=keep)
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise InputError(f"--claims {claims}: not valid TOML: {exc}") from None
    except KeyError as exc:
        raise InputError(f"--claims {claims}: missing key {exc} (layout: the shipped paper_claims.toml)") from None
    except (TypeError, ValueError) as exc:
        raise InputError(f"--claims {claims}: a claim is not a number: {exc}") from None
    if args.save:  # checked before the calibration: never over a file without --force, never over the shipped sets
        check_new_file(Path(args.save), "--save", args.force)
    check_foreign_run(Path(args.out), "calibration.json", args.force)  # another command's results stay
    out = out_dir(args.out)
    with locked_out(out, "calibrate"):  # one command per --out at a time
        return _calibrate_locked(args, base, claims, targets, out)


def _calibrate_locked(args: argparse.Namespace, base: ParameterSet, claims: Path, targets: list[ClaimTarget],
                      out: Path) -> int:
    """Calibrate into ``out`` (its lock held): the saved set and calibration.json first, then the figure."""
    from workbench.fit import DEFAULT_FREE, calibrate

    (out / "calibration.json").unlink(missing_ok=True)  # written at the end: an earlier one must not outlive a failure

    def progress(i: int, cost: float) -> None:
        if not args.json:
            print(f"\r  evaluation {i:4d}   weighted cost {cost:12.6g}", end="", file=sys.stderr, flush=True)

    res = calibrate(base, targets, free=tuple(args.free) if args.free else DEFAULT_FREE, name=args.name,
                    min_damping_ratio=args.min_damping, on_iteration=progress)
    if not args.json:
        print(file=sys.stderr)
    rows = res.table()
    summary = {"parameter_set": base.name, "claims": str(claims), "free": list(res.free), "success": res.success,
               "message": res.message, "evaluations": len(res.history), "claims_table": rows,
               "damping_ratios_calibrated": list(res.final.damping_ratios),
               "parameters": {f: res.params.values[f] for f in res.free},
               "parameters_start": {f: base.values[f] for f in res.free}}
    if args.save:
        toml = res.params.to_toml()
        write_whole(Path(args.save), lambda tmp: tmp.write_text(toml), "--save", args.force)
        summary["saved"] = args.save
    # the numbers first (the saved set, calibration.json), then the figure: a plotting failure never loses them
    (out / "calibration.json").write_text(dump_json(summary))

    def figure() -> Path:
        from workbench.compare import calibration_figure

        return calibration_figure(out / "calibration.png", res.history, rows, base.name, args.name)

    deco = Decorations("calibrate", args)
    if deco.attempt("calibration.png", figure) is None:
        summary["failed"] = deco.failed
        (out / "calibration.json").write_text(dump_json(summary))
    if args.json:
        print(dump_json(summary))
        return 0 if res.success and deco.ok else 1
    print(f"{'claim':32s} {'paper':>12s} {base.name:>12s} {args.name:>12s} {'error':>8s}")
    for r in rows:
        print(f"{r['claim']:32s} {r['paper']:12.5g} {r['start']:12.5g} {r['calibrated']:12.5g} "
              f"{100 * r['rel_error_calibrated']:7.1f}%")
    print("damping ratios: " + ", ".join(f"{100 * z:.2f} %" for z in res.final.damping_ratios))
    for f in res.free:
        print(f"  {f:8s} {base.values[f]:12.5g} -> {res.params.values[f]:12.5g}")
    if args.save:
        print(f"saved {args.save}")
    print(f"wrote {out}/calibration.png and calibration.json")
    return 0 if res.success and deco.ok else 1
