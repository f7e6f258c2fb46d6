"""The lane integrator: the Dormand–Prince 5(4) step of :mod:`plant.integrate_steps` for ``LANES`` batch members
sharing one step size, SIMD across members.

The same pair, PI controller, dense output and status codes as the member-by-member integrator
(:mod:`plant.integrate_scalar`), for ``LANES`` members at once: the step is the largest every live member accepts
(the error norm is the maximum of the members' norms, so each member meets its tolerance at least as tightly as
alone). All data of a group live in one flat work array ``W`` (rows of ``LANES`` values at ``ROW_*``, and the lane
forms ``rhs_lanes``/``out_lanes`` of the composition's hooks, all bound in its generated kernel module:
:mod:`plant.integrate_kernel_names`), so every loop over the lanes vectorises. A member that fails (non-finite
state, step below ``h_min``) is masked out of the error norm from then on and gets NaN outputs from where it
stopped; the others continue. Padding lanes (the last group of a batch) copy the last member and are masked from
the start.

Entry point: ``run_lanes`` (members ``lo .. hi - 1`` in groups of ``LANES``).
"""

from __future__ import annotations

import numpy as np

from plant.integrate_kernel_names import (
    LANES,
    N_BUS,
    N_OUTPUTS,
    N_PARAMS,
    N_STATES,
    W_ROWS,
    Array3,
    BoolVector,
    IntVector,
    Matrix,
    ROW_alive,
    ROW_atol,
    ROW_bus,
    ROW_dx,
    ROW_err,
    ROW_k1,
    ROW_k2,
    ROW_k3,
    ROW_k4,
    ROW_k5,
    ROW_k6,
    ROW_k7,
    ROW_p,
    ROW_tot,
    ROW_u,
    ROW_x,
    ROW_xc,
    ROW_xn,
    ROW_y,
    Vector,
    out_lanes,
    rhs_lanes,
)
from plant.integrate_scalar import nan_from, one
from plant.integrate_steps import (
    control_accepted,
    control_rejected,
    control_start,
    dense_point,
    dense_weights,
    error_ratio,
    input_position,
    log_error,
    output_due,
    solution5,
    stage2,
    stage3,
    stage4,
    stage5,
    stage6,
    stage_times,
    step_after_nonfinite,
    step_to_take,
)


def lane_inputs(u: Array3, b0: int, nl: int, t: float, u_t0: float, u_dt: float, W: Vector) -> None:
    """The inputs of members ``b0 .. b0 + nl - 1`` (padding lanes: the last) at time ``t`` into the ``ROW_u``
    rows."""
    m = u.shape[1]
    i = np.uint64(0)
    f = 0.0
    if m > 1:
        i, f = input_position(t, m, u_t0, u_dt)
    i1 = i + np.uint64(1) if m > 1 else i
    for k in range(u.shape[2]):
        kk = np.uint64(k)
        if u.shape[0] == 1:
            v = u[np.uint64(0), i, kk] * (1.0 - f) + u[np.uint64(0), i1, kk] * f
            for l in range(LANES):
                W[(ROW_u + k) * LANES + l] = v
        else:
            for l in range(LANES):
                bl = np.uint64(b0 + min(l, nl - 1))
                W[(ROW_u + k) * LANES + l] = u[bl, i, kk] * (1.0 - f) + u[bl, i1, kk] * f


def lane_rhs_into(t: float, W: Vector, dst: int) -> None:
    """The right-hand side at the states in the ``ROW_x`` rows, into rows ``dst .. dst + N_STATES``."""
    rhs_lanes(t, W)
    for i in range(N_STATES * LANES):
        W[dst * LANES + i] = W[ROW_dx * LANES + i]


def lane_emit(b0: int, nl: int, j: int, t: float, u: Array3, u_t0: float, u_dt: float, W: Vector, y: Array3,
              xs: Array3, bs: Array3, record_x: bool, record_bus: bool) -> None:
    """Output ``j`` of the group's members at time ``t``, from the states in the ``ROW_x`` rows."""
    lane_inputs(u, b0, nl, t, u_t0, u_dt, W)
    out_lanes(t, W)
    for l in range(nl):
        b = b0 + l
        for k in range(min(y.shape[2], N_OUTPUTS)):
            y[b, j, k] = W[(ROW_y + k) * LANES + l]
        if record_x:
            for k in range(N_STATES):
                xs[b, j, k] = W[(ROW_x + k) * LANES + l]
        if record_bus:
            for k in range(N_BUS):
                bs[b, j, k] = W[(ROW_bus + k) * LANES + l]


