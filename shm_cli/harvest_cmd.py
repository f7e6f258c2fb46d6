"""``shm harvest``: charge the ML2032 cell from base vibration (seed paper Sec. 3.3, Fig. 9) and audit the energy.

Writes to ``--out``: ``harvest_summary.json``, ``charge_curve.csv`` (Fig. 9 data), ``chunks.csv`` (per-interval
means), ``audit.csv``, ``charge_curve.png`` (and ``charge_rate.csv`` when the time to full is a projection).
The numbers (CSV, ``harvest_summary.json``) are written before the figure. Exit codes: 0 ok; 1 the run failed, in
coupled mode the energy books did not close within 1 %, or the figure could not be drawn (named in the message and
in the summary's ``failed``); 2 bad input.
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from board_config.errors import InputError
from shm_cli.command_args import add_command
from shm_cli.common import Decorations, add_out_arg, add_params_arg, dump_json, out_dir
from shm_cli.output_guard import add_force_arg, check_foreign_run, locked_out

#: the paper's claim, full recharge from 2 V within 10 minutes (= studies.harvest.PAPER_CLAIM_S; kept here so that
#: building the parser does not import the plant)
PAPER_CLAIM_S = 600.0


def register(sub: argparse._SubParsersAction) -> None:
    p = add_command(
        sub, "harvest", "energy harvesting: charge the ML2032 from base vibration, time to full, power audit",
        """Simulate the patches charging the board's cell under a sinusoidal base acceleration (seed paper Sec. 3.3,
        Eq. 6-10, Fig. 9). 'coupled' (default) solves the patch-bridge-cell circuit consistently, so charging damps
        the beam; 'paper' is Eq. 8 as written (the cell charges from the open-circuit |v_a|, the patches are not
        loaded). The power audit closes the energy books (coupled) or shows the energy Eq. 8 creates (paper).""")
    add_params_arg(p)
    p.add_argument("--coupling", choices=("coupled", "paper"), default="coupled",
                   help="coupled: energy-consistent circuit (default); paper: Eq. 8 as written")
    p.add_argument("--accel-g", type=float, default=0.1, help="base acceleration amplitude (g); default 0.1")
    p.add_argument("--freq-hz", type=float, default=5.8, help="excitation frequency (Hz); default 5.8")
    p.add_argument("--r-int-ohm", type=float, default=1.0, help="cell internal resistance R_bint (ohm); default 1")
    p.add_argument("--from-v", type=float, default=2.0,
                   help="start open-circuit voltage of the cell (V); default 2.0 (the paper's 'completely "
                        "discharged')")
    p.add_argument("--duration-s", type=float, default=PAPER_CLAIM_S,
                   help="simulated horizon (s); default 600 (the paper's 10 minutes). When the cell is not full "
                        "by then, the time to full is projected (and marked so)")
    p.add_argument("--diode-drop-v", type=float, default=0.0,
                   help="forward drop of one bridge diode (V); default 0 = ideal bridge")
    p.add_argument("--board-current-ma", type=float, default=0.0,
                   help="constant load current the board draws from the cell (mA); default 0")
    p.add_argument("--battery", default="ML2032", help="cell name in board_config/batteries.toml; default ML2032")
    p.add_argument("--eq8-literal", action="store_true",
                   help="paper coupling only: no blocking bridge, current flows back out of the cell whenever "
                        "|v_a| < v_b, as the bare Eq. 8 says")
    p.add_argument("--no-hysteresis", action="store_true",
                   help="leave the Bouc-Wen effect out (linear, passive piezo) to separate its work from the "
                        "harvest")
    p.add_argument("--no-projection", action="store_true", help="do not project the time to full")
    p.add_argument("--json", action="store_true", help="print the summary as JSON on stdout")
    add_out_arg(p)
    add_force_arg(p, "another command's finished run in --out (its report is rewritten)")
    p.set_defaults(func=cmd_harvest)


def _setup_from_args(args: argparse.Namespace):
    from plant import G0
    from studies.harvest import HarvestSetup

    if args.eq8_literal and args.coupling != "paper":
        raise InputError("--eq8-literal applies to --coupling paper only")
    for flag, value in (("--accel-g", args.accel_g), ("--freq-hz", args.freq_hz), ("--r-int-ohm", args.r_int_ohm),
                        ("--from-v", args.from_v), ("--duration-s", args.duration_s),
                        ("--diode-drop-v", args.diode_drop_v), ("--board-current-ma", args.board_current_ma)):
        if not math.isfinite(value):
            raise InputError(f"{flag} must be a finite number, got {value!r}")
    setup = HarvestSetup(
        params=args.params, coupling=args.coupling, accel=args.accel_g * G0, freq=args.freq_hz,
        r_int=args.r_int_ohm, v_start=args.from_v, v_diode=args.diode_drop_v,
        i_board=args.board_current_ma * 1e-3, battery=args.battery, duration=args.duration_s,
        eq8_reverse=args.eq8_literal, hysteresis=not args.no_hysteresis,
    )
    setup.validate()
    return setup


def cmd_harvest(args: argparse.Namespace) -> int:
    from board_config import load_parameter_set

    setup = _setup_from_args(args)
    load_parameter_set(args.params)  # a bad set fails here, before any output
    check_foreign_run(Path(args.out), "harvest_summary.json", args.force)  # another command's results stay
    out = out_dir(args.out)
    with locked_out(out, "harvest"):  # one command per --out at a time
        return _harvest_locked(args, setup, out)


def _harvest_locked(args: argparse.Namespace, setup: Any, out: Path) -> int:
    """Run the harvest into ``out`` (its lock held): the numbers first, then the figure; the exit code."""
    from studies.harvest import run_harvest

    (out / "harvest_summary.json").unlink(missing_ok=True)  # an earlier one must not outlive a failure
    bars: list[Any] = []  # created at the first report, once the model is built
    try:
        run = run_harvest(setup, progress=_progress_bar(setup, bars), project=not args.no_projection)
    except FloatingPointError as exc:
        print(f"shm: harvest failed: {exc}", file=sys.stderr)
        return 1
    finally:
        for bar in bars:
            bar.close()
    summary, deco = _write_results(args, run, out)
    if args.json:
        print(dump_json(summary))
    else:
        _print_summary(setup, run, summary, out)
    if setup.coupling == "coupled" and not run.audit.closes():
        print(f"shm: the coupled energy books do not close: residual {run.audit.relative_residual:+.3%} of sources",
              file=sys.stderr)
        return 1
    return 0 if deco.ok else 1


def _progress_bar(setup: Any, bars: list[Any]) -> Callable[[float, float, float], None]:
    """The harvest's progress callback: a tqdm bar on stderr (appended to ``bars`` at the first report), shown on a
    terminal or for a run of a simulated minute or more."""
    from tqdm import tqdm

    tty = sys.stderr.isatty()
    show = tty or setup.duration >= 60.0
    last = [0.0]

    def progress(t_done: float, t_total: float, soc: float) -> None:
        if not show:
            return
        if not bars:
            bars.append(tqdm(total=float(setup.duration), unit="s", file=sys.stderr, mininterval=0.2 if tty else 5.0,
                             desc=f"harvest {setup.coupling}",
                             bar_format="{l_bar}{bar}| {n:.0f}/{total:.0f} s sim [{elapsed}<{remaining}] {postfix}"))
        bars[0].update(t_done - last[0])
        last[0] = t_done
        bars[0].set_postfix_str(f"SoC {soc:.4f}", refresh=False)

    return progress


def _write_results(args: argparse.Namespace, run: Any, out: Path) -> tuple[dict[str, Any], Decorations]:
    """The numbers (CSV, harvest_summary.json), then the figure: a plotting failure never loses them."""
    from studies.harvest.figures import plot_charge_curve
    from studies.harvest.outputs import verdict, write_outputs

    files = write_outputs(run, out)
    summary = run.summary()
    summary["verdict"] = verdict(run)
    summary["files"] = files
    (out / "harvest_summary.json").write_text(dump_json(summary))
    deco = Decorations("harvest", args)
    plot = deco.attempt("charge_curve.png", lambda: plot_charge_curve(run, out / "charge_curve.png"))
    if plot is not None:
        files["plot"] = str(plot)
    else:
        summary["failed"] = deco.failed
    (out / "harvest_summary.json").write_text(dump_json(summary))
    return summary, deco


def _print_summary(setup: Any, run: Any, summary: dict[str, Any], out: Path) -> None:
    """The text report on stdout: the run, the cell, the verdict, what a full recharge would take, the audit."""
    from studies.harvest.outputs import format_duration, verdict

    print(f"parameter set {summary['parameter_set']}, coupling {setup.coupling} "
          f"({setup.terminal()}), cell {run.battery.spec.name}")
    print(f"simulated {run.t_end:.1f} s in {run.wall_s:.1f} s wall ({run.n_steps} steps)")
    print(f"cell: {run.v_bat[0]:.4f} V -> {run.v_bat[-1]:.4f} V, SoC {run.soc[0]:.4f} -> {run.soc[-1]:.4f}, "
          f"charge gained {run.q_d_start - run.q_d_end:.4g} C")
    print(f"patch terminal voltage peak {summary['stored_voltage_peak_V']:.4g} V "
          f"({summary['stored_gain_V_per_g']:.4g} V/g), tip peak {summary['tip_peak_m'] * 1e3:.3g} mm")
    print(verdict(run))
    if run.q_below_cutoff > 0:
        print(f"WARNING: {run.q_below_cutoff:.4g} C drawn below the cut-off voltage")
    w = summary["what_it_would_take"]
    print(f"\nwhat a full recharge within {w['target_s']:g} s would take: {w['energy_to_full_J']:.4g} J into the "
          f"cell = {w['required_mean_cell_power_W']:.3g} W on average; this run's base power in is "
          f"{w['measured_mean_base_power_W']:.3g} W ({w['required_over_base_power']:.3g} x short)")
    eff = w["harvest_efficiency_cell_over_base"]
    at_eff = ("" if math.isnan(eff) else
              f"; at this run's efficiency ({eff:.3g}): {w['accel_for_required_power_g']:.3g} g")
    print(f"  even harvesting all the base power: {w['accel_if_all_base_power_harvested_g']:.3g} g at "
          f"{setup.freq:g} Hz{at_eff}")
    print(f"  Eq. 8 (unloaded patches) needs an open-circuit amplitude of {w['eq8_required_amplitude_V']:.4g} V "
          f"({w['eq8_required_gain_V_per_g']:.4g} V/g; this run: {w['measured_gain_V_per_g']:.3g} V/g); with the "
          f"paper's {w['paper_gain_V_per_g']:g} V/g it takes {format_duration(w['eq8_time_at_paper_gain_s'])}")
    print()
    print(run.audit.table())
    if setup.coupling == "paper" and run.audit.energy_from_nowhere_J > 0:
        src = max(run.audit.row("base excitation power in (relative frame)").energy_J, 1e-300)
        print(f"\nEq. 8 took {run.audit.energy_from_nowhere_J:.4g} J from patches that never delivered it "
              f"({run.audit.energy_from_nowhere_J / src:.3g} x the base energy in)")
    print(f"\nresults in {out}/")


__all__ = ["cmd_harvest", "register"]
