"""Patch R-C: each patch couple is a capacitor C_ep charged through its resistance R_ep."""

from __future__ import annotations

from board_config.parameter_sets import core_parameters
from plant.effect import PhysicalEffect
from plant.layout import B_IR, B_QH, B_VC, X_Q


class PatchRC(PhysicalEffect):
    """R_ep·i_R,i = v_a − q_i/C_ep, and i_R,i adds to q̇_i (the piezo current source takes its share).

    Sets the default effective charge q_hi = q_i (the Bouc-Wen effect, when present, overrides it).
    """

    name = "patch_rc"
    role = "core"
    description = "Patch resistance and capacitance: the R-C charge dynamics (real pole 1/(2π R C))"
    origin = "Seed paper Eq. (1), fourth line; Table 2 R_ep, C_ep"
    parameters = core_parameters("R_ep", "C_ep")

    @staticmethod
    def pre(t, x, p, bus, dx, X, P, B):
        for i in range(3):
            bus[B_VC + i] = x[X_Q + i] / p[P.C_ep]
            bus[B_QH + i] = x[X_Q + i]

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        for i in range(3):
            ir = (bus[B.va] - bus[B_VC + i]) / p[P.R_ep]
            bus[B_IR + i] += ir
            dx[X_Q + i] += ir
