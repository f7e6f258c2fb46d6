"""Geometric (Duffing) stiffening of the laminate sections at large deflection."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from plant.effect import Parameter, PhysicalEffect
from plant.effects.library_support import FitRange, regress, residual
from plant.layout import B_S, P_K, X_DELTA


class GeometricStiffening(PhysicalEffect):
    r"""Cubic hardening of each bending section: the section force gains −k_i κ δ_i³.

    The stiffness of section i becomes k_i (1 + κ δ_i²): a hardening (κ > 0, membrane stretching and
    foreshortening of a clamped plate at large deflection, or a stiffening clamp contact) or softening
    (κ < 0, e.g. a loosening clamp) Duffing spring. It stores the potential k_i κ δ_i⁴/4 (conservative).
    """

    name = "geometric_stiffening"
    description = "Duffing spring per section: S_i += −k_i κ δ_i³"
    origin = ("Large-deflection kinematics of the cantilevered plate (mid-plane stretching, foreshortening) and "
              "nonlinear contact at the clamp make the bending stiffness grow with the square of the "
              "deflection (von Kármán plate theory; Duffing oscillator).")
    signature = ("Amplitude-dependent stiffness: the residual grows like the cube of the deflection — near zero "
                 "at small deflection and at zero crossings, largest at the peaks, with the sign opposing the "
                 "deflection (the model over-predicts large strokes when κ > 0); odd harmonics (3f) in the "
                 "residual spectrum of a sine test; resonances move with amplitude; no loop in residual versus "
                 "input (elastic, not hysteretic) and no dependence on the input rate.")
    parameters = (
        Parameter("kappa_nl", "m^-2", 0.0, -1.0e4, 5.0e5, "Relative cubic stiffness: k_i(δ) = k_i (1 + κ δ_i²)",
                  neutral=0.0, fit=FitRange(-1.0e4, 2.0e5, linthresh=100.0), challenge=(2e3, 1e4, 5e4)),
    )
    library_order = 2
    short_name = "stiffening"

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        kappa = p[P.kappa_nl]
        for i in range(3):
            d = x[X_DELTA + i]
            bus[B_S + i] -= p[P_K + i] * kappa * d * d * d

    @classmethod
    def guess(cls, data: Mapping[str, Any] | None = None) -> dict[str, float]:
        """κ from regressing the tip residual on z3³: with δ_i ≈ z3/3 the relative stroke loss is ≈ κ z3²/9."""
        rp = residual(data)
        if rp is None:
            return {"kappa_nl": 1.0e3}
        res, pred = rp
        b = regress(res, pred**3)
        return {"kappa_nl": cls.fit_range("kappa_nl").clip(-9.0 * b if b != 0 else 1.0e3)}
