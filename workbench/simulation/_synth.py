"""Synthetic records from a *truth* plant, for tests, demos and hidden-effect challenges.

The truth plant is the parameter set plus injected physical effects (registered names or dotted paths
``package.module:ClassName``) and parameter deviations — the same effect seam the hardware-in-the-loop stub uses
(:class:`plant.PlantModel` ``effects=`` / ``effect_params=``). The record is what a rig would log: the commanded
channel voltages (or base acceleration) and sensor readings with white Gaussian noise; the tip laser channel is
the truth's ``z3_meas`` (the sensor's view). Tests:

=========  ====================================================================================================
mbit-a     MBIT.a as the board runs it (``board_config`` ``mbit.toml``: 0.1 Hz, 600 V, 20 s, +100 V common mode)
mbit-b     MBIT.b as the board runs it (``mbit.toml``: 300 V step at 0.5 s, 10 ms rise, 3 s)
step       up-and-down voltage step (default 300 V, up at 0.5 s, down at mid-record), 8 s
sine       sine drive (default 300 V at 2 Hz, 10 s) or, with ``drive="base"``, a base acceleration (0.1 g, 5.8 Hz)
sweep      logarithmic chirp (default 0.5 → 50 Hz, 300 V or 0.05 g, 30 s)
frf        stepped-sine frequency-response table (default 30 frequencies 0.5 → 50 Hz, 600 V or 0.1 g)
=========  ====================================================================================================

Each time record carries its test regimes as ``segments`` (charging/discharging quarter cycles for sines,
before/transient/settled for steps, frequency bands for sweeps).
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from board_config import CORE_PARAMETER_NAMES, load_mbit, load_parameter_set
from board_config.errors import InputError
from plant import G0, InputSignals, PhysicalEffect, PlantModel
from plant.layout import N_INPUTS, U_V_CH1, U_V_CH2, U_Z0DD
from workbench.records import FrfChannel, FrfRecord, Record, record_from_arrays
from workbench.simulation._frequency_response import stepped_sine

TEST_KINDS = ("mbit-a", "mbit-b", "step", "sine", "sweep", "frf")
#: default white-noise standard deviations by channel (SI): laser triangulation ~2 µm, voltmeter 5 mV
DEFAULT_NOISE: dict[str, float] = {"z1": 2e-6, "z2": 2e-6, "z3": 2e-6, "v_stored": 5e-3}
#: SI unit of the channels synth can write (column name = f"{name}_{unit token}")
_COLUMN_UNITS = {"z": "m", "delta": "m", "q": "C", "qh": "C", "v_patch": "V", "v_stored": "V"}


@dataclass(frozen=True)
class SynthTest:
    """A test's waveform. Amplitudes in SI: V for a voltage drive (differential), m/s^2 for a base drive."""

    kind: str
    drive: str = "voltage"  # "voltage" | "base"
    amplitude: float = 300.0
    freq_hz: float = 2.0
    f0_hz: float = 0.5
    f1_hz: float = 50.0
    duration_s: float = 10.0
    bias_v: float = 100.0
    t_step_s: float = 0.5
    rate_hz: float = 1000.0
    n_freqs: int = 30
    rise_s: float = 1e-3  # step rise (amplifier slew / command ramp)
    polarity: tuple[int, int] = (1, -1)  # channel signs following the differential drive


