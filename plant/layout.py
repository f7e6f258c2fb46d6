"""Fixed layout of the core state vector, core parameter block, inputs and signal bus.

Every effect kernel may use these constants (they are plain module-level integers, so numba folds
them). Extra states and parameters of added effects come after the core blocks, at offsets the model
passes to the kernel (``so`` for states, ``po`` for parameters).

State vector ``x`` (SI units):

====== ======================= =====
index  symbol                  unit
====== ======================= =====
0..2   δ1..δ3 bending defl.    m
3..5   δ̇1..δ̇3                  m/s
6..8   q1..q3 linear charge    C
9..11  h_q1..h_q3 Bouc-Wen     C
====== ======================= =====
"""

from __future__ import annotations

from board_config.parameter_sets import CORE_INDEX as _CORE_INDEX

N_SECTIONS = 3

# --- core states -----------------------------------------------------------------------------------
X_DELTA = 0  # δ_i at X_DELTA + i (m)
X_DDELTA = 3  # δ̇_i at X_DDELTA + i (m/s)
X_Q = 6  # q_i at X_Q + i (C)
X_H = 9  # h_qi at X_H + i (C)
N_CORE_STATES = 12
CORE_STATE_NAMES: tuple[str, ...] = (
    "delta1", "delta2", "delta3",
    "ddelta1", "ddelta2", "ddelta3",
    "q1", "q2", "q3",
    "hq1", "hq2", "hq3",
)
CORE_STATE_UNITS: tuple[str, ...] = ("m",) * 3 + ("m/s",) * 3 + ("C",) * 6

# --- core parameters: indices from the one schema, board_config.CORE_PARAMETERS (plain ints, folded by numba) ----
P_R_EP: int = _CORE_INDEX["R_ep"]
P_C_EP: int = _CORE_INDEX["C_ep"]
P_D_EP: int = _CORE_INDEX["d_ep"]
P_M: int = _CORE_INDEX["m1"]  # m_i at P_M + i
P_K: int = _CORE_INDEX["k1"]  # k_i at P_K + i
P_C: int = _CORE_INDEX["c1"]  # c_i at P_C + i
P_ALPHA_H: int = _CORE_INDEX["alpha_h"]
P_A_H: int = _CORE_INDEX["A_h"]
P_N_H: int = _CORE_INDEX["n_h"]
P_BETA_H: int = _CORE_INDEX["beta_h"]
P_GAMMA_H: int = _CORE_INDEX["gamma_h"]
N_CORE_PARAMS: int = len(_CORE_INDEX)
if any(_CORE_INDEX[f"{s}{i + 1}"] != base + i for s, base in (("m", P_M), ("k", P_K), ("c", P_C))
       for i in range(N_SECTIONS)):
    raise ImportError("board_config.CORE_PARAMETERS must list m1..m3, k1..k3 and c1..c3 consecutively")

# --- inputs ----------------------------------------------------------------------------------------
U_V_CH1 = 0  # channel-1 voltage (patches of side 1), V
U_V_CH2 = 1  # channel-2 voltage (patches of side 2), V
U_Z0DD = 2  # base acceleration, m/s^2
N_INPUTS = 3
INPUT_NAMES: tuple[str, ...] = ("v_ch1", "v_ch2", "z0dd")
INPUT_UNITS: tuple[str, ...] = ("V", "V", "m/s^2")

# --- signal bus: named intermediate signals shared by the effect kernels ---------------------------
B_T = 0  # time, s
B_U_V1 = 1  # channel voltages as commanded by the input, V
B_U_V2 = 2
B_Z0DD = 3  # base acceleration, m/s^2
B_VA_DEMAND = 4  # differential drive demanded: (v_ch1 - v_ch2)/2, V
B_VA = 5  # terminal voltage applied to / produced by each patch couple, V
B_VC = 6  # capacitor voltage q_i/C_ep at B_VC + i, V
B_QH = 9  # effective (hysteretic) charge q_hi at B_QH + i, C
B_S = 12  # internal force of section i (spring + damper + piezo + added), N, at B_S + i
B_FM = 15  # external force on mass i (positive along z), N, at B_FM + i
B_IR = 18  # current through R_ep into patch couple i, A, at B_IR + i
B_Z = 21  # absolute section displacement relative to the base z_i, m, at B_Z + i
B_ZD = 24  # velocity of mass i relative to the base, m/s, at B_ZD + i
B_I_TERM = 27  # current leaving the patch terminals into an external load, A
B_P_PIEZO = 28  # mechanical power delivered by the piezo forces to the laminate, W
B_USER = 32  # first of the slots free for added effects (B_USER .. N_BUS-1)
N_BUS = 48
BUS_NAMES: dict[int, str] = {
    B_T: "t", B_U_V1: "v_ch1", B_U_V2: "v_ch2", B_Z0DD: "z0dd", B_VA_DEMAND: "va_demand", B_VA: "va",
    B_VC: "vc1", B_VC + 1: "vc2", B_VC + 2: "vc3", B_QH: "qh1", B_QH + 1: "qh2", B_QH + 2: "qh3",
    B_S: "s1", B_S + 1: "s2", B_S + 2: "s3", B_FM: "fm1", B_FM + 1: "fm2", B_FM + 2: "fm3",
    B_IR: "ir1", B_IR + 1: "ir2", B_IR + 2: "ir3", B_Z: "z1", B_Z + 1: "z2", B_Z + 2: "z3",
    B_ZD: "zd1", B_ZD + 1: "zd2", B_ZD + 2: "zd3", B_I_TERM: "i_term", B_P_PIEZO: "p_piezo",
}

# --- outputs ---------------------------------------------------------------------------------------
Y_Z = 0  # z1..z3, m
Y_DELTA = 3  # δ1..δ3, m
Y_Q = 6  # q1..q3, C
Y_QH = 9  # q_h1..q_h3, C
Y_VPATCH = 12  # patch (capacitor) voltages q_i/C_ep, V
Y_VSTORED = 15  # terminal ("stored") voltage, V
Y_Z3_MEAS = 16  # tip displacement as the laser sensor reports it, m (= z3 unless a sensor effect acts)
N_CORE_OUTPUTS = 17
CORE_OUTPUT_NAMES: tuple[str, ...] = (
    "z1", "z2", "z3", "delta1", "delta2", "delta3", "q1", "q2", "q3", "qh1", "qh2", "qh3",
    "v_patch1", "v_patch2", "v_patch3", "v_stored", "z3_meas",
)
CORE_OUTPUT_UNITS: tuple[str, ...] = ("m",) * 6 + ("C",) * 6 + ("V",) * 4 + ("m",)
