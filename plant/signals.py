"""Input signals for the plant: channel voltages and base acceleration on a uniform time grid."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from board_config.physical_constants import G0
from plant.layout import INPUT_NAMES, N_INPUTS, U_V_CH1, U_V_CH2, U_Z0DD

__all__ = ["G0", "InputSignals", "base_sine", "sine_drive", "step_drive"]


@dataclass(frozen=True)
class InputSignals:
    """Sampled inputs: ``values[b, k, i]`` for batch member ``b`` (or 1 shared), sample ``k``, input ``i``.

    Inputs (SI): ``v_ch1`` and ``v_ch2`` (V), ``z0dd`` (m/s^2). Samples are at ``t0 + k*dt``; the
    integrator interpolates linearly between samples and holds the end values outside.
    """

    t0: float
    dt: float
    values: np.ndarray

    def __post_init__(self) -> None:
        v = np.asarray(self.values, dtype=float)
        if v.ndim == 2:
            v = v[None]
        if v.ndim != 3 or v.shape[2] != N_INPUTS:
            raise ValueError(f"InputSignals.values must have shape (batch, samples, {N_INPUTS}) "
                             f"for inputs {INPUT_NAMES}; got {np.shape(self.values)}")
        if not np.all(np.isfinite(v)):
            bad = np.argwhere(~np.isfinite(v))[0]
            raise ValueError(f"InputSignals.values has a non-finite value at batch {bad[0]}, sample {bad[1]}, "
                             f"input '{INPUT_NAMES[bad[2]]}'")
        if not (self.dt > 0 and np.isfinite(self.dt)):
            raise ValueError(f"InputSignals.dt must be positive and finite, got {self.dt!r}")
        object.__setattr__(self, "values", np.ascontiguousarray(v))

    @property
    def batch(self) -> int:
        return self.values.shape[0]

    @property
    def n_samples(self) -> int:
        return self.values.shape[1]

    @property
    def t(self) -> np.ndarray:
        return self.t0 + self.dt * np.arange(self.n_samples)

    @classmethod
    def from_functions(cls, t_end: float, dt: float, va=None, z0dd=None, t0: float = 0.0) -> InputSignals:
        """Differential drive ``va(t)`` (V; channel 1 at +va, channel 2 at −va) and ``z0dd(t)`` (m/s^2)."""
        t = t0 + dt * np.arange(round((t_end - t0) / dt) + 1)
        vals = np.zeros((1, t.size, N_INPUTS))
        if va is not None:
            v = np.broadcast_to(np.asarray(va(t), dtype=float), t.shape)
            vals[0, :, U_V_CH1] = v
            vals[0, :, U_V_CH2] = -v
        if z0dd is not None:
            vals[0, :, U_Z0DD] = np.broadcast_to(np.asarray(z0dd(t), dtype=float), t.shape)
        return cls(t0, dt, vals)

    @classmethod
    def zeros(cls, t_end: float = 0.0) -> InputSignals:
        return cls(0.0, max(t_end, 1.0), np.zeros((1, 2, N_INPUTS)))


def sine_drive(amplitude_v: float, freq_hz: float, t_end: float, dt: float | None = None,
               phase_rad: float = 0.0) -> InputSignals:
    """Differential sine drive of amplitude ``amplitude_v`` (V) at ``freq_hz`` (Hz)."""
    dt = dt if dt is not None else min(1e-3, 1.0 / (freq_hz * 200.0))
    return InputSignals.from_functions(t_end, dt, va=lambda t: amplitude_v * np.sin(2 * np.pi * freq_hz * t
                                                                                    + phase_rad))


def step_drive(amplitude_v: float, t_end: float, t_step: float = 0.0, rise_s: float = 1e-3,
               dt: float = 1e-4) -> InputSignals:
    """Differential voltage step to ``amplitude_v`` (V) at ``t_step`` (s), with a linear rise of ``rise_s``
    (a real amplifier's finite slew; also keeps the input continuous for the integrator)."""
    rise = max(rise_s, dt)
    return InputSignals.from_functions(
        t_end, dt, va=lambda t: amplitude_v * np.clip((t - t_step) / rise, 0.0, 1.0))


def base_sine(accel_m_s2: float, freq_hz: float, t_end: float, dt: float | None = None) -> InputSignals:
    """Sinusoidal base acceleration of amplitude ``accel_m_s2`` (m/s^2) at ``freq_hz`` (Hz)."""
    dt = dt if dt is not None else min(1e-3, 1.0 / (freq_hz * 200.0))
    return InputSignals.from_functions(t_end, dt, z0dd=lambda t: accel_m_s2 * np.sin(2 * np.pi * freq_hz * t))