def synth_test(kind: str, **overrides: Any) -> SynthTest:
    """The default waveform of a test kind, with overrides (``None`` values are ignored)."""
    if kind not in TEST_KINDS:
        raise InputError(f"unknown test '{kind}' (tests: {', '.join(TEST_KINDS)})")
    over = {k: v for k, v in overrides.items() if v is not None}
    drive = over.get("drive", "voltage")
    if drive not in ("voltage", "base"):
        raise InputError(f"drive must be 'voltage' or 'base', got {drive!r}")
    if kind in ("mbit-a", "mbit-b", "step") and drive != "voltage":
        raise InputError(f"test '{kind}' drives the patches; drive='base' applies to sine, sweep and frf")
    base = drive == "base"
    ma, mb = load_mbit("a"), load_mbit("b")
    defaults: dict[str, dict[str, Any]] = {
        "mbit-a": {"amplitude": ma.amplitude, "freq_hz": ma.frequency, "duration_s": ma.duration,
                   "bias_v": ma.common_mode, "polarity": ma.channel_polarity},
        "mbit-b": {"amplitude": mb.amplitude, "duration_s": mb.duration, "t_step_s": mb.t_start,
                   "rise_s": mb.rise_time, "bias_v": mb.common_mode, "polarity": mb.channel_polarity},
        "step": {"amplitude": 300.0, "duration_s": 8.0},
        "sine": {"amplitude": 0.1 * G0 if base else 300.0, "freq_hz": 5.8 if base else 2.0, "duration_s": 10.0},
        "sweep": {"amplitude": 0.05 * G0 if base else 300.0, "duration_s": 30.0},
        "frf": {"amplitude": 0.1 * G0 if base else 600.0, "duration_s": 0.0},
    }
    spec = SynthTest(kind, **{**defaults[kind], **over})
    for name in ("amplitude", "freq_hz", "f0_hz", "f1_hz", "duration_s", "rate_hz"):
        v = getattr(spec, name)
        if not np.isfinite(v) or (v <= 0 and not (name == "duration_s" and kind == "frf")):
            raise InputError(f"{name} must be positive and finite, got {v!r}")
    if spec.f1_hz <= spec.f0_hz:
        raise InputError(f"sweep end f1_hz ({spec.f1_hz}) must be above f0_hz ({spec.f0_hz})")
    if spec.n_freqs < 2:
        raise InputError(f"n_freqs must be at least 2, got {spec.n_freqs}")
    if kind in ("mbit-b", "step") and not 0 <= spec.t_step_s < spec.duration_s:
        raise InputError(f"t_step_s ({spec.t_step_s}) must lie inside the record (0 .. {spec.duration_s} s)")
    if kind == "sweep" and spec.rate_hz < 10 * spec.f1_hz:
        raise InputError(f"rate_hz ({spec.rate_hz}) must be at least 10 × the sweep's end frequency ({spec.f1_hz})")
    return spec


def _quarter_segments(t: np.ndarray, freq: float, label_rise: str, label_fall: str) -> list[dict[str, Any]]:
    """Quarter cycles of sin(2π f t): |v| rising ('charging') then falling ('discharging')."""
    q = 0.25 / freq
    segs = []
    k = 0
    while k * q < t[-1] - 1e-12:
        a, b = k * q, min((k + 1) * q, float(t[-1]))
        segs.append({"start_s": float(a), "end_s": float(b), "label": label_rise if k % 2 == 0 else label_fall})
        k += 1
    return segs


def settle_time_s(model: PlantModel) -> float:
    """Four time constants of the slowest decaying linear mode at rest (s), clipped to [0.1, 5] s."""
    from workbench.simulation._replay import linearise

    a, _ = linearise(model, ["z3"])
    if not np.all(np.isfinite(a)):  # a model producing NaN: the simulation that follows names the culprit
        return 1.0
    ev = np.linalg.eigvals(a)
    dec = -ev.real[(ev.real < -1e-6)]
    osc = dec[np.abs(ev.imag[(ev.real < -1e-6)]) > 1e-6]
    slow = float(np.min(osc)) if osc.size else (float(np.min(dec)) if dec.size else 1.0)
    return float(np.clip(4.0 / slow, 0.1, 5.0))


