"""Dielectric leakage: a conductance in parallel with each patch capacitance."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from plant.effect import Parameter, PhysicalEffect
from plant.effects.library_support import FitRange, param, regress, residual
from plant.layout import B_VC, X_Q


class DielectricLeakage(PhysicalEffect):
    r"""Each patch couple leaks its charge through a parallel conductance G_leak: q̇_i −= G_leak q_i / C_ep.

    In actuation (amplifier terminal) the static charge becomes C_ep v_a / (1 + R_ep G_leak) and the R-C pole
    moves up to (1 + R_ep G_leak)/(2π R_ep C_ep); in open-circuit sensing the stored voltage decays with the
    time constant C_ep / G_leak (a high-pass at G_leak/(2π C_ep)).
    """

    name = "dielectric_leakage"
    description = "Parallel leakage conductance of each patch: q̇ −= G_leak q / C_ep"
    origin = ("Finite insulation resistance of the epoxy/Kapton dielectric between the interdigitated electrodes "
              "(moisture uptake, micro-cracks, contamination), of the cabling, and any bleed resistor at the "
              "amplifier output; a healthy MFC leaks < 10 nS, a degraded one µS to mS.")
    signature = ("Charge that the model keeps but the patches lose: in actuation the quasi-static stroke is lower "
                 "than modelled by a constant fraction 1/(1 + R_ep G) while resonances stay put, so the residual "
                 "is proportional to the response and opposite in sign, strongest at DC and low frequency, nearly "
                 "zero above the R-C pole (the step settles faster, to a lower level); in open-circuit sensing the "
                 "stored voltage decays between excitations. No time trend, no amplitude dependence.")
    parameters = (
        Parameter("G_leak", "S", 0.0, 0.0, 1.0e-2, "Leakage conductance in parallel with each patch couple",
                  neutral=0.0, fit=FitRange(0.0, 2.0e-3, linthresh=1e-7), challenge=(2e-6, 1e-5, 5e-5)),
    )
    library_order = 4
    short_name = "leakage"

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        g = p[P.G_leak]
        for i in range(3):
            dx[X_Q + i] -= g * bus[B_VC + i]

    @classmethod
    def guess(cls, data: Mapping[str, Any] | None = None) -> dict[str, float]:
        """From the in-phase relative residual r = −R G/(1 + R G) of the tip deflection: G = −r/(R (1 + r))."""
        r_ep = param(data, "R_ep", 1500.0)
        rp = residual(data)
        if rp is None:
            return {"G_leak": 1.0e-5}
        res, pred = rp
        rel = min(regress(res, pred), -1e-3)
        rel = max(rel, -0.9)
        return {"G_leak": cls.fit_range("G_leak").clip(-rel / (r_ep * (1.0 + rel)))}
