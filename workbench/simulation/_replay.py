"""Replay a record's inputs through the model: free-run simulation, and a k-step-ahead prediction.

* **Simulation (free run)** — the model starts at rest (or a given state) and sees only the record's inputs;
  it never sees the measured outputs. This is MATLAB ``compare(..., Inf)``; every model error accumulates.
* **k-step-ahead prediction** — a fixed-gain observer (steady-state Kalman gain of the model linearised at
  rest, corrected from the measured outputs every ``interval_s``, default the monitor's 10 ms) runs the
  *nonlinear* model along the record; from each corrected state the model is run open-loop for
  ``k = horizon_s / interval_s`` intervals, and the value it reaches is the k-step prediction
  ``ŷ(t | t − k·interval)``. Errors that a few intervals of measurement correct (offsets, slow drift, a wrong
  static gain) shrink here; errors in the fast dynamics (a wrong mode, missing damping) stay. It applies to
  time records whose measured channels are model outputs; not to frequency-response tables.

Residuals are ``measured − model`` (MATLAB's convention). Units are SI.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy import linalg

from board_config.errors import InputError
from plant import InputSignals, IntegrationFailed, Integrator, PhysicalEffect, PlantModel
from workbench.records import FrfRecord, Record
from workbench.simulation._frequency_response import stepped_sine

#: Default correction interval of the predictor: the board monitor's sampling (Table 3, f_mon = 100 Hz).
DEFAULT_INTERVAL_S = 0.01
#: Default prediction horizon (s): five monitor ticks, about one period of the first bending mode.
DEFAULT_HORIZON_S = 0.05


class ReplayError(InputError):
    """The record cannot be replayed through this model (a channel the model lacks, a terminal mismatch...)."""


class SimulationFailed(RuntimeError):
    """The model's integration failed on the record's inputs (diverged, step size collapsed...)."""


@dataclass
class ChannelReplay:
    """One measured channel against the model: ``residual = measured − simulated`` (SI)."""

    name: str
    model_output: str
    unit: str
    measured: np.ndarray
    simulated: np.ndarray
    noise_std: float | None = None

    @property
    def residual(self) -> np.ndarray:
        return self.measured - self.simulated


@dataclass
class Prediction:
    """k-step-ahead prediction on the observer's correction grid ``t``."""

    label: str
    method: str
    interval_s: float
    steps: int
    t: np.ndarray
    measured: dict[str, np.ndarray]
    predicted: dict[str, np.ndarray]
    one_step: dict[str, np.ndarray]  # ŷ(t | t − interval): the observer's own innovation reference
    gain_note: str = ""

    @property
    def horizon_s(self) -> float:
        return self.steps * self.interval_s


@dataclass
class Replay:
    """A record replayed through a model (see the module docstring)."""

    record: Record
    model: PlantModel
    t: np.ndarray
    channels: dict[str, ChannelReplay]
    drive_name: str
    drive_unit: str
    drive: np.ndarray
    prediction: Prediction | None = None
    prediction_note: str = ""
    wall_s: dict[str, float] = field(default_factory=dict)

    @property
    def model_label(self) -> str:
        return model_label(self.model)


@dataclass
class FrfReplay:
    """A frequency-response table against the model's stepped-sine response at the same drive amplitude."""

    record: FrfRecord
    model: PlantModel
    frequency_Hz: np.ndarray
    measured: dict[str, np.ndarray]
    modelled: dict[str, np.ndarray]
    units: dict[str, str]
    wall_s: dict[str, float] = field(default_factory=dict)

    @property
    def model_label(self) -> str:
        return model_label(self.model)


def model_label(model: PlantModel) -> str:
    """``table2`` or ``table2 + creep, duffing``: the parameter set and the effects added to the nominal model."""
    from plant import NOMINAL_EFFECTS

    added = [c.name for c in model.effects if c.name not in NOMINAL_EFFECTS and c.role != "terminal"]
    return f"{model.params.name}" + (f" + {', '.join(added)}" if added else "")


def model_for(record: Record | FrfRecord, params: Any = "table2",
              effects: Sequence[str | type[PhysicalEffect]] = (), effect_params: Mapping[str, float] | None = None,
              ) -> PlantModel:
    """The model to compare with ``record``: parameter set + added effects, with the record's terminal."""
    terminal = record.terminal or ("open_circuit" if _is_base_excited(record) else "amplifier")
    return PlantModel(params, effects=effects, terminal=terminal, effect_params=effect_params)