def lane_start(b0: int, nl: int, x0: Matrix, p: Matrix, atol: Vector, nout: int, W: Vector, code: IntVector,
               jfail: IntVector) -> None:
    """Load the group's parameters, start states and tolerances into ``W``; padding lanes are masked out."""
    n_p = min(p.shape[1], N_PARAMS)
    for i in range(W.shape[0]):
        W[i] = 0.0
    for l in range(LANES):
        b = b0 + min(l, nl - 1)
        for k in range(n_p):
            W[(ROW_p + k) * LANES + l] = p[b, k]
        for k in range(N_STATES):
            W[(ROW_xc + k) * LANES + l] = x0[b, k]
            W[(ROW_x + k) * LANES + l] = x0[b, k]
            W[(ROW_atol + k) * LANES + l] = atol[k]
        W[ROW_alive * LANES + l] = 1.0 if l < nl else 0.0
        code[l] = 0
        jfail[l] = nout


def lane_attempt(t: float, h_use: float, t_new: float, b0: int, nl: int, u: Array3, u_t0: float, u_dt: float,
                 W: Vector, rtol: float) -> None:
    """One step of ``h_use`` from ``t`` for every lane (start states in the ``ROW_xc`` rows, their derivatives in
    ``ROW_k1``): the stages, the 5th-order solution (``ROW_xn``, also in ``ROW_x``) and per lane the squared error
    sum (``ROW_err``) and the sum of the new states (``ROW_tot``)."""
    n = N_STATES
    x, xc, k1, k2, k3 = ROW_x * LANES, ROW_xc * LANES, ROW_k1 * LANES, ROW_k2 * LANES, ROW_k3 * LANES
    k4, k5, k6, k7, xn = ROW_k4 * LANES, ROW_k5 * LANES, ROW_k6 * LANES, ROW_k7 * LANES, ROW_xn * LANES
    t2, t3, t4, t5 = stage_times(t, h_use)
    for i in range(n * LANES):
        W[x + i] = stage2(W[xc + i], h_use, W[k1 + i])
    lane_inputs(u, b0, nl, t2, u_t0, u_dt, W)
    lane_rhs_into(t2, W, ROW_k2)
    for i in range(n * LANES):
        W[x + i] = stage3(W[xc + i], h_use, W[k1 + i], W[k2 + i])
    lane_inputs(u, b0, nl, t3, u_t0, u_dt, W)
    lane_rhs_into(t3, W, ROW_k3)
    for i in range(n * LANES):
        W[x + i] = stage4(W[xc + i], h_use, W[k1 + i], W[k2 + i], W[k3 + i])
    lane_inputs(u, b0, nl, t4, u_t0, u_dt, W)
    lane_rhs_into(t4, W, ROW_k4)
    for i in range(n * LANES):
        W[x + i] = stage5(W[xc + i], h_use, W[k1 + i], W[k2 + i], W[k3 + i], W[k4 + i])
    lane_inputs(u, b0, nl, t5, u_t0, u_dt, W)
    lane_rhs_into(t5, W, ROW_k5)
    for i in range(n * LANES):
        W[x + i] = stage6(W[xc + i], h_use, W[k1 + i], W[k2 + i], W[k3 + i], W[k4 + i], W[k5 + i])
    lane_inputs(u, b0, nl, t_new, u_t0, u_dt, W)
    lane_rhs_into(t_new, W, ROW_k6)
    for i in range(n * LANES):
        v = solution5(W[xc + i], h_use, W[k1 + i], W[k3 + i], W[k4 + i], W[k5 + i], W[k6 + i])
        W[xn + i] = v
        W[x + i] = v
    lane_rhs_into(t_new, W, ROW_k7)
    for l in range(LANES):
        W[ROW_err * LANES + l] = 0.0
        W[ROW_tot * LANES + l] = 0.0
    for k in range(n):
        for l in range(LANES):
            i = k * LANES + l
            r = error_ratio(h_use, W[k1 + i], W[k3 + i], W[k4 + i], W[k5 + i], W[k6 + i], W[k7 + i],
                            W[ROW_atol * LANES + i], rtol, W[xc + i], W[xn + i])
            W[ROW_err * LANES + l] += r * r
            W[ROW_tot * LANES + l] += W[xn + i]


