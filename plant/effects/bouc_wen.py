"""Bouc-Wen hysteresis of the patch charge (Eq. 1 last line, Eq. 2)."""

from __future__ import annotations

from plant.effect import Parameter, PhysicalEffect
from plant.layout import B_QH, P_A_H, P_ALPHA_H, P_BETA_H, P_GAMMA_H, P_N_H, X_H, X_Q


class BoucWenHysteresis(PhysicalEffect):
    """ḣ_qi = A_h q̇_i − β_h |q̇_i| |h_qi|^(n−1) h_qi − γ_h q̇_i |h_qi|^n;  q_hi = α_h q_i + (1 − α_h) h_qi."""

    name = "bouc_wen"
    role = "core"
    description = "Bouc-Wen hysteretic charge h_q and effective charge q_h = α q + (1 − α) h"
    origin = "Seed paper Eq. (1)-(2); piezo-ceramic domain switching gives rate-independent hysteresis"
    parameters = (
        Parameter("alpha_h", "1", 0.605, 0.0, 1.0, "Bouc-Wen linearity factor", core_index=P_ALPHA_H),
        Parameter("A_h", "1", -1.0, -float("inf"), float("inf"), "Bouc-Wen dissipation gain", core_index=P_A_H),
        Parameter("n_h", "1", 1.0, 0.0, float("inf"), "Bouc-Wen exponent n", core_index=P_N_H),
        Parameter("beta_h", "C^-n", 8.307, -float("inf"), float("inf"), "Bouc-Wen shape factor",
                  core_index=P_BETA_H),
        Parameter("gamma_h", "C^-n", 0.0, -float("inf"), float("inf"), "Bouc-Wen shape factor",
                  core_index=P_GAMMA_H),
    )

    @staticmethod
    def pre(t, x, p, bus, dx, so, po):
        a = p[P_ALPHA_H]
        for i in range(3):
            bus[B_QH + i] = a * x[X_Q + i] + (1.0 - a) * x[X_H + i]

    @staticmethod
    def post(t, x, p, bus, dx, so, po):
        n = p[P_N_H]
        for i in range(3):
            qd = dx[X_Q + i]
            h = x[X_H + i]
            ah = abs(h)
            hn1 = 1.0 if n == 1.0 else ah ** (n - 1.0)
            dx[X_H + i] += p[P_A_H] * qd - p[P_BETA_H] * abs(qd) * hn1 * h - p[P_GAMMA_H] * qd * hn1 * ah