def _is_base_excited(record: Record | FrfRecord) -> bool:
    if isinstance(record, FrfRecord):
        return record.drive == "z0dd"
    return record.drive()[0] == "z0dd"


def model_output_for(model: PlantModel, record_path: str, channel: str, declared: str | None) -> str:
    """Which model output a measured channel compares with.

    The declared ``model_output`` wins; the tip laser channel ``z3`` compares with ``z3_meas`` (the model's
    view through the laser sensor, equal to z3 unless a sensor effect acts); else the same name.
    """
    if declared is not None:
        if declared not in model.output_names:
            raise ReplayError(f"{record_path}: channel '{channel}' declares model_output '{declared}', which the "
                              f"model does not have (outputs: {', '.join(model.output_names)})")
        return declared
    if channel == "z3" and "z3_meas" in model.output_names:
        return "z3_meas"
    if channel in model.output_names:
        return channel
    raise ReplayError(f"{record_path}: channel '{channel}' matches no model output (outputs: "
                      f"{', '.join(model.output_names)}); set [channels.<column>] model_output in the metadata")


def _check_terminal(model: PlantModel, record: Record | FrfRecord) -> None:
    if record.terminal is None:
        return
    names = [c.name for c in model.effects if c.role == "terminal"]
    if record.terminal not in names:
        raise ReplayError(f"{record.path}: the record was taken with terminal '{record.terminal}' but the model's "
                          f"terminal is '{names[0] if names else '?'}' (build it with workbench.simulation.model_for)")


def replay(model: PlantModel, record: Record, *, params: np.ndarray | None = None, x0: np.ndarray | None = None,
           predict: bool = True, horizon_s: float = DEFAULT_HORIZON_S, interval_s: float = DEFAULT_INTERVAL_S,
           rtol: float = 1e-6) -> Replay:
    """Free-run simulation of ``record``'s inputs through ``model`` (+ a k-step prediction when it applies).

    ``params`` is a parameter vector (default the model's nominal one), ``x0`` an initial state (default rest).
    Raises :class:`ReplayError` when a channel has no model counterpart, :class:`SimulationFailed` when the
    integration fails.
    """
    if not isinstance(record, Record):
        raise ReplayError(f"{record.path}: replay() takes a time record; use replay_frf() for a frequency-response "
                          "table")
    _check_terminal(model, record)
    mapping = {n: model_output_for(model, record.path, n, record.channels[n].model_output) for n in record.outputs}
    wall: dict[str, float] = {}
    t0 = time.perf_counter()
    inputs = record.input_signals()
    sim = model.simulate(inputs, t_out=record.t, params=params, x0=x0, rtol=rtol)
    wall["simulate_s"] = time.perf_counter() - t0
    try:
        sim.raise_on_failure(f"{record.path}: free-run simulation failed: ")
    except IntegrationFailed as exc:
        raise SimulationFailed(str(exc)) from None
    channels = {
        n: ChannelReplay(n, mapping[n], record.channels[n].si_unit, record[n], sim[mapping[n]][0].copy(),
                         record.channels[n].noise_std)
        for n in record.outputs
    }
    dname, dunit, dval = record.drive()
    rep = Replay(record, model, record.t, channels, dname, dunit, dval, wall_s=wall)
    if predict:
        t1 = time.perf_counter()
        try:
            rep.prediction = predict_k_step(model, record, mapping, params=params, x0=x0, horizon_s=horizon_s,
                                            interval_s=interval_s, rtol=rtol)
        except PredictionUnavailable as exc:
            rep.prediction_note = str(exc)
        wall["predict_s"] = time.perf_counter() - t1
    else:
        rep.prediction_note = "prediction not requested"
    return rep