def lane_error_norm(nl: int, W: Vector, nonfinite: BoolVector) -> tuple[float, bool]:
    """The group's squared error norm (the largest of its live members') and whether a live member's new state is
    non-finite (those are marked in ``nonfinite``)."""
    err2 = 0.0
    any_bad = False
    for l in range(nl):
        nonfinite[l] = False
        if W[ROW_alive * LANES + l] > 0.0:
            e2 = W[ROW_err * LANES + l]
            if not (np.isfinite(e2) and np.isfinite(W[ROW_tot * LANES + l])):
                nonfinite[l] = True
                any_bad = True
            elif e2 > err2:
                err2 = e2
    return err2 / N_STATES, any_bad


def lane_dense_outputs(b0: int, nl: int, j: int, t: float, t_new: float, h_use: float, t_out: Vector, u: Array3,
                       u_t0: float, u_dt: float, W: Vector, y: Array3, xs: Array3, bs: Array3, record_x: bool,
                       record_bus: bool) -> int:
    """Emit every output time inside the accepted step ``(t, t_new]`` from the dense output, starting at output
    ``j``; returns the next output index."""
    x, xc, k1, k3, k4 = ROW_x * LANES, ROW_xc * LANES, ROW_k1 * LANES, ROW_k3 * LANES, ROW_k4 * LANES
    k5, k6, k7, xn = ROW_k5 * LANES, ROW_k6 * LANES, ROW_k7 * LANES, ROW_xn * LANES
    nout = t_out.shape[0]
    while j < nout and output_due(t_out[j], t_new):
        th = (t_out[j] - t) / h_use
        if th >= 1.0:
            for i in range(N_STATES * LANES):
                W[x + i] = W[xn + i]
        else:
            q = dense_weights(th)
            for i in range(N_STATES * LANES):
                W[x + i] = dense_point(W[xc + i], h_use, q, W[k1 + i], W[k3 + i], W[k4 + i], W[k5 + i], W[k6 + i],
                                       W[k7 + i])
        lane_emit(b0, nl, j, t_out[j], u, u_t0, u_dt, W, y, xs, bs, record_x, record_bus)
        j += 1
    return j


def lane_stop(nl: int, W: Vector, selected: BoolVector, code: IntVector, jfail: IntVector, j: int, status: int
              ) -> int:
    """Stop the live members ``selected`` with ``status`` at output ``j`` (masked out from now on); returns how
    many stopped."""
    stopped = 0
    for l in range(nl):
        if selected[l] and W[ROW_alive * LANES + l] > 0.0:
            W[ROW_alive * LANES + l] = 0.0
            code[l] = status
            jfail[l] = j
            stopped += 1
    return stopped


def lane_finish(b0: int, nl: int, nout: int, W: Vector, code: IntVector, jfail: IntVector, y: Array3, xs: Array3,
                record_x: bool, status: IntVector, nsteps: IntVector, nrej: IntVector, steps: int, rejected: int
                ) -> None:
    """NaN outputs (and states) of each stopped member from where it stopped, the final states of the others
    exactly at the end; statuses and the group's step counts."""
    for l in range(nl):
        b = b0 + l
        if code[l] != 0:
            nan_from(b, jfail[l], nout, y, xs, record_x)
        elif record_x:
            for k in range(N_STATES):
                xs[b, nout - 1, k] = W[(ROW_xc + k) * LANES + l]
        status[b] = code[l]
        nsteps[b] = steps
        nrej[b] = rejected


def lane_accept(W: Vector) -> None:
    """After an accepted step: its end becomes the next step's start (state and derivative, first same as last)."""
    for i in range(N_STATES * LANES):
        W[ROW_xc * LANES + i] = W[ROW_xn * LANES + i]
        W[ROW_k1 * LANES + i] = W[ROW_k7 * LANES + i]


