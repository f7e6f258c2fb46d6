"""Stepped-sine frequency response of the (nonlinear) plant, as a rig measures it.

At each frequency the model is driven by a sine of the stated amplitude from rest, left to settle, and the
first harmonic of each output is extracted by least squares over whole cycles. Because the plant is
nonlinear (Bouc-Wen hysteresis), the result depends on the amplitude, exactly like the measurement.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from board_config.errors import InputError
from plant import InputSignals, PlantModel
from plant.layout import N_INPUTS, U_V_CH1, U_V_CH2, U_Z0DD

DRIVES = ("va", "v_ch1", "v_ch2", "z0dd")


def sine_inputs(drive: str, amplitude: float, freq_hz: float, t_end: float, dt: float, bias_v: float = 0.0,
                t0: float = 0.0) -> InputSignals:
    """A sine on one drive: ``va`` (channel 1 at bias+a, channel 2 at bias−a), one channel, or ``z0dd``."""
    if drive not in DRIVES:
        raise InputError(f"unknown drive '{drive}' (drives: {', '.join(DRIVES)})")
    t = t0 + dt * np.arange(round((t_end - t0) / dt) + 1)
    s = amplitude * np.sin(2 * np.pi * freq_hz * (t - t0))
    u = np.zeros((t.size, N_INPUTS))
    if drive == "z0dd":
        u[:, U_Z0DD] = s
    else:
        u[:, U_V_CH1] = bias_v
        u[:, U_V_CH2] = bias_v
        if drive in ("va", "v_ch1"):
            u[:, U_V_CH1] += s
        if drive == "va":
            u[:, U_V_CH2] -= s
        elif drive == "v_ch2":
            u[:, U_V_CH2] += s
    return InputSignals(t0, dt, u)


def first_harmonic(t: np.ndarray, y: np.ndarray, freq_hz: float) -> complex:
    """Complex amplitude ``A e^{jφ}`` of ``y ≈ c + A sin(ωt + φ)`` by least squares (t spans whole cycles)."""
    w = 2 * np.pi * freq_hz
    basis = np.column_stack([np.sin(w * t), np.cos(w * t), np.ones_like(t)])
    (a, b, _), *_ = np.linalg.lstsq(basis, y, rcond=None)
    return complex(a, b)  # a sin + b cos = Re{(a + jb) e^{jωt}} shifted: amplitude |a+jb|, phase atan2(b, a)


def stepped_sine(model: PlantModel, frequencies_hz: Sequence[float] | np.ndarray, outputs: Sequence[str],
                 drive: str = "va", amplitude: float = 600.0, bias_v: float = 0.0, params: np.ndarray | None = None,
                 settle_cycles: float = 3.0, min_settle_s: float = 1.0, measure_cycles: int = 4,
                 points_per_cycle: int = 200) -> dict[str, np.ndarray]:
    """Complex response (output per unit drive, SI) of each output at each frequency.

    Phase is relative to the drive ``sin(ωt)``. Settling: ``max(settle_cycles/f, min_settle_s)`` seconds, then
    ``measure_cycles`` whole cycles are fitted. Raises :class:`plant.IntegrationFailed` (a ``FloatingPointError``)
    if an integration fails.
    """
    for name in outputs:
        if name not in model.output_names:
            raise KeyError(f"model has no output '{name}' (outputs: {', '.join(model.output_names)})")
    res: dict[str, list[complex]] = {o: [] for o in outputs}
    for f in frequencies_hz:
        f = float(f)
        if not f > 0:
            raise InputError(f"frequency must be positive, got {f}")
        settle = max(settle_cycles / f, min_settle_s)
        settle = np.ceil(settle * f) / f  # whole cycles, so the fit window starts at phase 0
        t_end = settle + measure_cycles / f
        dt = min(1e-3, 1.0 / (f * points_per_cycle))
        inp = sine_inputs(drive, amplitude, f, t_end, dt, bias_v)
        n_meas = measure_cycles * 64
        t_out = np.concatenate([[0.0], settle + np.arange(n_meas) / (64 * f)])
        sim = model.simulate(inp, t_out=t_out, params=params, h_max=min(1e-3, 1.0 / (20 * f)))
        sim.raise_on_failure(f"stepped sine at {f:g} Hz failed: ")
        for o in outputs:
            res[o].append(first_harmonic(t_out[1:], sim[o][0, 1:], f) / amplitude)
    return {o: np.asarray(v) for o, v in res.items()}
