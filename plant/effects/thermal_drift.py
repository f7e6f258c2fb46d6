"""Temperature drift of the piezoelectric coefficient d_ep during a test."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from plant.effect import Parameter, PhysicalEffect
from plant.effects.library_support import FitRange, param, regress, residual, time_axis
from plant.layout import B_QH, B_S, P_K, X_DDELTA, X_Q


class PiezoThermalDrift(PhysicalEffect):
    r"""d_ep(t) = d_ep [1 + κ_T ΔT(t)] with the patch temperature rising linearly, ΔT(t) = (dT/dt)·t.

    The change of coupling Δθ_i = k_i d_ep κ_T ΔT(t) acts on both sides of the transducer: it adds the force
    Δθ_i q_hi / C_ep to section i and draws the extra piezo current Δθ_i δ̇_i (reciprocal, like the nominal
    coupling). t is the model time, i.e. seconds from the record's time origin. ΔT is clamped to ±100 K.
    Only the product κ_T·dT/dt is identifiable from a record; the workbench fits dT/dt with κ_T at its
    literature value.
    """

    name = "thermal_drift"
    description = "Temperature drift of d_ep: d_ep (1 + κ_T (dT/dt) t)"
    origin = ("The piezoelectric coefficients of PZT-5A fibres rise by ~0.1–0.3 %/K near room temperature; "
              "self-heating of the patches under high-voltage drive (dielectric loss) or a warming rig/bay during "
              "a test changes the actuation authority while the test runs.")
    signature = ("A gain that changes during the record: the residual is proportional to the response (in phase "
                 "with it, same shape as the deflection) and its envelope grows linearly with time since the "
                 "start, with one sign throughout — identical input cycles early and late in the record leave "
                 "different residuals. Spectrum and correlation tests look like a plain gain error; the tell-tale "
                 "is the trend: windows above threshold cluster at the end of the record.")
    parameters = (
        Parameter("dT_dt", "K/s", 0.0, -2.0, 2.0, "Rate of change of the patch temperature during the test",
                  neutral=0.0, fit=FitRange(-2.0, 2.0, linthresh=1e-3), challenge=(0.05, 0.2, 1.0)),
        Parameter("kappa_T", "1/K", 2.5e-3, -0.02, 0.02, "Relative temperature coefficient of d_ep"),
    )
    library_order = 8
    short_name = "thermal"

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        dtemp = p[P.dT_dt] * t
        if dtemp > 100.0:
            dtemp = 100.0
        elif dtemp < -100.0:
            dtemp = -100.0
        rel = p[P.kappa_T] * dtemp
        for i in range(3):
            dtheta = p[P_K + i] * p[P.d_ep] * rel
            bus[B_S + i] += dtheta * bus[B_QH + i] / p[P.C_ep]
            dx[X_Q + i] -= dtheta * x[X_DDELTA + i]

    @classmethod
    def guess(cls, data: Mapping[str, Any] | None = None) -> dict[str, float]:
        """Regress the tip residual on t·z3 (the gain error grows linearly in time): slope/κ_T = dT/dt."""
        kappa = param(data, "kappa_T", 2.5e-3)
        rp = residual(data)
        if rp is None or kappa == 0:
            return {"dT_dt": 0.1}
        res, pred = rp
        t = time_axis(data, pred.size)
        slope = regress(res, t * pred)
        rate = slope / kappa if np.isfinite(slope) else 0.1
        return {"dT_dt": cls.fit_range("dT_dt").clip(rate if rate != 0 else 0.1)}