def synth_inputs(spec: SynthTest, settle_s: float = 1.0) -> tuple[np.ndarray, np.ndarray, list[dict[str, Any]]]:
    """``(t, u, segments)``: times (s), inputs ``(samples, 3)`` [v_ch1 V, v_ch2 V, z0dd m/s^2], regimes."""
    dt = 1.0 / spec.rate_hz
    t = dt * np.arange(round(spec.duration_s * spec.rate_hz) + 1)
    u = np.zeros((t.size, N_INPUTS))
    segs: list[dict[str, Any]] = []
    base = spec.drive == "base"
    if spec.kind in ("mbit-a", "sine"):
        s = spec.amplitude * np.sin(2 * np.pi * spec.freq_hz * t)
        segs = _quarter_segments(t, spec.freq_hz, "charging (|drive| rising)", "discharging (|drive| falling)")
        if base:
            u[:, U_Z0DD] = s
    elif spec.kind in ("mbit-b", "step"):
        rise = max(spec.rise_s, 1.0 / spec.rate_hz)
        ts = spec.t_step_s
        s = spec.amplitude * np.clip((t - ts) / rise, 0, 1)
        segs = [{"start_s": 0.0, "end_s": ts, "label": "before step"}] if ts > 0 else []
        t_down = 0.5 * (ts + t[-1]) if spec.kind == "step" else None
        end_up = t_down if t_down is not None else float(t[-1])
        segs.append({"start_s": ts, "end_s": min(ts + settle_s, end_up), "label": "transient (step up)"})
        if ts + settle_s < end_up:
            segs.append({"start_s": ts + settle_s, "end_s": end_up, "label": "settled (high)"})
        if t_down is not None:
            s = s - spec.amplitude * np.clip((t - t_down) / rise, 0, 1)
            segs.append({"start_s": t_down, "end_s": min(t_down + settle_s, float(t[-1])),
                         "label": "transient (step down)"})
            if t_down + settle_s < t[-1]:
                segs.append({"start_s": t_down + settle_s, "end_s": float(t[-1]), "label": "settled (low)"})
    elif spec.kind == "sweep":
        f0, f1, dur = spec.f0_hz, spec.f1_hz, spec.duration_s
        ln = np.log(f1 / f0)
        phase = 2 * np.pi * f0 * dur / ln * (np.exp(t / dur * ln) - 1)
        taper = np.clip(t / 0.2, 0, 1) * np.clip((t[-1] - t) / 0.2, 0, 1)  # no jump at the ends
        s = spec.amplitude * taper * np.sin(phase)
        edges = [f for f in (0.1, 0.2, 0.5, 1, 2, 5, 10, 20, 50, 100, 200, 500) if f0 < f < f1]
        bounds = [f0, *edges, f1]
        for a, b in itertools.pairwise(bounds):
            ta, tb = dur * np.log(a / f0) / ln, dur * np.log(b / f0) / ln
            segs.append({"start_s": float(ta), "end_s": float(tb), "label": f"sweep {a:g}–{b:g} Hz"})
        if base:
            u[:, U_Z0DD] = s
    else:
        raise InputError(f"test '{spec.kind}' has no time waveform (use synth_frf)")
    if not base:
        u[:, U_V_CH1] = spec.bias_v + spec.polarity[0] * s
        u[:, U_V_CH2] = spec.bias_v + spec.polarity[1] * s
    return t, u, segs


def truth_model(params: Any = "table2", effects: Sequence[str | type[PhysicalEffect]] = (),
                values: Mapping[str, float] | None = None, terminal: str = "amplifier") -> PlantModel:
    """The truth plant: a parameter set with core deviations and injected effects (``values`` sets either)."""
    pset = params if not isinstance(params, str) else load_parameter_set(params)
    values = dict(values or {})
    core = {k: float(v) for k, v in values.items() if k in CORE_PARAMETER_NAMES}
    rest = {k: float(v) for k, v in values.items() if k not in CORE_PARAMETER_NAMES}
    if core:
        pset = pset.with_values(None, **core)  # (the set's name kept)
    return PlantModel(pset, effects=effects, terminal=terminal, effect_params=rest)


class TruthSimulationError(InputError):
    """The truth plant cannot be simulated (an injected effect or a parameter value makes it produce NaN/Inf)."""


