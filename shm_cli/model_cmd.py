"""``shm model info|frf|step|loop``: the plant's modes, frequency responses and validation time responses."""

from __future__ import annotations

import argparse
import contextlib
import sys
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np

from board_config.errors import InputError
from board_config.physical_constants import G0
from shm_cli.command_args import add_command_group
from shm_cli.common import (
    add_out_arg,
    add_params_arg,
    check_memory,
    dump_json,
    number_in_range,
    out_dir,
    positive_float,
    write_csv,
)
from shm_cli.output_guard import add_force_arg, check_foreign_run, locked_out

#: largest differential amplitude the patches can be driven at within Table 1's -500 ... 1500 V per channel (the
#: channels at common mode 500 V +- 1000 V); the model commands drive v_ch1 = +A, v_ch2 = -A
MAX_DIFFERENTIAL_V = 1000.0
DIFFERENTIAL_AMPLITUDE = number_in_range(-MAX_DIFFERENTIAL_V, MAX_DIFFERENTIAL_V, unit="V (Table 1: -500 ... 1500 V "
                                         "per channel, so at most 1000 V differential)")
#: memory per simulated sample kept by the model commands (states, outputs), bytes
BYTES_PER_SAMPLE = 400


def register(sub: argparse._SubParsersAction) -> None:
    msub = add_command_group(
        sub, "model", "plant model: modes, frequency responses, step and hysteresis-loop responses",
        "Inspect the plant model of a parameter set.")
    pi = msub.add_parser("info", help="modes, damping, RC pole, static gain, harvesting gains")
    add_params_arg(pi)
    pi.add_argument("--json", action="store_true", help="print the summary as JSON")
    pi.set_defaults(func=cmd_info)

    pf = msub.add_parser("frf", help="frequency responses: z3/v_a (Fig. 6a) and stored voltage/z0dd (Fig. 6b)")
    add_params_arg(pf)
    pf.add_argument("--f-min-hz", type=positive_float, default=0.1)
    pf.add_argument("--f-max-hz", type=positive_float, default=200.0)
    pf.add_argument("--points", type=number_in_range(2, 10_000_000, integer=True), default=2000)
    _add_out_args(pf, cmd_frf)

    ps = _time_response_parser(msub, "step", "nonlinear step response (Fig. 7b)", 300.0, "step")
    ps.add_argument("--duration-s", type=positive_float, default=2.0)
    _add_out_args(ps, cmd_step)

    pl = _time_response_parser(msub, "loop", "quasi-static hysteresis loop (Fig. 7a)", 600.0, "sine")
    pl.add_argument("--freq-hz", type=positive_float, default=0.01)
    pl.add_argument("--cycles", type=positive_float, default=1.25)
    _add_out_args(pl, cmd_loop)


def _time_response_parser(msub: argparse._SubParsersAction, name: str, summary: str, amplitude_v: float,
                          drive: str) -> argparse.ArgumentParser:
    """A time-response sub-command (step, loop): its parameter set and differential drive amplitude (V)."""
    p: argparse.ArgumentParser = msub.add_parser(name, help=summary)
    add_params_arg(p)
    p.add_argument("--amplitude-v", type=DIFFERENTIAL_AMPLITUDE, default=amplitude_v,
                   help=f"differential {drive} amplitude (V, |A| <= {MAX_DIFFERENTIAL_V:g})")
    return p


def _add_out_args(p: argparse.ArgumentParser, func: Callable[[argparse.Namespace], int]) -> None:
    """``--out`` and ``--force`` of a sub-command that writes files, and its handler."""
    add_out_arg(p)
    add_force_arg(p, "another command's finished run in --out (its report is rewritten)")
    p.set_defaults(func=func)


@contextlib.contextmanager
def _model_out(args: argparse.Namespace) -> Iterator[Path]:
    """The ``--out`` folder, created and locked while the block writes into it (one command per folder at a time);
    a folder holding another command's finished run is refused without ``--force`` (exit 2, nothing written)."""
    check_foreign_run(Path(args.out), "", args.force)
    out = out_dir(args.out)
    with locked_out(out, "model"):
        yield out


