"""Standard nonlinear time responses of the paper's validation tests (Fig. 7)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from plant.model import PlantModel
from plant.signals import sine_drive, step_drive


@dataclass
class TimeResponse:
    """A single-trajectory response: time (s), differential drive v_a (V), tip displacement z3 (m)."""

    t: np.ndarray
    va: np.ndarray
    z3: np.ndarray
    label: str

    def columns(self) -> dict[str, np.ndarray]:
        return {"time_s": self.t, "va_V": self.va, "z3_m": self.z3}


def hysteresis_loop(model: PlantModel, amplitude_v: float = 600.0, freq_hz: float = 0.01, cycles: float = 1.25,
                    dt_out: float | None = None) -> TimeResponse:
    """Quasi-static sine drive (Fig. 7a: 0.01 Hz, 600 V): z3 against v_a traces the hysteresis loop."""
    t_end = cycles / freq_hz
    dt_out = dt_out if dt_out is not None else min(0.05, 1.0 / (freq_hz * 400))
    inp = sine_drive(amplitude_v, freq_hz, t_end, dt=min(1e-2, 1.0 / (freq_hz * 2000)))
    res = model.simulate(inp, dt_out=dt_out)
    res.raise_on_failure()
    va = amplitude_v * np.sin(2 * np.pi * freq_hz * res.t)
    return TimeResponse(res.t, va, res["z3"][0], f"{amplitude_v:g} V sine at {freq_hz:g} Hz")


def step_response(model: PlantModel, amplitude_v: float = 300.0, duration_s: float = 2.0, t_step: float = 0.1,
                  dt_out: float = 1e-3) -> TimeResponse:
    """Differential voltage step (Fig. 7b: 300 V) with a 1 ms rise."""
    inp = step_drive(amplitude_v, duration_s, t_step=t_step)
    res = model.simulate(inp, dt_out=dt_out)
    res.raise_on_failure()
    va = amplitude_v * np.clip((res.t - t_step) / 1e-3, 0.0, 1.0)
    return TimeResponse(res.t, va, res["z3"][0], f"{amplitude_v:g} V step")