def blame_non_finite(model: PlantModel, sim: Any, u: np.ndarray, dt: float, params: np.ndarray | None = None
                     ) -> str | None:
    """Name the effect (and hook) whose contribution first turns non-finite: the hooks are plain Python functions,
    so they are run one by one, uncompiled, at the start and at the last finite recorded state (time, state and
    inputs), checking the bus, the rates and the outputs after each."""
    from plant import layout as L

    p = np.asarray(model.p_nominal if params is None else params, float).ravel()
    points = [(0.0, model.x0_nominal.copy(), u[0])]
    if sim.states is not None:
        xs = sim.states[0]
        good = np.flatnonzero(np.all(np.isfinite(xs), axis=1))
        if good.size:
            k = int(good[-1])
            tk = float(sim.t[k])
            points.append((tk, xs[k].copy(), u[min(round(tk / dt), u.shape[0] - 1)]))
    for t, x, uu in points:
        bus = np.zeros(L.N_BUS)
        dx = np.zeros(model.n_states)
        y = np.zeros(model.n_outputs)
        bus[L.B_T], bus[L.B_U_V1], bus[L.B_U_V2], bus[L.B_Z0DD] = t, uu[0], uu[1], uu[2]
        with np.errstate(all="ignore"):
            for phase in ("pre", "rates", "post", "output"):
                for k, cls in enumerate(model.effects):
                    fn = getattr(cls, phase)
                    if fn is None:
                        continue
                    try:
                        fn(t, x, p, bus, y if phase == "output" else dx, *model.composition.hook_args(k, phase))
                    except (ZeroDivisionError, ValueError, OverflowError) as exc:
                        return (f"effect '{cls.name}' ({cls.__module__}.{cls.__qualname__}), hook '{phase}', fails at "
                                f"t = {t:.6g} s: {type(exc).__name__}: {exc}")
                    if not (np.all(np.isfinite(bus)) and np.all(np.isfinite(dx)) and np.all(np.isfinite(y))):
                        return (f"effect '{cls.name}' ({cls.__module__}.{cls.__qualname__}), hook '{phase}', produces "
                                f"NaN/Inf at t = {t:.6g} s — check its parameter values (division by a zero "
                                "parameter?) and its formula")
    return None


def _column(name: str) -> str:
    for prefix, unit in sorted(_COLUMN_UNITS.items(), key=lambda kv: -len(kv[0])):
        if name.startswith(prefix):
            return f"{name}_{unit}"
    raise InputError(f"synth cannot write channel '{name}' (channels: z1..z3, delta1..3, q1..3, qh1..3, "
                     "v_patch1..3, v_stored)")


def _provenance(model: PlantModel, effects: Sequence[Any], values: Mapping[str, float] | None,
                noise: Mapping[str, float], seed: int | None, blind: bool) -> dict[str, Any]:
    prov: dict[str, Any] = {"generator": "shm synth", "truth_params": model.params.name,
                            "noise_std": {k: float(v) for k, v in noise.items()}}
    if seed is not None:
        prov["seed"] = int(seed)
    if blind:
        prov["truth"] = "hidden (blind record)"
    else:
        prov["truth_effects"] = [e if isinstance(e, str) else f"{e.__module__}:{e.__qualname__}" for e in effects]
        # every added effect's parameters as simulated (its defaults too), then what was set
        prov["truth_values"] = {**added_effect_values(model), **{k: float(v) for k, v in (values or {}).items()}}
        neutral = neutral_effects(model)
        if neutral:
            prov["truth_neutral_effects"] = sorted(neutral)
            prov["truth_note"] = (f"{', '.join(sorted(neutral))} at neutral values: this truth equals the nominal "
                                  "plant (the record shows no effect)")
    return prov


def added_effect_values(model: PlantModel) -> dict[str, float]:
    """The value (SI) of every own parameter of the model's added effects (role ``"effect"``)."""
    return {p.name: model.param_value(p.name) for cls in model.effects if cls.role == "effect"
            for p in cls.own_parameters()}