def model_summary(params: str) -> dict:
    """Everything ``shm model info`` reports, as a dict (SI units in the key names)."""
    from plant import PlantModel
    from plant.linear import (
        harvest_gain_v_per_g,
        linearise,
        modal_summary,
        peak_near,
        static_tip_gain,
        static_tip_gain_closed_form,
    )

    model = PlantModel(params)
    lin = linearise(model)
    modal = modal_summary(lin)
    lin_oc = linearise(PlantModel(model.params, terminal="open_circuit"))
    f = np.logspace(-1, np.log10(300.0), 3000)
    gain = np.abs(lin_oc.frf(f, "v_stored", "z0dd")) * G0
    peaks = []
    for mode in modal.modes:
        fp, gp = peak_near(f, gain, mode["frequency_Hz"], 0.15)
        peaks.append({"mode_frequency_Hz": mode["frequency_Hz"], "peak_frequency_Hz": fp, "gain_V_per_g": gp})
    r, c = model.param_value("R_ep"), model.param_value("C_ep")
    return {
        "parameter_set": model.params.name,
        "source": model.params.source,
        "effects": list(model.effect_names),
        "modes": modal.modes,
        "real_poles": modal.real_poles,
        "pure_integrators": modal.integrators,
        "rc_pole_closed_form_Hz": 1.0 / (2 * np.pi * r * c),
        "static_tip_gain_m_per_V": static_tip_gain(lin),
        "static_tip_gain_closed_form_m_per_V": static_tip_gain_closed_form(model),
        "static_tip_deflection_at_600V_m": 600.0 * static_tip_gain(lin),
        "harvest_gain_at_5_8Hz_V_per_g": harvest_gain_v_per_g(lin_oc, 5.8),
        "harvest_gain_at_37Hz_V_per_g": harvest_gain_v_per_g(lin_oc, 37.0),
        "harvest_gain_peaks": peaks,
    }


def cmd_info(args: argparse.Namespace) -> int:
    if not args.json:  # the first line at once: the model may take a while (a first use compiles it, announced)
        from board_config import load_parameter_set

        params = load_parameter_set(args.params)
        print(f"parameter set: {params.name}  ({params.source})", flush=True)
    s = model_summary(args.params)
    if args.json:
        print(dump_json(s))
        return 0
    print(f"effects: {', '.join(s['effects'])}")
    print("bending modes:")
    for i, m in enumerate(s["modes"], 1):
        print(f"  mode {i}: {m['frequency_Hz']:8.3f} Hz   damping ratio {100 * m['damping_ratio']:5.2f} %")
    print("real poles:")
    for rp in s["real_poles"]:
        print(f"  {rp['frequency_Hz']:8.3f} Hz   (time constant {1e3 * rp['time_constant_s']:.2f} ms)")
    print(f"  R_ep*C_ep closed form: {s['rc_pole_closed_form_Hz']:.3f} Hz")
    print(f"pure integrators (Bouc-Wen remanence states): {s['pure_integrators']}")
    print(f"static tip gain z3/v_a: {1e6 * s['static_tip_gain_m_per_V']:.4f} um/V "
          f"(closed form {1e6 * s['static_tip_gain_closed_form_m_per_V']:.4f} um/V); "
          f"at 600 V: {1e3 * s['static_tip_deflection_at_600V_m']:.3f} mm")
    print(f"harvesting (open circuit) gain: {s['harvest_gain_at_5_8Hz_V_per_g']:.4g} V/g at 5.8 Hz, "
          f"{s['harvest_gain_at_37Hz_V_per_g']:.4g} V/g at 37 Hz")
    for pk in s["harvest_gain_peaks"]:
        print(f"  peak {pk['gain_V_per_g']:.4g} V/g at {pk['peak_frequency_Hz']:.2f} Hz")
    return 0


