"""Batched, compiled integration: Dormand–Prince 5(4) with step-size control, one trajectory per
batch member, batch members in parallel threads (numba ``prange``).

Inputs are sampled on a uniform grid and linearly interpolated (held constant outside it). Outputs
between steps come from the method's 4th-order dense output, so the step size is set by accuracy and stability,
not by the output rate; the last step lands exactly on the final time. Each trajectory has its
own step size; a trajectory that produces a non-finite state or needs a step below ``h_min`` stops
with a status code, filling the rest of its outputs with NaN, without affecting the others.

The integrator is kept as source text (:data:`INTEGRATOR_SOURCE`): :mod:`plant.compose` writes it into a
generated module together with the composed right-hand side, so that numba can cache the compiled
machine code on disk (a composition compiles once per machine, not once per process).
"""

from __future__ import annotations

from enum import IntEnum

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


class IntegrationStatus(IntEnum):
    OK = 0
    DIVERGED = 1  # a state became NaN or infinite
    STEP_TOO_SMALL = 2  # the step-size controller hit h_min
    TOO_MANY_STEPS = 3

    @property
    def message(self) -> str:
        return {
            0: "ok",
            1: "the state became non-finite (the model diverged)",
            2: "the step size fell below its minimum (stiff or discontinuous dynamics)",
            3: "the step budget was exhausted",
        }[int(self)]


class IntegrationFailed(FloatingPointError):
    """An integration stopped early: ``status`` (an :class:`IntegrationStatus`), the first failing batch
    ``member`` and ``t``, the start (s) of the interval in which it stopped (for a batch simulation: the last output
    time it reached). A ``FloatingPointError``, so ``except FloatingPointError`` catches it."""

    def __init__(self, message: str, status: IntegrationStatus | int, member: int, t: float) -> None:
        super().__init__(message)
        self.status = IntegrationStatus(int(status))
        self.member = int(member)
        self.t = float(t)

    def __reduce__(self) -> tuple[type[IntegrationFailed], tuple[str, int, int, float]]:
        # pickled whole (a worker process reports it to the campaign's parent)
        return type(self), (str(self), int(self.status), self.member, self.t)


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