def neutral_effects(model: PlantModel) -> dict[str, dict[str, float]]:
    """The model's added effects whose every own parameter sits at its declared neutral value (the parameter's
    ``neutral``), with those values: each leaves the plant the nominal one. An effect that declares no neutral value
    for a parameter is not judged (left out)."""
    out: dict[str, dict[str, float]] = {}
    for cls in model.effects:
        pars = cls.own_parameters()
        if cls.role != "effect" or not pars:
            continue
        table = cls.neutral_values()
        at: dict[str, float] = {}
        for par in pars:
            n = table.get(par.name)
            if n is None or model.param_value(par.name) != float(n):
                break
            at[par.name] = float(n)
        else:
            out[cls.name] = at
    return out


def _noise_for(channels: Sequence[str], noise: Mapping[str, float] | None) -> dict[str, float]:
    if noise is None:
        return {c: DEFAULT_NOISE.get(c, 0.0) for c in channels}
    return {k: float(v) for k, v in noise.items()}


def synth_record(spec: SynthTest, model: PlantModel, channels: Sequence[str] = ("z3",), *,
                 noise: Mapping[str, float] | None = None, seed: int | None = 0,
                 effects: Sequence[Any] = (), values: Mapping[str, float] | None = None, blind: bool = False,
                 params: np.ndarray | None = None) -> Record:
    """Simulate ``spec`` on the truth ``model`` and return the record a rig would log (in memory).

    ``noise`` maps channel (outputs, or inputs ``v_ch1``/``v_ch2``/``z0dd``) to a white-noise standard deviation
    (SI); ``None`` uses :data:`DEFAULT_NOISE`. ``effects``/``values`` are only written to the provenance
    (``blind`` hides them).
    """
    noise_map = _noise_for(channels, noise)
    for k in noise_map:
        if k not in channels and k not in ("v_ch1", "v_ch2", "z0dd"):
            raise InputError(f"noise given for '{k}', which the record does not contain (channels: "
                             f"{', '.join(channels)}; inputs v_ch1, v_ch2, z0dd)")
        if not (np.isfinite(noise_map[k]) and noise_map[k] >= 0):
            raise InputError(f"noise for '{k}' must be a non-negative number, got {noise_map[k]!r}")
    t, u, segs = synth_inputs(spec, settle_time_s(model) if spec.kind in ("mbit-b", "step") else 1.0)
    sim = model.simulate(InputSignals(0.0, 1.0 / spec.rate_hz, u), t_out=t, params=params, record_states=True)
    if not sim.ok or not np.all(np.isfinite(sim.y)):
        raise TruthSimulationError(f"the truth plant fails on the {spec.kind} test: "
                                   + (blame_non_finite(model, sim, u, 1.0 / spec.rate_hz, params)
                                      or '; '.join(sim.failures()) or "non-finite outputs"))
    rng = np.random.default_rng(seed)
    cols: dict[str, np.ndarray] = {}
    inputs: list[str] = []
    base = spec.drive == "base"
    for name, idx in (("v_ch1", U_V_CH1), ("v_ch2", U_V_CH2)) if not base else (("z0dd", U_Z0DD),):
        col = f"{name}_V" if name != "z0dd" else "z0dd_m_s2"
        cols[col] = u[:, idx] + (rng.normal(0, noise_map[name], t.size) if noise_map.get(name) else 0.0)
        inputs.append(col)
    chan_meta: dict[str, dict[str, Any]] = {}
    for c in channels:
        out = "z3_meas" if c == "z3" else c
        if out not in model.output_names:
            raise InputError(f"the truth model has no output '{out}' (outputs: {', '.join(model.output_names)})")
        col = _column(c)
        sd = noise_map.get(c, 0.0)
        cols[col] = sim[out][0] + (rng.normal(0, sd, t.size) if sd else 0.0)
        chan_meta[col] = {"noise_std": sd} if sd else {}
        if c == "z3":
            chan_meta[col]["sensor"] = "laser (tip)"
    meta: dict[str, Any] = {
        "test": spec.kind, "description": f"synthetic {spec.kind} record ({_describe(spec)})",
        "sample_rate_Hz": spec.rate_hz, "inputs": inputs, "terminal": _terminal_name(model),
        "params": model.params.name, "channels": {k: v for k, v in chan_meta.items() if v},
        "segments": segs, "provenance": _provenance(model, effects, values, noise_map, seed, blind),
    }
    if not meta["channels"]:
        del meta["channels"]
    return record_from_arrays(t, cols, meta, path=f"<synth {spec.kind}>")