def replay_frf(model: PlantModel, record: FrfRecord, *, params: np.ndarray | None = None) -> FrfReplay:
    """The model's stepped-sine response at the table's frequencies, drive and amplitude."""
    _check_terminal(model, record)
    mapping = {n: model_output_for(model, record.path, n, ch.model_output) for n, ch in record.responses.items()}
    t0 = time.perf_counter()
    try:
        h = stepped_sine(model, record.frequency_Hz, sorted(set(mapping.values())), drive=record.drive,
                         amplitude=record.drive_amplitude, bias_v=record.bias_V, params=params)
    except FloatingPointError as exc:
        raise SimulationFailed(f"{record.path}: {exc}") from None
    return FrfReplay(record, model, record.frequency_Hz, {n: ch.response for n, ch in record.responses.items()},
                     {n: h[mapping[n]] for n in record.responses}, {n: ch.unit_si for n, ch in
                                                                    record.responses.items()},
                     wall_s={"stepped_sine_s": time.perf_counter() - t0})


# ----------------------------------------------------------------------------------------------------------------
# the k-step predictor


class PredictionUnavailable(Exception):
    """Why no k-step prediction is shown (the reason is printed in the report)."""


def linearise(model: PlantModel, outputs: Sequence[str], params: np.ndarray | None = None
              ) -> tuple[np.ndarray, np.ndarray]:
    """``(A, C)`` of the model linearised at rest (zero state and inputs), by central differences."""
    p = model.p_nominal if params is None else np.asarray(params, float)
    x0 = model.x0_nominal.copy()
    n = model.n_states
    idx = [model.output_names.index(o) for o in outputs]
    a = np.zeros((n, n))
    c = np.zeros((len(idx), n))
    for j in range(n):
        h = 1e-6 * model.state_scales[j]
        xp, xm = x0.copy(), x0.copy()
        xp[j] += h
        xm[j] -= h
        a[:, j] = (model.rhs(0.0, xp, None, p) - model.rhs(0.0, xm, None, p)) / (2 * h)
        c[:, j] = (model.outputs(0.0, xp, None, p)[idx] - model.outputs(0.0, xm, None, p)[idx]) / (2 * h)
    return a, c


def observer_gain(a: np.ndarray, c: np.ndarray, interval_s: float, scales: np.ndarray, noise_std: np.ndarray,
                  process_rel: float = 0.05) -> np.ndarray:
    """Steady-state (filter-form) Kalman gain of the discretised linearisation.

    Process noise: independent on every state, ``process_rel`` × the state's typical magnitude per interval;
    measurement noise: ``noise_std`` per channel. Marginal modes (Bouc-Wen's integrator) are shifted slightly
    into the stable half-plane for the gain computation so that unobservable ones get no gain.
    """
    n = a.shape[0]
    ad = linalg.expm((a - 1e-2 * np.eye(n)) * interval_s)
    q = np.diag((process_rel * scales) ** 2)
    r = np.diag(np.maximum(noise_std, 1e-12) ** 2)
    p = linalg.solve_discrete_are(ad.T, c.T, q, r)
    s = c @ p @ c.T + r
    return p @ c.T @ np.linalg.inv(s)


def estimate_noise_std(y: np.ndarray) -> float:
    """Robust white-noise level of a sampled signal: MAD of second differences / √6 (smooth parts cancel)."""
    d2 = np.diff(np.asarray(y, float), 2)
    if d2.size == 0:
        return 0.0
    return float(1.4826 * np.median(np.abs(d2 - np.median(d2))) / np.sqrt(6.0))


