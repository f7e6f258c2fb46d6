"""An independent, plain-Python statement of the nominal equations (seed paper Eq. 1–3, our reading).

It is deliberately written the way a user would write it for ``scipy.integrate.solve_ivp`` — one function,
no effect seam — so that (a) the tests can check that the composed, compiled model equals it at random states
and (b) the benchmarks have the honest baseline a user would start from.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

import numpy as np


def nominal_rhs(t: float, x: np.ndarray, u: np.ndarray, prm: Mapping[str, float]) -> np.ndarray:
    """dx/dt of the nominal model with the amplifier terminal. ``u`` = (v_ch1 V, v_ch2 V, z0dd m/s^2)."""
    R, C, d = prm["R_ep"], prm["C_ep"], prm["d_ep"]
    m = np.array([prm["m1"], prm["m2"], prm["m3"]])
    k = np.array([prm["k1"], prm["k2"], prm["k3"]])
    c = np.array([prm["c1"], prm["c2"], prm["c3"]])
    alpha, A, n, beta, gamma = prm["alpha_h"], prm["A_h"], prm["n_h"], prm["beta_h"], prm["gamma_h"]
    delta, ddelta, q, h = x[0:3], x[3:6], x[6:9], x[9:12]
    va = 0.5 * (u[0] - u[1])
    z0dd = u[2]
    theta = k * d
    qh = alpha * q + (1 - alpha) * h
    # section forces and mass chain (z relative to the base)
    s = -k * delta - c * ddelta + theta * qh / C
    a1 = (s[0] - s[1]) / m[0] - z0dd
    a2 = (s[1] - s[2]) / m[1] - z0dd
    a3 = s[2] / m[2] - z0dd
    dddelta = np.array([a1, a2 - a1, a3 - a2])
    # electrics: R (q' + theta delta') = va - q/C
    dq = (va - q / C) / R - theta * ddelta
    # Bouc-Wen
    ah = np.abs(h)
    dh = A * dq - beta * np.abs(dq) * ah ** (n - 1) * h - gamma * dq * ah**n
    return np.concatenate([ddelta, dddelta, dq, dh])


def make_solve_ivp_rhs(prm: dict[str, float], t_u: np.ndarray, u: np.ndarray) -> Callable[[float, np.ndarray],
                                                                                          np.ndarray]:
    """``f(t, x)`` for solve_ivp with inputs ``u[k, :]`` sampled at ``t_u`` and linearly interpolated."""
    u0, u1, u2 = (np.ascontiguousarray(u[:, i]) for i in range(3))

    def f(t: float, x: np.ndarray) -> np.ndarray:
        ut = np.array([np.interp(t, t_u, u0), np.interp(t, t_u, u1), np.interp(t, t_u, u2)])
        return nominal_rhs(t, x, ut, prm)

    return f
