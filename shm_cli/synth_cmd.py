"""``shm synth``: write a synthetic measurement record from a truth plant (parameter set + injected effects)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from board_config.assignments import parse_assignments
from board_config.errors import InputError
from shm_cli.command_args import add_command
from shm_cli.common import (
    add_params_arg,
    check_memory,
    dump_json,
    finite_float,
    number_in_range,
    output_file_arg,
    positive_float,
    seed_int,
)
from shm_cli.output_guard import add_force_arg, check_new_file, write_whole

#: test frequencies synth accepts (Hz): up to Table 1's operational limit of the MFC (10 kHz)
FREQUENCY_HZ = number_in_range(1e-3, 1e4, unit="Hz (Table 1: the MFC operates from DC to 10 kHz)")
#: memory per record sample kept while simulating (the plant's states and outputs, the written columns), bytes
BYTES_PER_SAMPLE = 400

TESTS = ("mbit-a", "mbit-b", "step", "sine", "sweep", "frf")


def register(sub: argparse._SubParsersAction) -> None:
    p = add_command(
        sub, "synth", "write a synthetic record (CSV/TDMS) from a truth plant with injected effects and noise",
        """Simulate a test on a truth plant — the parameter set with parameter deviations and injected physical
        effects (the hardware-in-the-loop stub's seam) — and write the record a rig would log, in the documented
        format (docs/records.md). Output .csv (time record or, for --test frf, a frequency-response table) or .tdms.""")
    p.add_argument("--test", required=True, choices=TESTS, help="test to simulate")
    add_params_arg(p)
    p.add_argument("--effect", action="append", default=[], metavar="NAME|pkg.mod:Class",
                   help="inject a physical effect into the truth plant (registered name, dotted path or "
                        "FILE.py[:Class]); repeatable")
    p.add_argument("--set", action="append", default=[], metavar="NAME=VALUE", dest="set_values",
                   help="absolute value of a truth parameter (core or an injected effect's), SI; repeatable")
    p.add_argument("--deviation", action="append", default=[], metavar="NAME=REL",
                   help="relative deviation of a core parameter (k3=-0.3: k3 × 0.7); repeatable")
    p.add_argument("--noise", action="append", default=[], metavar="CH=SIGMA|none",
                   help="white sensor noise σ in SI (z3=2e-6 m, v_stored=5e-3 V; inputs v_ch1, v_ch2, z0dd too); "
                        "'none' for a noiseless record. Default: z 2 µm, v_stored 5 mV. For --test frf: "
                        "amp=REL and phase=DEG (default 0.01 and 0.5)")
    p.add_argument("--seed", type=seed_int, default=0, help="noise seed, 0 .. 2^32-1 (default 0)")
    p.add_argument("--channels", default=None, metavar="CH,CH",
                   help="measured channels (default: z3 for a voltage drive; v_stored,z3 for a base drive)")
    p.add_argument("--drive", choices=("voltage", "base"), default="voltage",
                   help="voltage on the patches (actuation) or base acceleration (harvesting, open circuit)")
    p.add_argument("--amplitude", type=positive_float, default=None,
                   help="drive amplitude: V (differential) for voltage, g for base (default per test)")
    p.add_argument("--freq-hz", type=FREQUENCY_HZ, default=None, help="sine frequency (Hz)")
    p.add_argument("--f0-hz", type=FREQUENCY_HZ, default=None, help="sweep / FRF start frequency (Hz)")
    p.add_argument("--f1-hz", type=FREQUENCY_HZ, default=None, help="sweep / FRF end frequency (Hz)")
    p.add_argument("--n-freqs", type=number_in_range(2, 100_000, integer=True), default=None,
                   help="FRF: number of frequencies (log-spaced)")
    p.add_argument("--duration-s", type=positive_float, default=None, help="record length (s)")
    p.add_argument("--rate-hz", type=positive_float, default=None, help="logger sample rate (Hz, default 1000)")
    p.add_argument("--bias-v", type=finite_float, default=None, help="common-mode voltage on both channels (V)")
    p.add_argument("--operating-hours", type=float, default=None, metavar="H",
                   help="stamp the record with the structure's operating time (h, header key operating_hours; "
                        "shm health trends on it)")
    p.add_argument("--blind", action="store_true",
                   help="leave the truth (effects, parameter values) out of the record's provenance")
    p.add_argument("--json", action="store_true", help="print a summary of the written record as JSON")
    p.add_argument("--out", required=True, metavar="FILE", type=output_file_arg, help="output file (.csv or .tdms)")
    add_force_arg(p, "the --out file")
    p.set_defaults(func=cmd_synth)


def _assignments(flag: str, items: list[str]) -> dict[str, float]:
    """``NAME=VALUE`` items, one assignment per item (board_config.assignments)."""
    return parse_assignments(flag, items, comma_lists=False)


#: largest base-acceleration amplitude synth accepts (g): far beyond any flight or test load of the laminate
MAX_BASE_G = 100.0


def _check_drive_limits(args: argparse.Namespace, spec, base: bool) -> None:
    """A voltage drive must keep both channels inside the MFC's demand range (paper Table 1: −500 … 1500 V):
    each channel swings bias ± amplitude. A base drive is limited to MAX_BASE_G."""
    from board_config import load_mfc_limits
    from plant import G0

    if base:
        if spec.amplitude > MAX_BASE_G * G0:
            raise InputError(f"--amplitude {args.amplitude:g} g: a base acceleration above {MAX_BASE_G:g} g is "
                             "outside what the model is meant for")
        return
    lim = load_mfc_limits()
    lo, hi = spec.bias_v - abs(spec.amplitude), spec.bias_v + abs(spec.amplitude)
    if lo < lim.voltage_min - 1e-9 or hi > lim.voltage_max + 1e-9:
        raise InputError(f"--amplitude {spec.amplitude:g} V with common mode (--bias-v) {spec.bias_v:g} V drives the "
                         f"channels over {lo:g} … {hi:g} V, outside the MFC demand range {lim.voltage_min:g} … "
                         f"{lim.voltage_max:g} V (paper Table 1): each channel swings bias ± amplitude")


def cmd_synth(args: argparse.Namespace) -> int:
    from board_config import CORE_PARAMETER_NAMES, CORE_PARAMETERS, ParameterVector, load_parameter_set
    from plant import G0
    from workbench.fit import probe_effects
    from workbench.records import write_record
    from workbench.simulation import synth_frf, synth_record, synth_test, truth_model, write_frf_record

    out = Path(args.out)
    if out.suffix.lower() not in (".csv", ".tdms"):
        raise InputError(f"--out {out}: expected a .csv or .tdms file name")
    if args.test == "frf" and out.suffix.lower() != ".csv":
        raise InputError("--test frf writes a frequency-response table: use a .csv file name")
    check_new_file(out, "--out", args.force)  # before the simulation; the write itself checks again
    pset = load_parameter_set(args.params)
    values = _assignments("--set", args.set_values)
    deviations = _assignments("--deviation", args.deviation)
    if deviations:  # on top of --set values; validated (names, range, bounds) by the one with_deviations
        base = ParameterVector.of(CORE_PARAMETERS, (values.get(n, pset.values[n]) for n in CORE_PARAMETER_NAMES))
        deviated = base.with_deviations(deviations, "--deviation")
        values.update({name: deviated[name] for name in deviations})
    base = args.drive == "base"
    amplitude = None if args.amplitude is None else args.amplitude * (G0 if base else 1.0)
    spec = synth_test(args.test, drive=args.drive, amplitude=amplitude, freq_hz=args.freq_hz, f0_hz=args.f0_hz,
                     f1_hz=args.f1_hz, duration_s=args.duration_s, rate_hz=args.rate_hz, bias_v=args.bias_v,
                     n_freqs=args.n_freqs)
    _check_drive_limits(args, spec, base)
    if args.test != "frf":
        n = spec.duration_s * spec.rate_hz
        check_memory(f"a {spec.duration_s:g} s record at {spec.rate_hz:g} Hz ({n:.3g} samples)",
                     n * BYTES_PER_SAMPLE, hint="shorten --duration-s or lower --rate-hz")
    channels = (args.channels.split(",") if args.channels else (["v_stored", "z3"] if base else ["z3"]))
    channels = [c.strip() for c in channels if c.strip()]
    _check_set_names(values, args.effect, CORE_PARAMETER_NAMES)
    probe_effects(args.effect, pset, "--effect")
    model = truth_model(pset, effects=args.effect, values=values, terminal="open_circuit" if base else "amplifier")
    _warn_neutral(model)
    out.parent.mkdir(parents=True, exist_ok=True)
    if args.test == "frf":
        nz = _frf_noise(args.noise)
        rec = synth_frf(spec, model, channels, noise_rel=nz["amp"], noise_phase_deg=nz["phase"], seed=args.seed,
                        effects=args.effect, values=values, blind=args.blind)
        if args.operating_hours is not None:
            rec = _stamp_hours(rec, args.operating_hours)
        write_whole(out, lambda tmp: write_frf_record(rec, tmp), "--out", args.force)
        path = out
        summary = {"file": str(path), "test": "frf", "frequencies": int(rec.frequency_Hz.size),
                   "channels": list(rec.responses), "drive": rec.drive}
    else:
        noise: dict[str, float] | None = None
        if args.noise:
            noise = {}
            for item in args.noise:
                if item != "none":
                    noise.update(_assignments("--noise", [item]))
        trec = synth_record(spec, model, channels, noise=noise, seed=args.seed, effects=args.effect, values=values,
                            blind=args.blind)
        if args.operating_hours is not None:
            trec = _stamp_hours(trec, args.operating_hours)
        write_whole(out, lambda tmp: write_record(trec, tmp), "--out", args.force)
        path = out
        summary = {"file": str(path), "test": trec.test, "samples": trec.n_samples, "duration_s": trec.duration_s,
                   "sample_rate_Hz": trec.sample_rate_Hz, "inputs": list(trec.inputs), "outputs": list(trec.outputs)}
    if args.operating_hours is not None:
        summary["operating_hours"] = float(args.operating_hours)
    summary["truth"] = "hidden" if args.blind else {"params": pset.name, "effects": args.effect, "values": values}
    if args.json:
        print(dump_json(summary))
    else:
        print(f"wrote {path} ({args.test}, truth: {pset.name}"
              + (f" + {', '.join(args.effect)}" if args.effect and not args.blind else "")
              + (" [blind]" if args.blind else "") + ")", file=sys.stderr)
    return 0


def _frf_noise(items: list[str]) -> dict[str, float]:
    """--noise for --test frf: amp=REL and phase=DEG (default 0.01 and 0.5; 'none': both 0)."""
    nz = {"amp": 0.01, "phase": 0.5}
    for item in items:
        if item == "none":
            nz = {"amp": 0.0, "phase": 0.0}
        else:
            nz.update(_assignments("--noise", [item]))
    unknown = set(nz) - {"amp", "phase"}
    if unknown:
        raise InputError(f"--noise for --test frf takes amp=REL and phase=DEG, got {sorted(unknown)}")
    return nz


def _warn_neutral(model) -> None:
    """Say on stderr when an injected effect sits at its neutral values: the record is then the nominal plant's
    while its header names the effect (the header also carries the values and ``truth_neutral_effects``)."""
    from workbench.simulation import neutral_effects

    units = dict(zip(model.param_names, model.param_units))
    for name, at in neutral_effects(model).items():
        vals = ", ".join(f"{k} = {v:g} {units.get(k, '')}".rstrip() for k, v in at.items())
        print(f"shm synth: warning: --effect {name} is at its neutral value ({vals}): the record equals the nominal "
              f"plant's; give it a strength with --set {next(iter(at))}=VALUE (`shm effects show {name}` lists its "
              "parameters and ranges)", file=sys.stderr)


def _check_set_names(values: dict[str, float], effects: list[str], core: tuple[str, ...]) -> None:
    """An unknown ``--set`` name is the command line's fault: say so, with the names that exist."""
    from plant import resolve_effect

    own: dict[str, str] = {}
    for spec in effects:
        cls = resolve_effect(spec)
        for par in cls.own_parameters():
            own[par.name] = cls.name
    for name in values:
        if name not in core and name not in own:
            known = (f"parameters of the injected effects: {', '.join(sorted(own))}" if own else
                     "no effect is injected (--effect NAME adds one)")
            raise InputError(f"--set {name}: no such parameter on the command line's truth plant (core parameters: "
                             f"{', '.join(core)}; {known})")


def _stamp_hours(rec, hours: float):
    """The record with the ``operating_hours`` header key (h >= 0; docs/records.md)."""
    import dataclasses
    import math

    if not (math.isfinite(hours) and hours >= 0):
        raise InputError(f"--operating-hours must be a number of hours >= 0, got {hours!r}")
    return dataclasses.replace(rec, meta={**rec.meta, "operating_hours": float(hours)})