def synth_frf(spec: SynthTest, model: PlantModel, channels: Sequence[str] = ("z3",), *,
              noise_rel: float = 0.01, noise_phase_deg: float = 0.5, seed: int | None = 0,
              effects: Sequence[Any] = (), values: Mapping[str, float] | None = None, blind: bool = False
              ) -> FrfRecord:
    """A stepped-sine frequency-response table of the truth ``model`` with relative amplitude and phase noise."""
    f = np.geomspace(spec.f0_hz, spec.f1_hz, spec.n_freqs)
    drive = "z0dd" if spec.drive == "base" else "va"
    outs = ["z3_meas" if c == "z3" else c for c in channels]
    h = stepped_sine(model, f, outs, drive=drive, amplitude=spec.amplitude,
                     bias_v=0.0 if drive == "z0dd" else spec.bias_v)
    rng = np.random.default_rng(seed)
    responses = {}
    for c, o in zip(channels, outs):
        hn = h[o] * (1 + noise_rel * rng.standard_normal(f.size)) * np.exp(
            1j * np.radians(noise_phase_deg) * rng.standard_normal(f.size))
        unit = _column(c).rsplit("_", 1)[1] + ("/V" if drive == "va" else "/(m/s^2)")
        responses[c] = FrfChannel(c, unit, hn)
    meta = {"test": "frf", "terminal": _terminal_name(model), "params": model.params.name,
            "provenance": _provenance(model, effects, values, {"amplitude_rel": noise_rel,
                                                               "phase_deg": noise_phase_deg}, seed, blind)}
    return FrfRecord(path="<synth frf>", frequency_Hz=f, drive=drive, drive_amplitude=spec.amplitude,
                     responses=responses, bias_V=spec.bias_v if drive == "va" else 0.0,
                     terminal=_terminal_name(model), meta=meta)


def write_frf_record(record: FrfRecord, path: Any) -> Any:
    """Write an :class:`FrfRecord` (e.g. from :func:`synth_frf`) as a frequency-response table."""
    from workbench.records import write_frf_table

    drive_unit, token = ("V", "V") if record.drive != "z0dd" else ("g", "g")
    amp = record.drive_amplitude if record.drive != "z0dd" else record.drive_amplitude / G0
    # written per g for base drives (as rigs quote V/g), per V otherwise; the table's units convert back to SI
    resp = {name: (ch.response, f"{ch.unit_si.split('/')[0]}_per_{token}") for name, ch in record.responses.items()}
    meta = {k: v for k, v in record.meta.items() if k not in ("format", "test", "frf")}
    meta["frf"] = {"drive": record.drive, "amplitude": float(amp), "amplitude_unit": drive_unit,
                   "bias_V": float(record.bias_V)}
    return write_frf_table(path, record.frequency_Hz, resp, meta)


def _terminal_name(model: PlantModel) -> str:
    return next(c.name for c in model.effects if c.role == "terminal")


def _describe(spec: SynthTest) -> str:
    amp = f"{spec.amplitude:g} V" if spec.drive == "voltage" else f"{spec.amplitude / G0:g} g"
    if spec.kind in ("mbit-a", "sine"):
        return f"{amp} at {spec.freq_hz:g} Hz, {spec.duration_s:g} s"
    if spec.kind in ("mbit-b", "step"):
        return f"{amp} step at {spec.t_step_s:g} s, {spec.duration_s:g} s"
    if spec.kind == "sweep":
        return f"{amp} log sweep {spec.f0_hz:g}–{spec.f1_hz:g} Hz, {spec.duration_s:g} s"
    return f"{amp} stepped sine {spec.f0_hz:g}–{spec.f1_hz:g} Hz, {spec.n_freqs} points"


def with_duration(spec: SynthTest, duration_s: float) -> SynthTest:
    return replace(spec, duration_s=float(duration_s))
