"""Output-current limit of the high-voltage amplifier driving the capacitive patches."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from plant.effect import Parameter, PhysicalEffect
from plant.effects.library_support import FitRange, param, series
from plant.layout import B_VC


class AmplifierCurrentLimit(PhysicalEffect):
    r"""The amplifier delivers at most I_max into the three patch couples in parallel.

    The current it sources is Σ_i (v_a − q_i/C_ep)/R_ep = 3 (v_a − v̄_c)/R_ep, so the terminal voltage is
    held within v̄_c ± I_max R_ep / 3 of the mean patch voltage v̄_c:

        v_a = clip(v_demand, v̄_c − I_max R_ep/3, v̄_c + I_max R_ep/3).

    Into a capacitive load this is a slew-rate limit dv̄_c/dt ≤ I_max/(3 C_ep). The neutral value 10 A is above
    anything the rig can draw (1500 V across R_ep/3 = 500 Ω is 3 A), so the default changes nothing. With the
    open-circuit terminal no current flows and the limit never binds.
    """

    name = "amplifier_current_limit"
    description = "High-voltage amplifier output current limit: v_a within v̄_c ± I_max R_ep/3"
    origin = ("High-voltage piezo amplifiers have a current (and hence slew-rate) limit, typically tens to "
              "hundreds of mA; three 10.6 µF patch couples charged through 1.5 kΩ ask for up to 0.6 A on a 300 V "
              "step and ~12 mA on a 600 V / 0.1 Hz sine.")
    signature = ("The drive cannot follow fast changes: after a voltage step the deflection rises along a ramp "
                 "(constant charging current) instead of the R-C exponential, so the residual is a large transient "
                 "of the sign opposite to the step right after it and zero in steady state; in sine tests the "
                 "residual appears where the input rate is largest (zero crossings) and grows with "
                 "amplitude × frequency. Residual versus input rate shows a dead band, then a linear rise.")
    parameters = (
        Parameter("I_max", "A", 10.0, 1.0e-4, 10.0, "Maximum output current of the amplifier into the patches",
                  neutral=10.0, fit=FitRange(1.0e-3, 10.0, log=True), challenge=(0.2, 0.05, 0.008)),
    )
    library_order = 5
    short_name = "amp_limit"

    @staticmethod
    def pre(t, x, p, bus, dx, X, P, B):
        vc = (bus[B_VC] + bus[B_VC + 1] + bus[B_VC + 2]) / 3.0
        band = p[P.I_max] * p[P.R_ep] / 3.0
        va = bus[B.va]
        if va > vc + band:
            bus[B.va] = vc + band
        elif va < vc - band:
            bus[B.va] = vc - band

    @classmethod
    def guess(cls, data: Mapping[str, Any] | None = None) -> dict[str, float]:
        """Half the peak current the current model asks for: 3 max|v_a − v̄_c| / R_ep from the predicted
        patch voltages and the demanded differential voltage."""
        r_ep = param(data, "R_ep", 1500.0)
        v1 = series(data, "inputs", "v_ch1")
        v2 = series(data, "inputs", "v_ch2")
        vps = [series(data, "predicted", f"v_patch{i}") for i in (1, 2, 3)]
        if v1 is None or v2 is None or v2.size != v1.size:
            return {"I_max": 0.05}
        patches = [v for v in vps if v is not None and v.size == v1.size]
        if len(patches) != 3:
            return {"I_max": 0.05}
        va = 0.5 * (v1 - v2)
        vc = (patches[0] + patches[1] + patches[2]) / 3.0
        peak = 3.0 * float(np.max(np.abs(va - vc))) / r_ep
        return {"I_max": cls.fit_range("I_max").clip(0.5 * peak if peak > 0 else 0.05)}
