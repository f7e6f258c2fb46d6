"""Linear analysis of the plant around rest: state-space matrices, modes, real poles, frequency responses.

The model is linearised numerically (central differences of the composed right-hand side and output map)
at the rest state (all states zero, inputs zero). At h_q = 0 the Bouc-Wen term is differentiable with slope
A_h, so the small-signal model has q_h = (α_h + (1 − α_h) A_h) q (plus three pure-integrator states h_q that
carry the remanence; they are reported separately, not as modes).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from plant import layout as L
from plant.model import PlantModel
from plant.signals import G0

#: input directions (in the raw input space v_ch1, v_ch2, z0dd)
INPUT_DIRECTIONS: dict[str, np.ndarray] = {
    "va": np.array([1.0, -1.0, 0.0]),  # differential drive: channel 1 at +v, channel 2 at −v (V)
    "z0dd": np.array([0.0, 0.0, 1.0]),  # base acceleration (m/s^2)
}


@dataclass
class LinearModel:
    """x' = A x + B u, y = C x + D u around rest. Inputs named by :data:`INPUT_DIRECTIONS` (SI)."""

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    state_names: tuple[str, ...]
    input_names: tuple[str, ...]
    output_names: tuple[str, ...]
    output_units: tuple[str, ...]

    def frf(self, freqs_hz: np.ndarray, output: str, input: str) -> np.ndarray:
        """Complex frequency response of ``output`` to ``input`` at ``freqs_hz`` (SI units ratio)."""
        j = self.output_names.index(output)
        k = self.input_names.index(input)
        n = self.A.shape[0]
        eye = np.eye(n)
        h = np.empty(len(freqs_hz), dtype=complex)
        for i, f in enumerate(np.asarray(freqs_hz, dtype=float)):
            s = 2j * np.pi * f
            h[i] = self.C[j] @ np.linalg.solve(s * eye - self.A, self.B[:, k]) + self.D[j, k]
        return h


@dataclass
class ModalSummary:
    """Modes (complex pairs), real poles and pure integrators of the linearised model."""

    modes: list[dict[str, float]] = field(default_factory=list)  # {frequency_Hz, damping_ratio, ...}
    real_poles: list[dict[str, float]] = field(default_factory=list)  # {frequency_Hz, time_constant_s}
    integrators: int = 0

    def as_dict(self) -> dict[str, Any]:
        return {"modes": self.modes, "real_poles": self.real_poles, "pure_integrators": self.integrators}


def linearise(model: PlantModel, params: np.ndarray | None = None, x0: np.ndarray | None = None,
              rel_step: float = 1e-6) -> LinearModel:
    """Numerical linearisation (central differences) of the composed model at ``x0`` (default: rest)."""
    p = model.p_nominal if params is None else np.asarray(params, dtype=float)
    x0 = np.zeros(model.n_states) if x0 is None else np.asarray(x0, dtype=float)
    u0 = np.zeros(L.N_INPUTS)
    n, ny = model.n_states, model.n_outputs
    A = np.empty((n, n))
    C = np.empty((ny, n))
    for k in range(n):
        h = rel_step * model.state_scales[k]
        xp, xm = x0.copy(), x0.copy()
        xp[k] += h
        xm[k] -= h
        A[:, k] = (model.rhs(0.0, xp, u0, p) - model.rhs(0.0, xm, u0, p)) / (2 * h)
        C[:, k] = (model.outputs(0.0, xp, u0, p) - model.outputs(0.0, xm, u0, p)) / (2 * h)
    names = tuple(INPUT_DIRECTIONS)
    B = np.empty((n, len(names)))
    D = np.empty((ny, len(names)))
    for k, name in enumerate(names):
        d = INPUT_DIRECTIONS[name]
        h = 1e-3 if name == "va" else 1e-4
        B[:, k] = (model.rhs(0.0, x0, u0 + h * d, p) - model.rhs(0.0, x0, u0 - h * d, p)) / (2 * h)
        D[:, k] = (model.outputs(0.0, x0, u0 + h * d, p) - model.outputs(0.0, x0, u0 - h * d, p)) / (2 * h)
    return LinearModel(A, B, C, D, model.state_names, names, model.output_names, model.output_units)


def modal_summary(lin: LinearModel, zero_tol: float = 1e-6) -> ModalSummary:
    """Natural frequencies (Hz), damping ratios, real poles; eigenvalues ~0 are counted as integrators."""
    ev = np.linalg.eigvals(lin.A)
    scale = max(np.max(np.abs(ev)), 1.0)
    out = ModalSummary()
    for lam in sorted(ev, key=lambda z: (abs(z), z.imag)):
        mag = abs(lam)
        if mag < zero_tol * scale:
            out.integrators += 1
        elif abs(lam.imag) > 1e-9 * mag:
            if lam.imag > 0:
                out.modes.append({"frequency_Hz": mag / (2 * np.pi), "damping_ratio": -lam.real / mag,
                                  "damped_frequency_Hz": lam.imag / (2 * np.pi)})
        else:
            out.real_poles.append({"frequency_Hz": -lam.real / (2 * np.pi), "time_constant_s": -1.0 / lam.real})
    return out


def static_tip_gain(lin: LinearModel, f_low_hz: float = 1e-6) -> float:
    """Quasi-static gain of z3 to the differential drive v_a (m/V): the FRF's low-frequency limit."""
    return float(np.real(lin.frf(np.array([f_low_hz]), "z3", "va")[0]))


def static_tip_gain_closed_form(model: PlantModel) -> float:
    """Closed form of the static z3/v_a gain (m/V): 3 d_ep (α_h + (1 − α_h) A_h).

    At rest q_i = C_ep v_a, the small-signal Bouc-Wen branch gives q_hi = (α + (1−α)A) q_i, every section force
    S_i vanishes (the chain carries no load), so δ_i = d_ep (α + (1−α)A) v_a for each of the three sections.
    """
    a, A = model.param_value("alpha_h"), model.param_value("A_h")
    if "bouc_wen" not in model.effect_names:
        a, A = 1.0, 0.0
    return 3.0 * model.param_value("d_ep") * (a + (1.0 - a) * A)


def harvest_gain_v_per_g(lin: LinearModel, freq_hz: float) -> float:
    """|stored voltage / base acceleration| at ``freq_hz``, in V per g (needs an open-circuit terminal model)."""
    return float(abs(lin.frf(np.array([freq_hz]), "v_stored", "z0dd")[0]) * G0)


def peak_near(freqs: np.ndarray, mag: np.ndarray, f_center: float, rel_band: float = 0.5) -> tuple[float, float]:
    """(frequency, magnitude) of the largest value of ``mag`` within ±rel_band of ``f_center``."""
    sel = (freqs >= f_center * (1 - rel_band)) & (freqs <= f_center * (1 + rel_band))
    if not np.any(sel):
        raise ValueError(f"no frequency within ±{rel_band:.0%} of {f_center} Hz")
    i = np.argmax(np.where(sel, mag, -np.inf))
    return float(freqs[i]), float(mag[i])
