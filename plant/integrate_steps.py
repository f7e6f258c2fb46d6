"""The Dormand–Prince 5(4) step both integrators take: tableau, stage formulas, dense output, step-size control.

The member-by-member integrator (:mod:`plant.integrate_scalar`) and the lane integrator
(:mod:`plant.integrate_lanes`) differ only in where their numbers live (rows of one member, or rows of ``LANES``
members in one flat work array); every formula of the step is written once, here, as a function of scalars that
both call per element. They are compiled with ``inline="always"`` (:data:`INLINE`): numba pastes them into the
loops, which then compile as if the formula were written there (same operations in the same order, hence the same
bits, and the lane loops still vectorise).

Like the other templates, these functions are copied into each composition's generated kernel module
(:func:`plant.integrate.kernel_source`), and the tableau and controller constants below are written into it as
literals (:data:`TABLEAU_NAMES`): numba's on-disk cache keys on that file, so a changed constant recompiles.
"""

from __future__ import annotations

import numpy as np

# Dormand–Prince 5(4) tableau
_C2, _C3, _C4, _C5 = 1 / 5, 3 / 10, 4 / 5, 8 / 9
_A21 = 1 / 5
_A31, _A32 = 3 / 40, 9 / 40
_A41, _A42, _A43 = 44 / 45, -56 / 15, 32 / 9
_A51, _A52, _A53, _A54 = 19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729
_A61, _A62, _A63, _A64, _A65 = 9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656
_B1, _B3, _B4, _B5, _B6 = 35 / 384, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84
_E1, _E3, _E4, _E5, _E6, _E7 = (
    71 / 57600, -71 / 16695, 71 / 1920, -17253 / 339200, 22 / 525, -1 / 40,
)
# dense output: x(t + θh) = x + h Σ_i k_i P_i(θ), P_i(θ) = Σ_m P_im θ^m (Hairer's DOPRI5, as in scipy's RK45)
_P12, _P13, _P14 = -8048581381 / 2820520608, 8663915743 / 2820520608, -12715105075 / 11282082432
_P32, _P33, _P34 = 131558114200 / 32700410799, -68118460800 / 10900136933, 87487479700 / 32700410799
_P42, _P43, _P44 = -1754552775 / 470086768, 14199869525 / 1410260304, -10690763975 / 1880347072
_P52, _P53, _P54 = 127303824393 / 49829197408, -318862633887 / 49829197408, 701980252875 / 199316789632
_P62, _P63, _P64 = -282668133 / 205662961, 2019193451 / 616988883, -1453857185 / 822651844
_P72, _P73, _P74 = 40617522 / 29380423, -110615467 / 29380423, 69997945 / 29380423

# Step-size control: Gustafsson's PI controller as in Hairer's DOPRI5 (Hairer, Nørsett & Wanner, Solving ODE I,
# Sec. II.4 and IV.2): h_new = h · clip(SAFE · err^(-PI_ALPHA) · err_prev^(PI_BETA), GROW_MIN, GROW_MAX) with
# PI_ALPHA = 1/5 − 0.75 PI_BETA. The β term damps the step-size oscillation an elementary controller
# (β = 0) shows at the stability limit of an explicit method (here the 102 Hz mode): fewer rejected steps
# at the same tolerance. No growth right after a rejection; a rejected step shrinks by SAFE · err^(-PI_ALPHA)
# (at least GROW_MIN). Until the first rejection of a call the elementary controller (SAFE · err^(-1/5)) ramps
# the step up from its small start.
_SAFE = 0.9
_PI_BETA = 0.08
_PI_ALPHA = 0.2 - 0.75 * _PI_BETA
_GROW_MAX = 5.0
_GROW_MIN = 0.2
_LOG_ERR_FLOOR = -9.210340371976182  # log(1e-4): the previous error enters the controller at least as 1e-4

#: names of the constants (tableau and step-size controller) written into the generated kernel module
TABLEAU_NAMES: tuple[str, ...] = (
    *(n for n in list(globals()) if n.startswith(("_A", "_B", "_C", "_E", "_P")) and n[2:].isdigit()),
    "_SAFE", "_PI_BETA", "_PI_ALPHA", "_GROW_MAX", "_GROW_MIN", "_LOG_ERR_FLOOR",
)


def stage_times(t: float, h: float) -> tuple[float, float, float, float]:
    """The times (s) of stages 2 to 5 of a step of ``h`` from ``t`` (stage 6 and 7 are at its end)."""
    return t + _C2 * h, t + _C3 * h, t + _C4 * h, t + _C5 * h


def stage2(x: float, h: float, k1: float) -> float:
    return x + h * _A21 * k1


def stage3(x: float, h: float, k1: float, k2: float) -> float:
    return x + h * (_A31 * k1 + _A32 * k2)


def stage4(x: float, h: float, k1: float, k2: float, k3: float) -> float:
    return x + h * (_A41 * k1 + _A42 * k2 + _A43 * k3)


def stage5(x: float, h: float, k1: float, k2: float, k3: float, k4: float) -> float:
    return x + h * (_A51 * k1 + _A52 * k2 + _A53 * k3 + _A54 * k4)


def stage6(x: float, h: float, k1: float, k2: float, k3: float, k4: float, k5: float) -> float:
    return x + h * (_A61 * k1 + _A62 * k2 + _A63 * k3 + _A64 * k4 + _A65 * k5)


def solution5(x: float, h: float, k1: float, k3: float, k4: float, k5: float, k6: float) -> float:
    """The 5th-order solution at the end of the step (also the state of stage 7: first same as last)."""
    return x + h * (_B1 * k1 + _B3 * k3 + _B4 * k4 + _B5 * k5 + _B6 * k6)