INTEGRATOR_SOURCE = r'''
@numba.njit(cache=CACHE, nogil=True, error_model="numpy", inline="always")
def dense_weights(th):
    # Dormand-Prince dense-output weights at theta = th (x(t + th h) = x + h sum_i q_i k_i; k2 has none)
    th2 = th * th
    th3 = th2 * th
    th4 = th3 * th
    return (th + _P12 * th2 + _P13 * th3 + _P14 * th4, _P32 * th2 + _P33 * th3 + _P34 * th4,
            _P42 * th2 + _P43 * th3 + _P44 * th4, _P52 * th2 + _P53 * th3 + _P54 * th4,
            _P62 * th2 + _P63 * th3 + _P64 * th4, _P72 * th2 + _P73 * th3 + _P74 * th4)


@numba.njit(cache=CACHE, nogil=True, error_model="numpy", inline="always")
def step_to_take(h, remaining):
    # the step to attempt and whether it is the last: a step within 1e-9 of the end lands exactly on it
    if h >= remaining * (1.0 - 1e-9):
        return remaining, True
    return h, False


@numba.njit(cache=CACHE, nogil=True, error_model="numpy", inline="always")
def next_step(h, h_use, log_err, log_err_prev, pi_on, after_reject, last, h_max):
    # the step after an accepted one: PI controller (Gustafsson; Hairer's DOPRI5) once a step has been rejected
    # in this call; before that the elementary controller, which ramps up from the small initial step as fast as
    # before (a rig or stepper restarts every tick: PI from the first step cost ~50 % more attempts per 10 ms)
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


@numba.njit(cache=CACHE, nogil=True, error_model="numpy")
def input_at(u, bu, t, u_t0, u_dt, uvec):
    # unsigned indices: no negative-index wraparound test on each load (the sample index comes from a float,
    # which the compiler cannot prove non-negative); ~5 % per attempted step, same numbers
    m = u.shape[1]
    ub = np.uint64(bu)
    if m == 1:
        for k in range(u.shape[2]):
            uvec[k] = u[ub, np.uint64(0), np.uint64(k)]
        return
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
    for k in range(u.shape[2]):
        kk = np.uint64(k)
        uvec[k] = u[ub, i, kk] * (1.0 - f) + u[ub, i + np.uint64(1), kk] * f


@numba.njit(cache=CACHE, nogil=True, error_model="numpy")
def emit(b, j, t, xo, pb, u, bu, u_t0, u_dt, uvec, bus, dx, yv, y, xs, bs, record_x, record_bus):
    input_at(u, bu, t, u_t0, u_dt, uvec)
    out(t, xo, pb, uvec, bus, dx, yv)
    for k in range(yv.shape[0]):
        y[b, j, k] = yv[k]
    if record_x:
        for k in range(xo.shape[0]):
            xs[b, j, k] = xo[k]
    if record_bus:
        for k in range(N_BUS):
            bs[b, j, k] = bus[k]


@numba.njit(cache=CACHE, nogil=True, error_model="numpy")
def one(b, x0, p, u, u_t0, u_dt, t_out, rtol, atol, h_max, h_min, max_steps,
        y, xs, bs, record_x, record_bus, status, nsteps, nrej, w, bus, uvec, yv):
    # w: (12, N_STATES) work rows, allocated once per chunk (no allocation per member or per step)
    n = N_STATES
    bu = np.int64(0)
    if u.shape[0] > 1:
        bu = np.int64(b)
    x = w[0]
    k1 = w[1]
    k2 = w[2]
    k3 = w[3]
    k4 = w[4]
    k5 = w[5]
    k6 = w[6]
    k7 = w[7]
    xt = w[8]
    xn = w[9]
    xo = w[10]
    dx = w[11]
    for k in range(n):
        x[k] = x0[b, k]
    pb = p[b]
    nout = t_out.shape[0]
    t = t_out[0]
    t_end = t_out[nout - 1]
    emit(b, 0, t, x, pb, u, bu, u_t0, u_dt, uvec, bus, dx, yv, y, xs, bs, record_x, record_bus)
    input_at(u, bu, t, u_t0, u_dt, uvec)
    rhs(t, x, pb, uvec, bus, k1)
    h = min(h_max, 1e-4)
    log_err_prev = _LOG_ERR_FLOOR
    after_reject = False
    pi_on = False
    steps = 0
    rejected = 0
    code = 0
    j = 1
    while j < nout:
        h_use, last = step_to_take(h, t_end - t)
        for k in range(n):
            xt[k] = x[k] + h_use * _A21 * k1[k]
        input_at(u, bu, t + _C2 * h_use, u_t0, u_dt, uvec)
        rhs(t + _C2 * h_use, xt, pb, uvec, bus, k2)
        for k in range(n):
            xt[k] = x[k] + h_use * (_A31 * k1[k] + _A32 * k2[k])
        input_at(u, bu, t + _C3 * h_use, u_t0, u_dt, uvec)
        rhs(t + _C3 * h_use, xt, pb, uvec, bus, k3)
        for k in range(n):
            xt[k] = x[k] + h_use * (_A41 * k1[k] + _A42 * k2[k] + _A43 * k3[k])
        input_at(u, bu, t + _C4 * h_use, u_t0, u_dt, uvec)
        rhs(t + _C4 * h_use, xt, pb, uvec, bus, k4)
        for k in range(n):
            xt[k] = x[k] + h_use * (_A51 * k1[k] + _A52 * k2[k] + _A53 * k3[k] + _A54 * k4[k])
        input_at(u, bu, t + _C5 * h_use, u_t0, u_dt, uvec)
        rhs(t + _C5 * h_use, xt, pb, uvec, bus, k5)
        for k in range(n):
            xt[k] = x[k] + h_use * (_A61 * k1[k] + _A62 * k2[k] + _A63 * k3[k] + _A64 * k4[k]
                                    + _A65 * k5[k])
        t_new = t_end if last else t + h_use
        input_at(u, bu, t_new, u_t0, u_dt, uvec)
        rhs(t_new, xt, pb, uvec, bus, k6)
        for k in range(n):
            xn[k] = x[k] + h_use * (_B1 * k1[k] + _B3 * k3[k] + _B4 * k4[k] + _B5 * k5[k] + _B6 * k6[k])
        rhs(t_new, xn, pb, uvec, bus, k7)
        err2 = 0.0
        total = 0.0
        for k in range(n):
            e = h_use * (_E1 * k1[k] + _E3 * k3[k] + _E4 * k4[k] + _E5 * k5[k] + _E6 * k6[k] + _E7 * k7[k])
            r = e / (atol[k] + rtol * max(abs(x[k]), abs(xn[k])))
            err2 += r * r
            total += xn[k]
        err2 = err2 / n
        steps += 1
        if not (np.isfinite(total) and np.isfinite(err2)):
            # a non-finite state anywhere makes the sum non-finite (one test instead of one per state)
            rejected += 1
            if h_use <= h_min:
                code = 1
                break
            h = h_use * _GROW_MIN
            after_reject = True
            continue
        log_err = 0.5 * np.log(max(err2, 1e-300))
        if err2 <= 1.0:
            # dense output (4th order, Dormand-Prince) for every output time inside (t, t_new]
            while j < nout and t_out[j] <= t_new + 1e-12 * abs(t_new):
                th = (t_out[j] - t) / h_use
                if th >= 1.0:
                    for k in range(n):
                        xo[k] = xn[k]
                else:
                    q1, q3, q4, q5, q6, q7 = dense_weights(th)
                    for k in range(n):
                        xo[k] = x[k] + h_use * (q1 * k1[k] + q3 * k3[k] + q4 * k4[k] + q5 * k5[k] + q6 * k6[k]
                                                + q7 * k7[k])
                emit(b, j, t_out[j], xo, pb, u, bu, u_t0, u_dt, uvec, bus, dx, yv, y, xs, bs, record_x,
                     record_bus)
                j += 1
            t = t_new
            for k in range(n):
                x[k] = xn[k]
                k1[k] = k7[k]
            h = next_step(h, h_use, log_err, log_err_prev, pi_on, after_reject, last, h_max)
            after_reject = False
            log_err_prev = max(log_err, _LOG_ERR_FLOOR)
        else:
            rejected += 1
            after_reject = True
            pi_on = True
            h = h_use * max(_GROW_MIN, _SAFE * np.exp(-_PI_ALPHA * log_err))
            if h < h_min:
                code = 2
                break
        if steps >= max_steps:
            code = 3
            break
    if code != 0:
        for jj in range(j, nout):
            for k in range(y.shape[2]):
                y[b, jj, k] = np.nan
            if record_x:
                for k in range(n):
                    xs[b, jj, k] = np.nan
    else:
        # leave the final state exactly at the end of the interval (the stepper continues from it)
        if record_x:
            for k in range(n):
                xs[b, nout - 1, k] = x[k]
    status[b] = code
    nsteps[b] = steps
    nrej[b] = rejected


@numba.njit(cache=CACHE, nogil=True, error_model="numpy")
def run_chunk_stats(lo, hi, x0, p, u, u_t0, u_dt, t_out, rtol, atol, h_max, h_min, max_steps,
                    y, xs, bs, record_x, record_bus, status, nsteps, nrej):
    # nsteps[b]: attempted steps of member b; nrej[b]: of which rejected
    w = np.empty((12, N_STATES))
    bus = np.zeros(N_BUS)
    uvec = np.zeros(u.shape[2])
    yv = np.zeros(y.shape[2])
    for b in range(lo, hi):
        one(np.int64(b), x0, p, u, u_t0, u_dt, t_out, rtol, atol, h_max, h_min, max_steps,
            y, xs, bs, record_x, record_bus, status, nsteps, nrej, w, bus, uvec, yv)


@numba.njit(cache=CACHE, nogil=True, error_model="numpy")
def run_chunk(lo, hi, x0, p, u, u_t0, u_dt, t_out, rtol, atol, h_max, h_min, max_steps,
              y, xs, bs, record_x, record_bus, status, nsteps):
    nrej = np.empty(max(hi, 1), dtype=np.int64)
    run_chunk_stats(lo, hi, x0, p, u, u_t0, u_dt, t_out, rtol, atol, h_max, h_min, max_steps,
                    y, xs, bs, record_x, record_bus, status, nsteps, nrej)

'''


