"""Harvesting terminals: the patches charge a rechargeable cell through a full-bridge rectifier (seed paper Sec. 3.3).

Two terminal effects share one battery, rectifier and power-audit implementation:

``harvest_coupled`` (the energy-consistent circuit, default of ``shm harvest``)
    The three patch couples (each ``R_ep`` in series with ``C_ep`` and the piezo current source) are in parallel on
    the terminal node ``v_a``; the node feeds a full bridge (drop ``V_diode`` per diode, two diodes conduct), whose
    output charges the cell (Thevenin: open-circuit voltage ``v_oc(q_d)`` from the cell table, in series with
    ``R_bint``) and supplies the board's load current ``i_board``. Kirchhoff at the node, ``sum_i i_R,i = -i_load``
    with ``R_ep i_R,i = v_a - q_i/C_ep``, makes the patches a Thevenin source ``v_s = mean(q_i)/C_ep`` behind
    ``R_s = R_ep/3``; with the bridge that gives the closed form (``i_r`` = bridge output current, ``>= 0``)::

        i_r = max(0, (|v_s| - 2 V_diode - v_oc + R_bint i_board) / (R_s + R_bint)),   v_a = v_s - sign(v_s) R_s i_r

    The charging current is drawn through ``R_ep`` out of the patch capacitors and so acts back on the beam.

``harvest_paper`` (Eq. 8 as written)
    ``v_b + R_bint q_b' = |v_a|`` with ``v_a`` the *open-circuit* patch voltage (the patches are not loaded: the
    terminal is the voltmeter of Fig. 6b). The same closed form with ``R_s = 0``; optionally (``eq8_reverse = 1``)
    without the bridge's blocking, i.e. current flows back out of the cell whenever ``|v_a| < v_b``, as the bare
    equation says. Energy drawn by the cell is not taken from anywhere: the power audit shows it.

Battery (both): the state is the discharged capacity ``q_d`` (C), ``q_d' = i_board - i_r``; the open-circuit voltage
``v_oc(q_d)`` is a monotone cubic (PCHIP) through ``N_OCV_NODES`` values ``bat_ocv_00..`` at Chebyshev-spaced ``q_d``
from 0 (full) to ``bat_q_max`` (cut-off), dense near both knees of the curve, so Eq. 6's
``C_b = -dq_d/dv_b = -1/v_oc'(q_d)``. Capacity limits: a charge controller tapers the charging current to zero over
the last ``bat_taper`` coulombs before full (no charging past full; the voltage it blocks is booked as controller
loss); below the cut-off the cell keeps delivering ``i_board`` (the curve is extrapolated linearly) and the state
``bat_q_below_cutoff`` counts the charge drawn there, so that a run can report it.

Power audit: extra states integrate, with the same integrator as the dynamics, the base power in (relative frame,
``-z0'' sum m_j z_j'``), structural damping, the Bouc-Wen part of the piezo work, the net work of any other added
effects, ``R_ep`` losses, the power into the bridge, diode, controller, ``R_bint`` and board losses, and the
chemical energy into the cell (``integral v_oc i_bat dt``). With the stored mechanical and electrical energy (outputs
``E_mech``, ``E_elec``) the books close to integration accuracy in the coupled circuit (see studies.harvest).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from plant.effect import OutputSpec, Parameter, PhysicalEffect, StateSpec
from plant.layout import (
    B_FM,
    B_I_TERM,
    B_IR,
    B_P_PIEZO,
    B_S,
    B_VA,
    B_VA_DEMAND,
    B_Z0DD,
    B_ZD,
    P_C,
    P_C_EP,
    P_D_EP,
    P_K,
    P_M,
    P_R_EP,
    X_DDELTA,
    X_DELTA,
    X_Q,
)

#: number of open-circuit-voltage nodes (Chebyshev-spaced in discharged capacity, 0 = full ... bat_q_max = cut-off)
N_OCV_NODES = 25

# The helpers below take the slots of the first own state (bat_qd), parameter (R_bint) and output (v_bat) and
# address the rest relative to them: the OCV table is an array of N_OCV_NODES parameters.
# own-parameter indices (relative to the effect's parameter offset po = P.R_bint)
K_R_BINT = 0
K_V_DIODE = 1
K_I_BOARD = 2
K_Q_MAX = 3
K_TAPER = 4
K_OCV = 5
K_EQ8_REVERSE = K_OCV + N_OCV_NODES  # harvest_paper only

# extra-state indices (relative to the effect's state offset so = X.bat_qd)
S_QD = 0  # discharged capacity q_d, C
S_Q_BELOW = 1  # charge drawn while below the cut-off, C
S_E_IN = 2  # base power in, J
S_E_DAMP = 3  # structural damping loss, J
S_E_HYST = 4  # Bouc-Wen part of the piezo work on the laminate (may have either sign), J
S_E_OTHER = 5  # net work of other added effects (mechanical + electrical), J
S_E_REP = 6  # loss in the patch resistances R_ep, J
S_E_RECT_IN = 7  # energy into the bridge (= drawn from the patch terminals), J
S_E_DIODE = 8  # bridge diode loss, J
S_E_CTRL = 9  # charge-controller loss (taper near full), J
S_E_RINT = 10  # loss in the cell's internal resistance, J
S_E_BOARD = 11  # energy delivered to the board load, J
S_E_BAT = 12  # chemical energy into the cell, integral of v_oc * i_bat, J

# extra outputs (relative to the effect's output offset yo = Y.v_bat)
O_V_BAT = 0
O_V_BAT_TERM = 1
O_SOC = 2
O_I_BAT = 3
O_I_RECT = 4
O_P_IN = 5
O_E_MECH = 6
O_E_ELEC = 7


def _default_ocv_nodes() -> tuple[float, float, np.ndarray]:
    """Capacity (C), taper (C) and OCV nodes (V) of the ML2032 table, the defaults of the battery parameters."""
    from board_config.battery import load_battery

    spec = load_battery("ML2032")
    k = np.arange(N_OCV_NODES)
    q = 0.5 * spec.capacity * (1.0 - np.cos(np.pi * k / (N_OCV_NODES - 1)))
    return spec.capacity, 2e-3 * spec.capacity, np.asarray(spec.ocv(q), dtype=float)


_Q_MAX0, _TAPER0, _OCV0 = _default_ocv_nodes()

_COMMON_PARAMETERS: tuple[Parameter, ...] = (
    Parameter("R_bint", "ohm", 1.0, 1e-9, 1e9, "Internal resistance of the cell (Thevenin series resistance)"),
    Parameter("V_diode", "V", 0.0, 0.0, 5.0, "Forward drop of one bridge diode (two conduct); 0 = ideal bridge"),
    Parameter("i_board", "A", 0.0, 0.0, 10.0, "Load current the board draws from the cell terminals"),
    Parameter("bat_q_max", "C", _Q_MAX0, 1e-9, 1e9, "Cell capacity from full to the cut-off voltage"),
    Parameter("bat_taper", "C", _TAPER0, 1e-12, 1e9,
              "Charge before full over which the charge controller tapers the charging current to zero"),
    *(Parameter(f"bat_ocv_{k:02d}", "V", float(_OCV0[k]), 0.0, 100.0,
                f"Open-circuit voltage at node {k}: q_d = bat_q_max (1 - cos(pi {k}/{N_OCV_NODES - 1})) / 2")
      for k in range(N_OCV_NODES)),
)

#: the power audit's energy accumulators (states in J, integrated from 0; the module docstring says what each
#: books), in state order; studies.harvest.audit reads them by these names
ENERGY_ACCUMULATORS: tuple[str, ...] = (
    "E_base_in", "E_damping", "E_hysteresis", "E_other_effects", "E_R_ep", "E_rectifier_in", "E_diodes",
    "E_controller", "E_R_bint", "E_board", "E_battery",
)

_STATES: tuple[StateSpec, ...] = (
    StateSpec("bat_qd", "C", 1.0, 0.0),
    StateSpec("bat_q_below_cutoff", "C", 1e-3, 0.0),
    *(StateSpec(name, "J", 1e-6, 0.0) for name in ENERGY_ACCUMULATORS),
)

_OUTPUTS: tuple[OutputSpec, ...] = (
    OutputSpec("v_bat", "V"),  # open-circuit voltage of the cell
    OutputSpec("v_bat_term", "V"),  # terminal voltage of the cell (v_oc + R_bint i_bat)
    OutputSpec("soc_bat", "1"),  # state of charge, 1 - q_d / q_max
    OutputSpec("i_bat", "A"),  # current into the cell (charging > 0)
    OutputSpec("i_rect", "A"),  # bridge output current
    OutputSpec("p_base_in", "W"),  # instantaneous base power into the laminate
    OutputSpec("E_mech", "J"),  # kinetic + elastic energy of the laminate
    OutputSpec("E_elec", "J"),  # energy in the patch capacitors
)


# ------------------------------------------------------------------------------------------------------------------
# Kernel helpers (numba). They live in this module so that the composed-kernel cache fingerprint covers them.
# ------------------------------------------------------------------------------------------------------------------
@numba.njit(cache=True, nogil=True)
def ocv_node(k, n, q_max):
    """Discharged capacity (C) of OCV node k of n: Chebyshev-spaced, dense near full and near the cut-off knee."""
    return 0.5 * q_max * (1.0 - math.cos(math.pi * k / (n - 1)))


@numba.njit(cache=True, nogil=True)
def _edge_slope(h0, h1, m0, m1):
    d = ((2.0 * h0 + h1) * m0 - h0 * m1) / (h0 + h1)
    if d * m0 <= 0.0:
        return 0.0
    if m0 * m1 <= 0.0 and abs(d) > 3.0 * abs(m0):
        return 3.0 * m0
    return d


@numba.njit(cache=True, nogil=True)
def _node_slope(p, base, n, q_max, k):
    """Monotone (Fritsch-Butland, as scipy's PCHIP) slope dv/dq at node k."""
    if k == 0:
        h0 = ocv_node(1, n, q_max)
        h1 = ocv_node(2, n, q_max) - h0
        return _edge_slope(h0, h1, (p[base + 1] - p[base]) / h0, (p[base + 2] - p[base + 1]) / h1)
    if k == n - 1:
        h0 = q_max - ocv_node(n - 2, n, q_max)
        h1 = ocv_node(n - 2, n, q_max) - ocv_node(n - 3, n, q_max)
        return _edge_slope(h0, h1, (p[base + n - 1] - p[base + n - 2]) / h0,
                           (p[base + n - 2] - p[base + n - 3]) / h1)
    hl = ocv_node(k, n, q_max) - ocv_node(k - 1, n, q_max)
    hr = ocv_node(k + 1, n, q_max) - ocv_node(k, n, q_max)
    dl = (p[base + k] - p[base + k - 1]) / hl
    dr = (p[base + k + 1] - p[base + k]) / hr
    if dl * dr <= 0.0:
        return 0.0
    w1 = 2.0 * hr + hl
    w2 = hr + 2.0 * hl
    return (w1 + w2) / (w1 / dl + w2 / dr)


@numba.njit(cache=True, nogil=True)
def ocv_and_slope(p, base, n, q_max, q):
    """Open-circuit voltage (V) and dv/dq_d (V/C) at discharged capacity ``q`` (C); linear outside [0, q_max]."""
    if q <= 0.0:
        d = _node_slope(p, base, n, q_max, 0)
        return p[base] + d * q, d
    if q >= q_max:
        d = _node_slope(p, base, n, q_max, n - 1)
        return p[base + n - 1] + d * (q - q_max), d
    arg = 1.0 - 2.0 * q / q_max
    arg = min(1.0, max(-1.0, arg))
    k = int(math.acos(arg) * (n - 1) / math.pi)
    k = min(max(k, 0), n - 2)
    while k > 0 and q < ocv_node(k, n, q_max):
        k -= 1
    while k < n - 2 and q > ocv_node(k + 1, n, q_max):
        k += 1
    qa = ocv_node(k, n, q_max)
    h = ocv_node(k + 1, n, q_max) - qa
    s = (q - qa) / h
    v0 = p[base + k]
    v1 = p[base + k + 1]
    m0 = _node_slope(p, base, n, q_max, k) * h
    m1 = _node_slope(p, base, n, q_max, k + 1) * h
    s2 = s * s
    s3 = s2 * s
    v = (2 * s3 - 3 * s2 + 1) * v0 + (s3 - 2 * s2 + s) * m0 + (-2 * s3 + 3 * s2) * v1 + (s3 - s2) * m1
    dv = ((6 * s2 - 6 * s) * v0 + (3 * s2 - 4 * s + 1) * m0 + (-6 * s2 + 6 * s) * v1 + (3 * s2 - 2 * s) * m1) / h
    return v, dv


def ocv_nodes(q_max: float, n: int = 0) -> np.ndarray:
    """The discharged capacities (C) of the OCV nodes (Python side)."""
    n = n or N_OCV_NODES
    return np.array([ocv_node(k, n, float(q_max)) for k in range(n)])


@numba.njit(cache=True, nogil=True)
def bridge_charging_current(v_src, r_src, v_oc, r_int, v_diode, i_board, reverse):
    """Bridge output current (A) of a source ``v_src`` (V) behind ``r_src`` (ohm) into a cell (``v_oc`` V behind
    ``r_int`` ohm) that also supplies ``i_board`` (A); two diodes of drop ``v_diode`` (V) conduct. With ``reverse``
    the bridge does not block (Eq. 8 taken literally: no diodes, current may be negative)."""
    if reverse:
        return (abs(v_src) - v_oc + r_int * i_board) / (r_src + r_int)
    i = (abs(v_src) - 2.0 * v_diode - v_oc + r_int * i_board) / (r_src + r_int)
    return i if i > 0.0 else 0.0


@numba.njit(cache=True, nogil=True)
def _battery_side(x, p, so, po, paper):
    """Solve the terminal: (v_a, v_src, i_r, v_oc, dv_oc/dq, v_term, i_bat) for the current state."""
    c_ep = p[P_C_EP]
    v_src = (x[X_Q] + x[X_Q + 1] + x[X_Q + 2]) / (3.0 * c_ep)
    r_int = p[po + K_R_BINT]
    v_d = p[po + K_V_DIODE]
    i_board = p[po + K_I_BOARD]
    q_max = p[po + K_Q_MAX]
    taper = p[po + K_TAPER]
    q_d = x[so + S_QD]
    v_oc, dv = ocv_and_slope(p, po + K_OCV, N_OCV_NODES, q_max, q_d)
    reverse = False
    r_src = 0.0
    if paper:
        reverse = p[po + K_EQ8_REVERSE] > 0.5
    else:
        r_src = p[P_R_EP] / 3.0
    i_r = bridge_charging_current(v_src, r_src, v_oc, r_int, v_d, i_board, reverse)
    if i_r > 0.0:
        # charge controller: no charging past full (taper over the last `taper` coulombs)
        g = q_d / taper
        if g < 0.0:
            g = 0.0
        elif g > 1.0:
            g = 1.0
        i_r *= g
    v_a = v_src
    if not paper:
        if v_src > 0.0:
            v_a = v_src - r_src * i_r
        elif v_src < 0.0:
            v_a = v_src + r_src * i_r
    i_bat = i_r - i_board
    v_term = v_oc + r_int * i_bat
    return v_a, v_src, i_r, v_oc, dv, v_term, i_bat


@numba.njit(cache=True, nogil=True)
def _pre(x, p, bus, so, po, paper):
    v_a, v_src, i_r, _v_oc, _dv, _v_term, _i_bat = _battery_side(x, p, so, po, paper)
    bus[B_VA_DEMAND] = v_src
    bus[B_VA] = v_a
    if paper:
        bus[B_I_TERM] = 0.0
    elif v_src >= 0.0:
        bus[B_I_TERM] = i_r
    else:
        bus[B_I_TERM] = -i_r


@numba.njit(cache=True, nogil=True)
def _post(x, p, bus, dx, so, po, paper):
    v_a, v_src, i_r, v_oc, _dv, v_term, i_bat = _battery_side(x, p, so, po, paper)
    i_board = p[po + K_I_BOARD]
    q_max = p[po + K_Q_MAX]
    # --- battery ---
    dx[so + S_QD] += -i_bat
    if x[so + S_QD] >= q_max and i_bat < 0.0:
        dx[so + S_Q_BELOW] += -i_bat
    # --- mechanical side ---
    c_ep = p[P_C_EP]
    p_in = 0.0
    p_damp = 0.0
    p_cpl = 0.0
    p_mech = 0.0
    p_elastic = 0.0
    p_rep = 0.0
    p_cap = 0.0
    p_cap_model = 0.0
    for i in range(3):
        dd = x[X_DDELTA + i]
        p_in -= bus[B_Z0DD] * p[P_M + i] * bus[B_ZD + i]
        p_damp += p[P_C + i] * dd * dd
        p_elastic -= p[P_K + i] * x[X_DELTA + i] * dd
        p_mech += bus[B_S + i] * dd + bus[B_FM + i] * bus[B_ZD + i]
        theta = p[P_K + i] * p[P_D_EP]
        v_c = x[X_Q + i] / c_ep
        p_cpl += v_c * theta * dd
        i_rp = bus[B_IR + i]
        p_rep += (bus[B_VA] - v_c) * i_rp
        p_cap += v_c * dx[X_Q + i]
        p_cap_model += v_c * (i_rp - theta * dd)
    p_piezo = bus[B_P_PIEZO]
    p_other = (p_mech - (p_elastic - p_damp + p_piezo)) + (p_cap - p_cap_model)
    dx[so + S_E_IN] += p_in
    dx[so + S_E_DAMP] += p_damp
    dx[so + S_E_HYST] += p_piezo - p_cpl
    dx[so + S_E_OTHER] += p_other
    dx[so + S_E_REP] += p_rep
    # --- bridge and cell ---
    v_in = abs(v_a) if not paper else abs(v_src)
    v_d = p[po + K_V_DIODE]
    reverse = paper and p[po + K_EQ8_REVERSE] > 0.5
    p_diode = 0.0 if reverse else 2.0 * v_d * i_r
    dx[so + S_E_RECT_IN] += v_in * i_r
    dx[so + S_E_DIODE] += p_diode
    dx[so + S_E_CTRL] += (v_in * i_r - p_diode) - v_term * i_r
    dx[so + S_E_RINT] += p[po + K_R_BINT] * i_bat * i_bat
    dx[so + S_E_BOARD] += v_term * i_board
    dx[so + S_E_BAT] += v_oc * i_bat


@numba.njit(cache=True, nogil=True)
def _output(x, p, bus, y, so, po, yo, paper):
    _v_a, _v_src, i_r, v_oc, _dv, v_term, i_bat = _battery_side(x, p, so, po, paper)
    y[yo + O_V_BAT] = v_oc
    y[yo + O_V_BAT_TERM] = v_term
    y[yo + O_SOC] = 1.0 - x[so + S_QD] / p[po + K_Q_MAX]
    y[yo + O_I_BAT] = i_bat
    y[yo + O_I_RECT] = i_r
    p_in = 0.0
    e_mech = 0.0
    e_elec = 0.0
    for i in range(3):
        p_in -= bus[B_Z0DD] * p[P_M + i] * bus[B_ZD + i]
        e_mech += 0.5 * p[P_M + i] * bus[B_ZD + i] ** 2 + 0.5 * p[P_K + i] * x[X_DELTA + i] ** 2
        e_elec += 0.5 * x[X_Q + i] ** 2 / p[P_C_EP]
    y[yo + O_P_IN] = p_in
    y[yo + O_E_MECH] = e_mech
    y[yo + O_E_ELEC] = e_elec


class HarvestCoupled(PhysicalEffect):
    """Patches → full bridge → cell, solved consistently (Σ i_R = −i_load); the charging current damps the beam."""

    name = "harvest_coupled"
    role = "terminal"
    description = ("Harvesting circuit: patches in parallel -> full bridge (diode drop V_diode) -> Thevenin cell "
                   "(OCV table, R_bint) + board load i_board; loads the patches (energy-consistent)")
    origin = ("Seed paper Sec. 3.3, Fig. 8b with Kirchhoff's current law at the patch terminal; "
              "closed-form bridge solution; power audit states")
    signature = "Tip response and stored voltage lower under load than in open circuit (electrical damping)"
    parameters = _COMMON_PARAMETERS
    states = _STATES
    outputs = _OUTPUTS

    @staticmethod
    def pre(t, x, p, bus, dx, X, P, B):
        _pre(x, p, bus, X.bat_qd, P.R_bint, False)

    @staticmethod
    def post(t, x, p, bus, dx, X, P, B):
        _post(x, p, bus, dx, X.bat_qd, P.R_bint, False)

    @staticmethod
    def output(t, x, p, bus, y, X, P, B, Y):
        _output(x, p, bus, y, X.bat_qd, P.R_bint, Y.v_bat, False)


class HarvestPaper(PhysicalEffect):
    """Eq. 8 as written: v_b + R_bint q̇_b = |v_a| with v_a the open-circuit patch voltage (patches not loaded)."""

    name = "harvest_paper"
    role = "terminal"
    description = ("Seed paper Eq. 8 as written: the cell charges from |v_a| of the open-circuit patches, which "
                   "are not loaded (energy is not conserved; the audit shows by how much)")
    origin = "Seed paper Sec. 3.3, Eq. (6)-(8)"
    signature = "Battery charges while the beam and patch voltages are those of open circuit"
    parameters = (
        *_COMMON_PARAMETERS,
        Parameter("eq8_reverse", "1", 0.0, 0.0, 1.0,
                  "1: Eq. 8 literally, no blocking bridge (current flows back out when |v_a| < v_b); 0: bridge"),
    )
    states = _STATES
    outputs = _OUTPUTS

    @staticmethod
    def pre(t, x, p, bus, dx, X, P, B):
        _pre(x, p, bus, X.bat_qd, P.R_bint, True)

    @staticmethod
    def post(t, x, p, bus, dx, X, P, B):
        _post(x, p, bus, dx, X.bat_qd, P.R_bint, True)

    @staticmethod
    def output(t, x, p, bus, y, X, P, B, Y):
        _output(x, p, bus, y, X.bat_qd, P.R_bint, Y.v_bat, True)
