"""Bouc-Wen hysteresis of the patch charge (Eq. 1 last line, Eq. 2)."""

from __future__ import annotations

from board_config.parameter_sets import core_parameters
from plant.effect import PhysicalEffect
from plant.layout import B_QH, X_H, X_Q


class BoucWenHysteresis(PhysicalEffect):
    """ḣ_qi = A_h q̇_i − β_h |q̇_i| |h_qi|^(n−1) h_qi − γ_h q̇_i |h_qi|^n;  q_hi = α_h q_i + (1 − α_h) h_qi."""

    name = "bouc_wen"
    role = "core"
    description = "Bouc-Wen hysteretic charge h_q and effective charge q_h = α q + (1 − α) h"
    origin = "Seed paper Eq. (1)-(2); piezo-ceramic domain switching gives rate-independent hysteresis"
    parameters = core_parameters("alpha_h", "A_h", "n_h", "beta_h", "gamma_h")

    @staticmethod
    def pre(t, x, p, bus, dx, X, P, B):
        a = p[P.alpha_h]
        for i in range(3):
            bus[B_QH + i] = a * x[X_Q + i] + (1.0 - a) * x[X_H + i]

    @staticmethod
    def post(t, x, p, bus, dx, X, P, B):
        if p[P.n_h] == 1.0:
            # n = 1 (the seed's value): |h|^(n-1) = 1 and no power is computed. A test of parameters alone, so the
            # lane form (plant.lanes) runs this branch by itself when every member of a group has n = 1.
            for i in range(3):
                qd = dx[X_Q + i]
                h = x[X_H + i]
                dx[X_H + i] += p[P.A_h] * qd - p[P.beta_h] * abs(qd) * h - p[P.gamma_h] * qd * abs(h)
        else:
            n = p[P.n_h]
            for i in range(3):
                qd = dx[X_Q + i]
                h = x[X_H + i]
                ah = abs(h)
                hn1 = ah ** (n - 1.0)
                dx[X_H + i] += p[P.A_h] * qd - p[P.beta_h] * abs(qd) * hn1 * h - p[P.gamma_h] * qd * hn1 * ah
