"""Electromechanical coupling of the patches with the laminate sections."""

from __future__ import annotations

from board_config.parameter_sets import core_parameters
from plant.effect import PhysicalEffect
from plant.layout import B_QH, B_S, P_K, X_DDELTA, X_Q


class PiezoCoupling(PhysicalEffect):
    """Force θ_i q_hi / C_ep on section i, and the piezo current θ_i δ̇_i drawn from q̇_i (θ_i = k_i d_ep)."""

    name = "piezo_coupling"
    role = "core"
    description = "Piezo force θ q_h / C on each section and back-coupling current θ δ̇, θ_i = k_i d_ep"
    origin = "Seed paper Eq. (1): terms k_i d_ep q_hi / C_ep and R_ep k_i d_ep δ̇_i"
    parameters = core_parameters("d_ep")

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        for i in range(3):
            theta = p[P_K + i] * p[P.d_ep]
            force = theta * bus[B_QH + i] / p[P.C_ep]
            bus[B_S + i] += force
            bus[B.p_piezo] += force * x[X_DDELTA + i]
            dx[X_Q + i] -= theta * x[X_DDELTA + i]
