"""Compliance of the root clamp: the cantilever is not perfectly built in."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from plant.effect import Parameter, PhysicalEffect, StateSpec
from plant.effects.library_support import FitRange
from plant.layout import B_Z, B_ZD


class RootClampCompliance(PhysicalEffect):
    r"""A compliant clamp under the root section: one more lumped degree of freedom δ0 below the chain.

    The clamp (the clamped length of laminate and the clamp plates, mass m_0) sits on a spring of compliance
    c_r = 1/k_0 with damping c_0 = 2 ζ_0 √(k_0 m_0). Every section rides on it: z_i = δ0 + δ1 + … + δi, and

        m_0 (δ̈0 + z̈0) = S_0 − S_1,   S_0 = −k_0 δ0 − c_0 δ̇0,   δ̈1 = z̈1 − δ̈0,

    with S_1 the root section force (spring, damper, piezo and added forces). At c_r = 0 the clamp is rigid
    (δ0 ≡ 0) and the model is the nominal one. At equilibrium under the internal piezo forces S_1 = 0, so the
    clamp does not change the quasi-static actuation stroke; it lowers the resonances and adds base-excited
    motion.
    """

    name = "root_compliance"
    description = "Compliant root clamp: extra DOF δ0 (m_0, k_0 = 1/c_r, ζ_0) under the root section"
    origin = ("A bolted clamp is never rigid: contact compliance of the clamp plates, bending of the fixture and "
              "slip of the laminate in the clamp let the root deflect and rotate, lowering the bending "
              "resonances (most of all the first) — a classic source of model-to-test frequency error.")
    signature = ("Resonances lower than modelled with the quasi-static stroke unchanged: ringing after a step at "
                 "a lower frequency than the model (the residual beats, its spectrum holds a pair of lines around "
                 "each mode, largest around the first), base-excited responses larger; quasi-static (0.1 Hz) "
                 "tests show almost nothing; no amplitude dependence.")
    parameters = (
        # fit range from 1e-4 m/N: below it the clamp mode (> 350 Hz) stiffens the integration and moves the bending
        # modes by < 0.2 %
        Parameter("clamp_compliance", "m/N", 0.0, 0.0, 0.05, "Compliance of the root clamp, 1/k_0", neutral=0.0,
                  fit=FitRange(1.0e-4, 2.0e-2, log=True), challenge=(1e-3, 4e-3, 1.5e-2)),
        Parameter("m_clamp", "kg", 2.0e-3, 1.0e-4, 0.1, "Mass moving with the clamp"),
        Parameter("zeta_clamp", "1", 0.05, 0.0, 1.0, "Damping ratio of the clamp spring on its own mass"),
    )
    states = (StateSpec("delta0", "m", 1e-4), StateSpec("ddelta0", "m/s", 1e-2))
    library_order = 7
    short_name = "root_compl"

    @staticmethod
    def pre(t, x, p, bus, dx, X, P, B):
        d0 = x[X.delta0]
        v0 = x[X.ddelta0]
        for i in range(3):
            bus[B_Z + i] += d0
            bus[B_ZD + i] += v0

    @staticmethod
    def post(t, x, p, bus, dx, X, P, B):
        if p[P.clamp_compliance] <= 0.0:  # a rigid clamp (a test of a parameter alone: see plant.lanes)
            dx[X.delta0] = 0.0
            dx[X.ddelta0] = 0.0
        else:
            cr = p[P.clamp_compliance]
            m0 = p[P.m_clamp]
            k0 = 1.0 / cr
            c0 = 2.0 * p[P.zeta_clamp] * math.sqrt(k0 * m0)
            s0 = -k0 * x[X.delta0] - c0 * x[X.ddelta0]
            a0 = (s0 - bus[B.s1]) / m0 - bus[B.z0dd]
            dx[X.delta0] = x[X.ddelta0]
            dx[X.ddelta0] = a0
            dx[X.ddelta1] -= a0

    @classmethod
    def guess(cls, data: Mapping[str, Any] | None = None) -> dict[str, float]:
        """Half the root section's own compliance (1/(2 k1)) — a clamp about twice as stiff as the root."""
        k1 = 332.98
        if data and isinstance(data.get("params"), Mapping):
            k1 = float(data["params"].get("k1", k1))
        return {"clamp_compliance": cls.fit_range("clamp_compliance").clip(0.5 / k1)}