def cmd_frf(args: argparse.Namespace) -> int:
    from plant import PlantModel
    from plant.linear import linearise

    if not (0 < args.f_min_hz < args.f_max_hz):
        raise InputError(f"need 0 < --f-min-hz < --f-max-hz, got {args.f_min_hz} and {args.f_max_hz}")
    if args.points < 2:
        raise InputError(f"--points must be at least 2, got {args.points}")
    check_memory(f"--points {args.points}", args.points * 128.0, hint="use fewer --points")
    with _model_out(args) as out:
        model = PlantModel(args.params)
        lin = linearise(model)
        lin_oc = linearise(PlantModel(model.params, terminal="open_circuit"))
        f = np.logspace(np.log10(args.f_min_hz), np.log10(args.f_max_hz), args.points)
        h_z = lin.frf(f, "z3", "va")
        h_v = lin_oc.frf(f, "v_stored", "z0dd") * G0
        write_csv(out / "frf_z3_per_va.csv", {"frequency_Hz": f, "amplitude_m_per_V": np.abs(h_z),
                                              "phase_deg": np.degrees(np.unwrap(np.angle(h_z)))})
        write_csv(out / "frf_vstored_per_accel.csv", {"frequency_Hz": f, "amplitude_V_per_g": np.abs(h_v),
                                                      "phase_deg": np.degrees(np.unwrap(np.angle(h_v)))})
        from workbench.compare import FRF_FIGURES, bode_figure

        for name, h in (("frf_z3_per_va", h_z * 1e6), ("frf_vstored_per_accel", h_v)):
            ylabel, title = FRF_FIGURES[name]
            bode_figure(out / f"{name}.png", f, h, ylabel, f"{title} — {model.params.name}")
        print(f"wrote {out}/frf_z3_per_va.(csv|png) and {out}/frf_vstored_per_accel.(csv|png)")
    return 0


def _plot_time(out: Path, name: str, resp, xy_loop: bool, title: str) -> None:
    from workbench.compare import time_response_figure

    time_response_figure(out / f"{name}.png", resp, xy_loop, title)


def cmd_step(args: argparse.Namespace) -> int:
    from plant import PlantModel
    from plant.responses import step_response

    if args.duration_s <= 0.1:
        raise InputError(f"--duration-s must be above 0.1 s (the step is applied at 0.1 s), got {args.duration_s}")
    check_memory(f"--duration-s {args.duration_s:g} ({args.duration_s / 1e-3:.3g} output samples)",
                 args.duration_s / 1e-3 * BYTES_PER_SAMPLE, hint="use a shorter --duration-s")
    with _model_out(args) as out:
        model = PlantModel(args.params)
        resp = step_response(model, args.amplitude_v, args.duration_s)
        write_csv(out / "step.csv", resp.columns())
        _plot_time(out, "step", resp, False, f"Step response, {resp.label} — {model.params.name} (cf. Fig. 7b)")
        print(f"final z3 {resp.z3[-1] * 1e3:.4f} mm; wrote {out}/step.csv and step.png", file=sys.stdout)
    return 0


def cmd_loop(args: argparse.Namespace) -> int:
    from plant import PlantModel
    from plant.responses import hysteresis_loop

    if args.freq_hz <= 0 or args.cycles <= 0:
        raise InputError(f"--freq-hz and --cycles must be positive, got {args.freq_hz} and {args.cycles}")
    n = args.cycles / args.freq_hz / min(1e-2, 1.0 / (args.freq_hz * 2000))
    check_memory(f"--cycles {args.cycles:g} at --freq-hz {args.freq_hz:g} ({n:.3g} input samples)",
                 n * BYTES_PER_SAMPLE, hint="use fewer --cycles")
    with _model_out(args) as out:
        model = PlantModel(args.params)
        resp = hysteresis_loop(model, args.amplitude_v, args.freq_hz, args.cycles)
        write_csv(out / "loop.csv", resp.columns())
        _plot_time(out, "loop", resp, True, f"Hysteresis loop, {resp.label} — {model.params.name} (cf. Fig. 7a)")
        print(f"z3 range {resp.z3.min() * 1e3:.4f} .. {resp.z3.max() * 1e3:.4f} mm; wrote {out}/loop.csv and loop.png")
    return 0