#: batch members integrated together by the lane integrator (one SIMD register of float64 on AVX-512)
LANES = 16

# The lane integrator: the same Dormand–Prince 5(4) pair, PI controller, dense output and status codes as the
# member-by-member integrator above, for LANES members sharing one step size (the largest step every live member
# accepts: the error norm is the maximum of the members' norms, so each member meets its tolerance at least as
# tightly as alone). All data of a group live in one flat work array W (rows of LANES values, offsets _O_* and the
# lane-form rhs_lanes/out_lanes generated by plant.compose), so every loop over the lanes vectorises. A member
# that fails (non-finite state, step below h_min) is masked out of the error norm from then on and gets NaN
# outputs from where it stopped; the others continue. Padding lanes (the last group of a batch) copy the last
# member and are masked from the start.
LANE_INTEGRATOR_SOURCE = r"""
@numba.njit(cache=CACHE, nogil=True, error_model="numpy")
def lane_inputs(u, b0, nl, t, u_t0, u_dt, W):
    m = u.shape[1]
    i = np.uint64(0)
    f = 0.0
    if m > 1:
        s = (t - u_t0) / u_dt
        if s <= 0.0:
            i = np.uint64(0)
        elif s >= m - 1:
            i = np.uint64(m - 2)
            f = 1.0
        else:
            i = np.uint64(s)
            if i > np.uint64(m - 2):
                i = np.uint64(m - 2)
            f = s - i
    i1 = i + np.uint64(1) if m > 1 else i
    for k in range(u.shape[2]):
        kk = np.uint64(k)
        if u.shape[0] == 1:
            v = u[np.uint64(0), i, kk] * (1.0 - f) + u[np.uint64(0), i1, kk] * f
            for l in range(LANES):
                W[(_O_u + k) * LANES + l] = v
        else:
            for l in range(LANES):
                bl = np.uint64(b0 + min(l, nl - 1))
                W[(_O_u + k) * LANES + l] = u[bl, i, kk] * (1.0 - f) + u[bl, i1, kk] * f


@numba.njit(cache=CACHE, nogil=True, error_model="numpy")
def lane_rhs_into(t, W, dst):
    # rhs at the states in the x rows, into rows dst .. dst + N_STATES
    rhs_lanes(t, W)
    for i in range(N_STATES * LANES):
        W[dst * LANES + i] = W[_O_dx * LANES + i]


@numba.njit(cache=CACHE, nogil=True, error_model="numpy")
def lane_emit(b0, nl, j, t, u, u_t0, u_dt, W, y, xs, bs, record_x, record_bus):
    # the states to emit are in the x rows
    lane_inputs(u, b0, nl, t, u_t0, u_dt, W)
    out_lanes(t, W)
    for l in range(nl):
        b = b0 + l
        for k in range(min(y.shape[2], N_OUTPUTS)):
            y[b, j, k] = W[(_O_y + k) * LANES + l]
        if record_x:
            for k in range(N_STATES):
                xs[b, j, k] = W[(_O_x + k) * LANES + l]
        if record_bus:
            for k in range(N_BUS):
                bs[b, j, k] = W[(_O_bus + k) * LANES + l]


@numba.njit(cache=CACHE, nogil=True, error_model="numpy")
def lane_group(b0, nl, x0, p, u, u_t0, u_dt, t_out, rtol, atol, h_max, h_min, max_steps,
               y, xs, bs, record_x, record_bus, status, nsteps, nrej, W, code, jfail, nonfinite):
    n = N_STATES
    nout = t_out.shape[0]
    n_p = min(p.shape[1], N_PARAMS)
    for i in range(W.shape[0]):
        W[i] = 0.0
    for l in range(LANES):
        b = b0 + min(l, nl - 1)
        for k in range(n_p):
            W[(_O_p + k) * LANES + l] = p[b, k]
        for k in range(n):
            W[(_O_xc + k) * LANES + l] = x0[b, k]
            W[(_O_x + k) * LANES + l] = x0[b, k]
            W[(_O_atol + k) * LANES + l] = atol[k]
        W[_O_alive * LANES + l] = 1.0 if l < nl else 0.0
        code[l] = 0
        jfail[l] = nout
    n_alive = nl
    t = t_out[0]
    t_end = t_out[nout - 1]
    lane_emit(b0, nl, 0, t, u, u_t0, u_dt, W, y, xs, bs, record_x, record_bus)
    lane_inputs(u, b0, nl, t, u_t0, u_dt, W)
    lane_rhs_into(t, W, _O_k1)
    h = min(h_max, 1e-4)
    log_err_prev = _LOG_ERR_FLOOR
    after_reject = False
    pi_on = False
    steps = 0
    rejected = 0
    j = 1
    while j < nout and n_alive > 0:
        h_use, last = step_to_take(h, t_end - t)
        for i in range(n * LANES):
            W[_O_x * LANES + i] = W[_O_xc * LANES + i] + h_use * _A21 * W[_O_k1 * LANES + i]
        lane_inputs(u, b0, nl, t + _C2 * h_use, u_t0, u_dt, W)
        lane_rhs_into(t + _C2 * h_use, W, _O_k2)
        for i in range(n * LANES):
            W[_O_x * LANES + i] = W[_O_xc * LANES + i] + h_use * (_A31 * W[_O_k1 * LANES + i]
                                                                 + _A32 * W[_O_k2 * LANES + i])
        lane_inputs(u, b0, nl, t + _C3 * h_use, u_t0, u_dt, W)
        lane_rhs_into(t + _C3 * h_use, W, _O_k3)
        for i in range(n * LANES):
            W[_O_x * LANES + i] = W[_O_xc * LANES + i] + h_use * (_A41 * W[_O_k1 * LANES + i]
                                                                 + _A42 * W[_O_k2 * LANES + i]
                                                                 + _A43 * W[_O_k3 * LANES + i])
        lane_inputs(u, b0, nl, t + _C4 * h_use, u_t0, u_dt, W)
        lane_rhs_into(t + _C4 * h_use, W, _O_k4)
        for i in range(n * LANES):
            W[_O_x * LANES + i] = W[_O_xc * LANES + i] + h_use * (_A51 * W[_O_k1 * LANES + i]
                                                                 + _A52 * W[_O_k2 * LANES + i]
                                                                 + _A53 * W[_O_k3 * LANES + i]
                                                                 + _A54 * W[_O_k4 * LANES + i])
        lane_inputs(u, b0, nl, t + _C5 * h_use, u_t0, u_dt, W)
        lane_rhs_into(t + _C5 * h_use, W, _O_k5)
        for i in range(n * LANES):
            W[_O_x * LANES + i] = W[_O_xc * LANES + i] + h_use * (_A61 * W[_O_k1 * LANES + i]
                                                                 + _A62 * W[_O_k2 * LANES + i]
                                                                 + _A63 * W[_O_k3 * LANES + i]
                                                                 + _A64 * W[_O_k4 * LANES + i]
                                                                 + _A65 * W[_O_k5 * LANES + i])
        t_new = t_end if last else t + h_use
        lane_inputs(u, b0, nl, t_new, u_t0, u_dt, W)
        lane_rhs_into(t_new, W, _O_k6)
        for i in range(n * LANES):
            v = W[_O_xc * LANES + i] + h_use * (_B1 * W[_O_k1 * LANES + i] + _B3 * W[_O_k3 * LANES + i]
                                               + _B4 * W[_O_k4 * LANES + i] + _B5 * W[_O_k5 * LANES + i]
                                               + _B6 * W[_O_k6 * LANES + i])
            W[_O_xn * LANES + i] = v
            W[_O_x * LANES + i] = v
        lane_rhs_into(t_new, W, _O_k7)
        for l in range(LANES):
            W[_O_err * LANES + l] = 0.0
            W[_O_tot * LANES + l] = 0.0
        for k in range(n):
            for l in range(LANES):
                i = k * LANES + l
                e = h_use * (_E1 * W[_O_k1 * LANES + i] + _E3 * W[_O_k3 * LANES + i] + _E4 * W[_O_k4 * LANES + i]
                             + _E5 * W[_O_k5 * LANES + i] + _E6 * W[_O_k6 * LANES + i]
                             + _E7 * W[_O_k7 * LANES + i])
                xo = W[_O_xc * LANES + i]
                xv = W[_O_xn * LANES + i]
                r = e / (W[_O_atol * LANES + i] + rtol * max(abs(xo), abs(xv)))
                W[_O_err * LANES + l] += r * r
                W[_O_tot * LANES + l] += xv
        steps += 1
        err2 = 0.0
        any_bad = False
        for l in range(nl):
            nonfinite[l] = False
            if W[_O_alive * LANES + l] > 0.0:
                e2 = W[_O_err * LANES + l]
                if not (np.isfinite(e2) and np.isfinite(W[_O_tot * LANES + l])):
                    nonfinite[l] = True
                    any_bad = True
                elif e2 > err2:
                    err2 = e2
        err2 = err2 / n
        if any_bad:
            rejected += 1
            if h_use <= h_min:
                # the members that stay non-finite at the smallest step stop here; the others go on
                for l in range(nl):
                    if nonfinite[l]:
                        W[_O_alive * LANES + l] = 0.0
                        code[l] = 1
                        jfail[l] = j
                        n_alive -= 1
                h = h_use
            else:
                h = h_use * _GROW_MIN
            after_reject = True
            continue
        log_err = 0.5 * np.log(max(err2, 1e-300))
        if err2 <= 1.0:
            while j < nout and t_out[j] <= t_new + 1e-12 * abs(t_new):
                th = (t_out[j] - t) / h_use
                if th >= 1.0:
                    for i in range(n * LANES):
                        W[_O_x * LANES + i] = W[_O_xn * LANES + i]
                else:
                    q1, q3, q4, q5, q6, q7 = dense_weights(th)
                    for i in range(n * LANES):
                        W[_O_x * LANES + i] = W[_O_xc * LANES + i] + h_use * (
                            q1 * W[_O_k1 * LANES + i] + q3 * W[_O_k3 * LANES + i] + q4 * W[_O_k4 * LANES + i]
                            + q5 * W[_O_k5 * LANES + i] + q6 * W[_O_k6 * LANES + i] + q7 * W[_O_k7 * LANES + i])
                lane_emit(b0, nl, j, t_out[j], u, u_t0, u_dt, W, y, xs, bs, record_x, record_bus)
                j += 1
            t = t_new
            for i in range(n * LANES):
                W[_O_xc * LANES + i] = W[_O_xn * LANES + i]
                W[_O_k1 * LANES + i] = W[_O_k7 * LANES + i]
            h = next_step(h, h_use, log_err, log_err_prev, pi_on, after_reject, last, h_max)
            after_reject = False
            log_err_prev = max(log_err, _LOG_ERR_FLOOR)
        else:
            rejected += 1
            after_reject = True
            pi_on = True
            h = h_use * max(_GROW_MIN, _SAFE * np.exp(-_PI_ALPHA * log_err))
            if h < h_min:
                # the members whose error stays above tolerance at the smallest step stop here
                for l in range(nl):
                    if W[_O_alive * LANES + l] > 0.0 and W[_O_err * LANES + l] > n:
                        W[_O_alive * LANES + l] = 0.0
                        code[l] = 2
                        jfail[l] = j
                        n_alive -= 1
                h = h_use
        if steps >= max_steps:
            for l in range(nl):
                if W[_O_alive * LANES + l] > 0.0:
                    W[_O_alive * LANES + l] = 0.0
                    code[l] = 3
                    jfail[l] = j
                    n_alive -= 1
            break
    for l in range(nl):
        b = b0 + l
        if code[l] != 0:
            for jj in range(jfail[l], nout):
                for k in range(y.shape[2]):
                    y[b, jj, k] = np.nan
                if record_x:
                    for k in range(n):
                        xs[b, jj, k] = np.nan
        elif record_x:
            for k in range(n):
                xs[b, nout - 1, k] = W[(_O_xc + k) * LANES + l]
        status[b] = code[l]
        nsteps[b] = steps
        nrej[b] = rejected


@numba.njit(cache=CACHE, nogil=True, error_model="numpy")
def run_lanes(lo, hi, x0, p, u, u_t0, u_dt, t_out, rtol, atol, h_max, h_min, max_steps,
              y, xs, bs, record_x, record_bus, status, nsteps, nrej):
    # members lo .. hi - 1 in groups of LANES (the last group padded). The step budget is per member: a member
    # whose group ran out of steps (the group's steps are its slowest member's) is integrated again alone.
    W = np.zeros(W_ROWS * LANES)
    code = np.zeros(LANES, dtype=np.int64)
    jfail = np.zeros(LANES, dtype=np.int64)
    nonfinite = np.zeros(LANES, dtype=np.bool_)
    w = np.empty((12, N_STATES))
    bus = np.zeros(N_BUS)
    uvec = np.zeros(u.shape[2])
    yv = np.zeros(y.shape[2])
    for b0 in range(lo, hi, LANES):
        nl = min(LANES, hi - b0)
        lane_group(b0, nl, x0, p, u, u_t0, u_dt, t_out, rtol, atol, h_max, h_min, max_steps,
                   y, xs, bs, record_x, record_bus, status, nsteps, nrej, W, code, jfail, nonfinite)
        for l in range(nl):
            if code[l] == 3:
                one(np.int64(b0 + l), x0, p, u, u_t0, u_dt, t_out, rtol, atol, h_max, h_min, max_steps,
                    y, xs, bs, record_x, record_bus, status, nsteps, nrej, w, bus, uvec, yv)
"""


#: names of the constants (tableau and step-size controller) the generated integrator module imports from here
TABLEAU_NAMES: tuple[str, ...] = (
    *(n for n in list(globals()) if n.startswith(("_A", "_B", "_C", "_E", "_P")) and n[2:].isdigit()),
    "_SAFE", "_PI_BETA", "_PI_ALPHA", "_GROW_MAX", "_GROW_MIN", "_LOG_ERR_FLOOR",
)