def _observer_run(model: PlantModel, inputs: InputSignals, m: int, n_int: int, meas: np.ndarray, gain: np.ndarray,
                  yidx: np.ndarray, p: np.ndarray, x0: np.ndarray | None, interval: float, rtol: float
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Run the nonlinear model with output-injection corrections every ``m`` samples.

    Returns the corrected states at the correction times (``n_int + 1`` rows) and the one-interval-ahead
    outputs before each correction (``n_int`` rows). One integrator interval per correction, no per-call allocation.
    """
    integrator = Integrator(model, rtol)
    n = model.n_states
    x = np.array((model.x0_nominal if x0 is None else np.asarray(x0, float)).reshape(1, n), order="C")
    pp = np.ascontiguousarray(p, dtype=float).reshape(1, -1)
    u = inputs.values  # (1, samples, 3), absolute time from inputs.t0
    y = np.zeros((1, 2, model.n_outputs))
    xsb = np.zeros((1, 2, n))
    t_out = np.zeros(2)
    h_max = min(interval, 5e-3)
    xs = np.empty((n_int + 1, n))
    xs[0] = x[0]
    one = np.empty((n_int, yidx.size))
    t0, dt = float(inputs.t0), float(inputs.dt)
    for i in range(n_int):
        t_out[0] = t0 + i * m * dt
        t_out[1] = t0 + (i + 1) * m * dt
        try:
            integrator.interval(x, pp, u, t0, dt, t_out, h_max, y, xsb, what="observer")
        except IntegrationFailed as exc:
            raise PredictionUnavailable(f"observer run failed at t = {exc.t:.6g} s ({exc.status.message})") from None
        yi = y[0, 1, yidx]
        one[i] = yi
        x[0] = xsb[0, 1] + gain @ (meas[(i + 1) * m] - yi)
        xs[i + 1] = x[0]
    return xs, one


def predict_k_step(model: PlantModel, record: Record, mapping: Mapping[str, str], *,
                   params: np.ndarray | None = None, x0: np.ndarray | None = None,
                   horizon_s: float = DEFAULT_HORIZON_S, interval_s: float = DEFAULT_INTERVAL_S,
                   rtol: float = 1e-6) -> Prediction:
    """k-step-ahead prediction with a fixed-gain observer on the nonlinear model (see the module docstring)."""
    inputs = record.input_signals()
    dt = inputs.dt
    m = max(1, round(interval_s / dt))
    interval = m * dt
    k = max(1, round(horizon_s / interval))
    n_int = (inputs.n_samples - 1) // m
    if n_int < k + 2:
        raise PredictionUnavailable(f"record too short for a {k}-step prediction at {interval * 1e3:g} ms intervals "
                                    f"({record.duration_s:g} s)")
    names = list(mapping)
    outs = [mapping[n] for n in names]
    grid = inputs.t
    meas = np.column_stack([np.interp(grid, record.t, record[n]) if not record.uniform else record[n][:grid.size]
                            for n in names])
    noise = np.array([record.channels[n].noise_std if record.channels[n].noise_std else
                      estimate_noise_std(record[n]) for n in names])
    span = np.array([max(np.ptp(record[n]), 1e-300) for n in names])
    noise = np.maximum(noise, 1e-4 * span)  # a noiseless record still gets a finite measurement weight
    p = model.p_nominal if params is None else np.asarray(params, float)
    a, c = linearise(model, outs, p)
    try:
        gain = observer_gain(a, c, interval, model.state_scales, noise)
    except (np.linalg.LinAlgError, ValueError) as exc:
        raise PredictionUnavailable(f"no observer gain for the linearised model ({exc})") from None
    yidx = np.array([model.output_names.index(o) for o in outs])
    xs, one = _observer_run(model, inputs, m, n_int, meas, gain, yidx, p, x0, interval, rtol)
    u = inputs.values[0]
    # open-loop k intervals from every corrected state, batched (window-relative time)
    starts = np.arange(0, n_int - k + 1)
    idx = starts[:, None] * m + np.arange(k * m + 1)[None, :]
    win = InputSignals(0.0, dt, u[idx])
    sim = model.simulate(win, t_out=np.array([0.0, k * interval]), params=p, x0=xs[starts], rtol=rtol,
                         h_max=min(interval, 5e-3))
    if not sim.ok:
        raise PredictionUnavailable(f"k-step windows failed: {'; '.join(sim.failures()[:3])}")
    t_pred = grid[(starts + k) * m]
    predicted = {n: sim[o][:, 1].copy() for n, o in zip(names, outs)}
    measured = {n: meas[(starts + k) * m, j] for j, n in enumerate(names)}
    one_step = {n: one[:, j] for j, n in enumerate(names)}
    return Prediction(
        label=f"{k}-step-ahead prediction (horizon {k * interval * 1e3:g} ms, corrected every {interval * 1e3:g} ms)",
        method=("fixed-gain observer: steady-state Kalman gain of the model linearised at rest, measured "
                f"{', '.join(names)} fed back every {interval * 1e3:g} ms; nonlinear model run open-loop for "
                f"{k} intervals from each corrected state"),
        interval_s=interval, steps=k, t=t_pred, measured=measured, predicted=predicted, one_step=one_step,
        gain_note=f"measurement noise assumed {', '.join(f'{n}: {s:.3g}' for n, s in zip(names, noise))} (SI)",
    )
