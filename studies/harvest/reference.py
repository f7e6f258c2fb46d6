"""An independent, plain-Python statement of the harvesting model (nominal plant + harvesting terminal + audit).

Written the way a user would write it for ``scipy.integrate.solve_ivp`` — one function, no effect seam, the cell's
curve through scipy's PCHIP — so that the tests can check the compiled terminals (:mod:`plant.effects.harvesting`)
against it at random states, and the harvesting benchmark has the honest baseline a user would start from.
State layout: the 12 core states, then ``bat_qd`` and the 12 audit accumulators in the terminal's order.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

import numpy as np
from scipy.interpolate import PchipInterpolator

from plant.reference import nominal_rhs


class ReferenceCell:
    """The cell of the reference model: PCHIP through the OCV nodes, linear outside [0, q_max]."""

    def __init__(self, q_max: float, taper: float, ocv_nodes: np.ndarray) -> None:
        self.q_max = float(q_max)
        self.taper = float(taper)
        n = len(ocv_nodes)
        q = 0.5 * self.q_max * (1.0 - np.cos(np.pi * np.arange(n) / (n - 1)))  # the terminals' node positions
        self.curve = PchipInterpolator(q, np.asarray(ocv_nodes, dtype=float))
        self.slope = self.curve.derivative()
        self.v_full, self.v_cut = float(ocv_nodes[0]), float(ocv_nodes[-1])
        self.s_full, self.s_cut = float(self.slope(0.0)), float(self.slope(self.q_max))

    def ocv(self, q_d: float) -> float:
        if q_d <= 0.0:
            return self.v_full + self.s_full * q_d
        if q_d >= self.q_max:
            return self.v_cut + self.s_cut * (q_d - self.q_max)
        return float(self.curve(q_d))


def harvest_rhs(t: float, x: np.ndarray, u: np.ndarray, prm: Mapping[str, float], cell: ReferenceCell,
                coupling: str = "coupled") -> np.ndarray:
    """dx/dt of the nominal model with a harvesting terminal (``coupled`` or ``paper``) and the audit states."""
    R, C, d = prm["R_ep"], prm["C_ep"], prm["d_ep"]
    m = np.array([prm["m1"], prm["m2"], prm["m3"]])
    k = np.array([prm["k1"], prm["k2"], prm["k3"]])
    c = np.array([prm["c1"], prm["c2"], prm["c3"]])
    r_int, v_d, i_board = prm["R_bint"], prm["V_diode"], prm["i_board"]
    reverse = coupling == "paper" and prm.get("eq8_reverse", 0.0) > 0.5
    q = x[6:9]
    q_d = x[12]
    # terminal: patches as a Thevenin source mean(q)/C behind R/3 (coupled) or unloaded (paper)
    v_s = q.sum() / (3.0 * C)
    r_s = R / 3.0 if coupling == "coupled" else 0.0
    v_oc = cell.ocv(q_d)
    if reverse:
        i_r = (abs(v_s) - v_oc + r_int * i_board) / (r_s + r_int)
    else:
        i_r = max(0.0, (abs(v_s) - 2.0 * v_d - v_oc + r_int * i_board) / (r_s + r_int))
    if i_r > 0.0:
        i_r *= min(max(q_d / cell.taper, 0.0), 1.0)
    v_a = v_s - np.sign(v_s) * r_s * i_r
    # the plant with that terminal voltage: nominal_rhs takes it as a differential drive (v_ch1 = -v_ch2 = v_a)
    core = nominal_rhs(t, x[:12], np.array([v_a, -v_a, u[2]]), prm)
    ddelta = x[3:6]
    zd = np.cumsum(ddelta)
    theta = k * d
    alpha = prm["alpha_h"]
    qh = alpha * q + (1.0 - alpha) * x[9:12]
    v_c = q / C
    i_rp = (v_a - v_c) / R
    i_bat = i_r - i_board
    v_term = v_oc + r_int * i_bat
    v_in = abs(v_a)
    p_diode = 0.0 if reverse else 2.0 * v_d * i_r
    rates = np.zeros(13)
    rates[0] = -i_bat
    rates[1] = -i_bat if (q_d >= cell.q_max and i_bat < 0.0) else 0.0
    rates[2] = -u[2] * float(m @ zd)  # base power in
    rates[3] = float(c @ ddelta**2)  # damping
    rates[4] = float(np.sum(theta * (qh - q) / C * ddelta))  # Bouc-Wen work
    rates[5] = 0.0  # no other effects in the reference
    rates[6] = float(np.sum((v_a - v_c) * i_rp))  # R_ep
    rates[7] = v_in * i_r
    rates[8] = p_diode
    rates[9] = (v_in * i_r - p_diode) - v_term * i_r
    rates[10] = r_int * i_bat**2
    rates[11] = v_term * i_board
    rates[12] = v_oc * i_bat
    return np.concatenate([core, rates])


def make_solve_ivp_rhs(prm: Mapping[str, float], cell: ReferenceCell, t_u: np.ndarray, z0dd: np.ndarray,
                       coupling: str = "coupled") -> Callable[[float, np.ndarray], np.ndarray]:
    """``f(t, x)`` for solve_ivp with the base acceleration ``z0dd`` sampled at ``t_u`` (linear interpolation)."""
    z = np.ascontiguousarray(z0dd, dtype=float)

    def f(t: float, x: np.ndarray) -> np.ndarray:
        return harvest_rhs(t, x, np.array([0.0, 0.0, np.interp(t, t_u, z)]), prm, cell, coupling)

    return f