def error_ratio(h: float, k1: float, k3: float, k4: float, k5: float, k6: float, k7: float, atol: float,
                rtol: float, x_old: float, x_new: float) -> float:
    """One state's error estimate (5th minus 4th order) over its tolerance at the larger of start and end."""
    e = h * (_E1 * k1 + _E3 * k3 + _E4 * k4 + _E5 * k5 + _E6 * k6 + _E7 * k7)
    return e / (atol + rtol * max(abs(x_old), abs(x_new)))


def dense_weights(th: float) -> tuple[float, float, float, float, float, float]:
    """Dormand-Prince dense-output weights at theta = th (x(t + th h) = x + h sum_i q_i k_i; k2 has none)."""
    th2 = th * th
    th3 = th2 * th
    th4 = th3 * th
    return (th + _P12 * th2 + _P13 * th3 + _P14 * th4, _P32 * th2 + _P33 * th3 + _P34 * th4,
            _P42 * th2 + _P43 * th3 + _P44 * th4, _P52 * th2 + _P53 * th3 + _P54 * th4,
            _P62 * th2 + _P63 * th3 + _P64 * th4, _P72 * th2 + _P73 * th3 + _P74 * th4)


def dense_point(x: float, h: float, q: tuple[float, float, float, float, float, float], k1: float, k3: float,
                k4: float, k5: float, k6: float, k7: float) -> float:
    """One state inside the step, from the weights ``q`` of :func:`dense_weights`."""
    q1, q3, q4, q5, q6, q7 = q
    return x + h * (q1 * k1 + q3 * k3 + q4 * k4 + q5 * k5 + q6 * k6 + q7 * k7)


def output_due(t_out: float, t_new: float) -> bool:
    """Whether output time ``t_out`` lies inside the step that ends at ``t_new`` (dense output serves it)."""
    return t_out <= t_new + 1e-12 * abs(t_new)


def step_to_take(h: float, remaining: float) -> tuple[float, bool]:
    """The step to attempt and whether it is the last: a step within 1e-9 of the end lands exactly on it."""
    if h >= remaining * (1.0 - 1e-9):
        return remaining, True
    return h, False


def log_error(err2: float) -> float:
    """log of the error norm from its square (the square of an exact step counts as 1e-300)."""
    return 0.5 * np.log(max(err2, 1e-300))


def next_step(h: float, h_use: float, log_err: float, log_err_prev: float, pi_on: bool, after_reject: bool,
              last: bool, h_max: float) -> float:
    """The step after an accepted one: PI controller (Gustafsson; Hairer's DOPRI5) once a step has been rejected
    in this call; before that the elementary controller, which ramps up from the small initial step as fast as
    before (a rig or stepper restarts every tick: PI from the first step cost ~50 % more attempts per 10 ms)."""
    if pi_on:
        fac = _SAFE * np.exp(_PI_BETA * log_err_prev - _PI_ALPHA * log_err)
    else:
        fac = _SAFE * np.exp(-0.2 * log_err)
    fac = min(_GROW_MAX, max(_GROW_MIN, fac))
    if after_reject and fac > 1.0:
        fac = 1.0
    if last:
        h = max(h, h_use * fac)
    else:
        h = h_use * fac
    return min(h, h_max)


def control_start(h_max: float) -> tuple[float, float, bool, bool]:
    """The controller at the start of a call: (first step: 0.1 ms at most ``h_max``, previous log error: the floor,
    after a rejection: no, PI on: no — the elementary controller until the first rejection)."""
    return min(h_max, 1e-4), _LOG_ERR_FLOOR, False, False


def control_accepted(h: float, h_use: float, log_err: float, log_err_prev: float, pi_on: bool, after_reject: bool,
                     last: bool, h_max: float) -> tuple[float, float, bool]:
    """After an accepted step of ``h_use``: (next step, the log error the next step remembers — at least the floor,
    after a rejection: no)."""
    return (next_step(h, h_use, log_err, log_err_prev, pi_on, after_reject, last, h_max),
            max(log_err, _LOG_ERR_FLOOR), False)


def control_rejected(h_use: float, log_err: float) -> tuple[float, bool, bool]:
    """After a step the error control rejected: (next step, after a rejection: yes, PI on: yes)."""
    return h_use * max(_GROW_MIN, _SAFE * np.exp(-_PI_ALPHA * log_err)), True, True


def step_after_nonfinite(h_use: float) -> float:
    """The step after one that produced a non-finite state."""
    return h_use * _GROW_MIN


def input_position(t: float, m: int, u_t0: float, u_dt: float) -> tuple[np.uint64, float]:
    """Sample index and fraction of time ``t`` (s) on an input grid of ``m >= 2`` samples from ``u_t0`` every
    ``u_dt`` (held constant outside it). Unsigned: no negative-index wraparound test on each load (the index comes
    from a float, which the compiler cannot prove non-negative); ~5 % per attempted step, same numbers."""
    s = (t - u_t0) / u_dt
    if s <= 0.0:
        i = np.uint64(0)
        f = 0.0
    elif s >= m - 1:
        i = np.uint64(m - 2)
        f = 1.0
    else:
        i = np.uint64(s)
        if i > np.uint64(m - 2):
            i = np.uint64(m - 2)
        f = s - i
    return i, f


#: the functions of this module, in the order the kernel module defines them; all inlined where they are called
FUNCTIONS = (stage_times, stage2, stage3, stage4, stage5, stage6, solution5, error_ratio, dense_weights, dense_point,
             output_due, step_to_take, log_error, next_step, control_start, control_accepted, control_rejected,
             step_after_nonfinite, input_position)
INLINE = FUNCTIONS
