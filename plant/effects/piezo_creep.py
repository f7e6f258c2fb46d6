"""Piezo creep: the slow, roughly logarithmic growth of the patches' strain after a voltage change."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from plant.effect import Parameter, PhysicalEffect, StateSpec
from plant.effects.library_support import FitRange, regress, residual, time_axis
from plant.layout import B_QH, B_S, P_K


class PiezoCreep(PhysicalEffect):
    r"""Creep of the piezo-ceramic rods as two Kelvin–Voigt elements per patch couple, one decade apart.

    For each section i two creep charges w_i1, w_i2 relax towards the effective charge q_hi,

        ẇ_i1 = (q_hi − w_i1)/τ_c,      ẇ_i2 = (q_hi − w_i2)/(10 τ_c),

    and the patch pushes with the extra force ΔS_i = θ_i γ_c (w_i1 + w_i2)/2 / C_ep (θ_i = k_i d_ep). After a
    step the extra stroke rises over τ_c/2 … 20 τ_c, which approximates the logarithmic creep law
    ε(t) = ε_0 [1 + γ log10(t/t_0)] of piezo-ceramics over those two decades; the static (DC) stroke becomes
    (1 + γ_c) times the creep-free one. The creep acts on the mechanical side only (no extra charge is drawn),
    as in the usual phenomenological creep operators for piezo actuators.
    """

    name = "piezo_creep"
    description = "Logarithmic-like piezo creep: two Kelvin-Voigt creep elements (τ_c, 10 τ_c) on the patch force"
    origin = ("Slow, thermally activated motion of ferroelectric domain walls in the PZT fibres keeps changing the "
              "remanent polarisation, hence the strain, for seconds to minutes after the field changes "
              "(Jung & Gweon 2000; Changhai & Lining 2004: creep of a few % per decade of time).")
    signature = ("Slow drift of the deflection after every change of the drive, in the direction of the change: "
                 "after a step the measured deflection keeps creeping up for seconds while the model is flat, so "
                 "the residual grows roughly with log(t) and has the sign of the step; in a slow sine the "
                 "measured loop is larger and lags the model. Residual energy sits below 1/(2π τ_c); the "
                 "input–residual cross-correlation is one-sided with a long tail (the residual follows the input "
                 "late), and it does not depend on the deflection rate.")
    parameters = (
        Parameter("gamma_creep", "1", 0.0, 0.0, 1.0, "Creep gain: extra static stroke as a fraction of the "
                  "creep-free stroke", neutral=0.0, fit=FitRange(0.0, 0.5, linthresh=1e-3),
                  challenge=(0.01, 0.03, 0.1)),
        Parameter("tau_creep", "s", 1.0, 0.01, 1000.0, "Shorter creep time constant (the second is 10 τ_c)",
                  fit=FitRange(0.03, 100.0, log=True), challenge=(0.5, 1.0, 2.0)),
    )
    states = tuple(StateSpec(f"w_creep{i + 1}{k + 1}", "C", 1e-3) for i in range(3) for k in range(2))
    library_order = 1
    short_name = "creep"

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        gamma = p[P.gamma_creep]
        tau = p[P.tau_creep]
        for i in range(3):
            qh = bus[B_QH + i]
            fast = X.w_creep11 + 2 * i  # w_creep{i+1}1; its slow twin w_creep{i+1}2 follows it
            w1 = x[fast]
            w2 = x[fast + 1]
            dx[fast] += (qh - w1) / tau
            dx[fast + 1] += (qh - w2) / (10.0 * tau)
            bus[B_S + i] += p[P_K + i] * p[P.d_ep] * gamma * 0.5 * (w1 + w2) / p[P.C_ep]

    @classmethod
    def guess(cls, data: Mapping[str, Any] | None = None) -> dict[str, float]:
        """γ_c from the late, in-phase part of the tip residual; τ_c from the record length (a tenth of it)."""
        out = {"gamma_creep": 0.05, "tau_creep": 1.0}
        rp = residual(data)
        if rp is None:
            return out
        res, pred = rp
        t = time_axis(data, res.size)
        span = float(t[-1] - t[0]) if t.size > 1 else 10.0
        late = slice(res.size // 2, None)
        gain = regress(res[late], pred[late])
        out["gamma_creep"] = cls.fit_range("gamma_creep").clip(max(gain, 0.01))
        out["tau_creep"] = cls.fit_range("tau_creep").clip(float(np.clip(span / 10.0, 0.1, 10.0)))
        return out