def lane_group(b0: int, nl: int, x0: Matrix, p: Matrix, u: Array3, u_t0: float, u_dt: float, t_out: Vector,
               rtol: float, atol: Vector, h_max: float, h_min: float, max_steps: int, y: Array3, xs: Array3,
               bs: Array3, record_x: bool, record_bus: bool, status: IntVector, nsteps: IntVector, nrej: IntVector,
               W: Vector, code: IntVector, jfail: IntVector, stopping: BoolVector) -> None:
    """Integrate members ``b0 .. b0 + nl - 1`` (``nl <= LANES``) over ``t_out`` with one shared step size; ``W``,
    ``code``, ``jfail`` and ``stopping`` are work arrays of the chunk."""
    nout = t_out.shape[0]
    lane_start(b0, nl, x0, p, atol, nout, W, code, jfail)
    n_alive = nl
    t = t_out[0]
    t_end = t_out[nout - 1]
    lane_emit(b0, nl, 0, t, u, u_t0, u_dt, W, y, xs, bs, record_x, record_bus)
    lane_inputs(u, b0, nl, t, u_t0, u_dt, W)
    lane_rhs_into(t, W, ROW_k1)
    h, log_err_prev, after_reject, pi_on = control_start(h_max)
    steps = 0
    rejected = 0
    j = 1
    while j < nout and n_alive > 0:
        h_use, last = step_to_take(h, t_end - t)
        t_new = t_end if last else t + h_use
        lane_attempt(t, h_use, t_new, b0, nl, u, u_t0, u_dt, W, rtol)
        steps += 1
        err2, any_bad = lane_error_norm(nl, W, stopping)
        if any_bad:
            rejected += 1
            if h_use <= h_min:
                # the members that stay non-finite at the smallest step stop here; the others go on
                n_alive -= lane_stop(nl, W, stopping, code, jfail, j, 1)
                h = h_use
            else:
                h = step_after_nonfinite(h_use)
            after_reject = True
            continue
        log_err = log_error(err2)
        if err2 <= 1.0:
            j = lane_dense_outputs(b0, nl, j, t, t_new, h_use, t_out, u, u_t0, u_dt, W, y, xs, bs, record_x,
                                   record_bus)
            t = t_new
            lane_accept(W)
            h, log_err_prev, after_reject = control_accepted(h, h_use, log_err, log_err_prev, pi_on, after_reject,
                                                             last, h_max)
        else:
            rejected += 1
            h, after_reject, pi_on = control_rejected(h_use, log_err)
            if h < h_min:
                # the members whose error stays above tolerance at the smallest step stop here
                for l in range(nl):
                    stopping[l] = W[ROW_err * LANES + l] > N_STATES
                n_alive -= lane_stop(nl, W, stopping, code, jfail, j, 2)
                h = h_use
        if steps >= max_steps:
            stopping[:] = True
            n_alive -= lane_stop(nl, W, stopping, code, jfail, j, 3)
            break
    lane_finish(b0, nl, nout, W, code, jfail, y, xs, record_x, status, nsteps, nrej, steps, rejected)


def run_lanes(lo: int, hi: int, x0: Matrix, p: Matrix, u: Array3, u_t0: float, u_dt: float, t_out: Vector,
              rtol: float, atol: Vector, h_max: float, h_min: float, max_steps: int, y: Array3, xs: Array3,
              bs: Array3, record_x: bool, record_bus: bool, status: IntVector, nsteps: IntVector, nrej: IntVector
              ) -> None:
    """Members ``lo .. hi - 1`` in groups of ``LANES`` (the last group padded). The step budget is per member: a
    member whose group ran out of steps (the group's steps are its slowest member's) is integrated again alone."""
    W = np.zeros(W_ROWS * LANES)
    code = np.zeros(LANES, dtype=np.int64)
    jfail = np.zeros(LANES, dtype=np.int64)
    stopping = np.zeros(LANES, dtype=np.bool_)
    w = np.empty((12, N_STATES))
    bus = np.zeros(N_BUS)
    uvec = np.zeros(u.shape[2])
    yv = np.zeros(y.shape[2])
    for b0 in range(lo, hi, LANES):
        nl = min(LANES, hi - b0)
        lane_group(b0, nl, x0, p, u, u_t0, u_dt, t_out, rtol, atol, h_max, h_min, max_steps,
                   y, xs, bs, record_x, record_bus, status, nsteps, nrej, W, code, jfail, stopping)
        for l in range(nl):
            if code[l] == 3:
                one(np.int64(b0 + l), x0, p, u, u_t0, u_dt, t_out, rtol, atol, h_max, h_min, max_steps,
                    y, xs, bs, record_x, record_bus, status, nsteps, nrej, w, bus, uvec, yv)


#: the functions of this module in the order the kernel module defines them, those inlined where called, and the
#: helpers whose bodies are written into their caller (plant.integrate_splice: cheaper to compile than numba's
#: inlining, and no reference count per array argument)
FUNCTIONS = (lane_inputs, lane_rhs_into, lane_emit, lane_start, lane_stop, lane_finish, lane_group, run_lanes)
INLINE = ()
SPLICED = {lane_group: (lane_attempt, lane_error_norm, lane_dense_outputs, lane_accept)}
