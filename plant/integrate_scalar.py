"""The member-by-member integrator: Dormand–Prince 5(4) with step-size control, one trajectory at a time.

Each batch member has its own step size; outputs between steps come from the 4th-order dense output; the last step
lands exactly on the final time. A member that produces a non-finite state or needs a step below ``h_min`` stops
with a status code (:class:`plant.integrate.IntegrationStatus`), its remaining outputs NaN. The step's formulas
are those of :mod:`plant.integrate_steps`, shared with the lane integrator; the composition's ``rhs``, ``out`` and
sizes are bound in its generated kernel module (:mod:`plant.integrate_kernel_names`), into which
:func:`plant.integrate.kernel_source` copies these functions.

Entry points: ``run_chunk_stats`` (members ``lo .. hi - 1``, counting attempted and rejected steps) and
``run_chunk`` (the same without the rejection count).
"""

from __future__ import annotations

import numpy as np

from plant.integrate_kernel_names import N_BUS, N_STATES, Array3, Index, IntVector, Matrix, Vector, out, rhs
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


def input_at(u: Array3, bu: Index, t: float, u_t0: float, u_dt: float, uvec: Vector) -> None:
    """The inputs of member ``bu`` of ``u`` at time ``t`` into ``uvec`` (linear between samples)."""
    m = u.shape[1]
    ub = np.uint64(bu)
    if m == 1:
        for k in range(u.shape[2]):
            uvec[k] = u[ub, np.uint64(0), np.uint64(k)]
        return
    i, f = input_position(t, m, u_t0, u_dt)
    for k in range(u.shape[2]):
        kk = np.uint64(k)
        uvec[k] = u[ub, i, kk] * (1.0 - f) + u[ub, i + np.uint64(1), kk] * f


def emit(b: Index, j: int, t: float, xo: Vector, pb: Vector, u: Array3, bu: Index, u_t0: float, u_dt: float,
         uvec: Vector, bus: Vector, dx: Vector, yv: Vector, y: Array3, xs: Array3, bs: Array3, record_x: bool,
         record_bus: bool) -> None:
    """Output ``j`` of member ``b`` at time ``t`` from the state ``xo`` (and the state and bus if recorded)."""
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


def attempt(t: float, h_use: float, t_new: float, x: Vector, k1: Vector, k2: Vector, k3: Vector, k4: Vector,
            k5: Vector, k6: Vector, k7: Vector, xt: Vector, xn: Vector, pb: Vector, u: Array3, bu: Index,
            u_t0: float, u_dt: float, uvec: Vector, bus: Vector, rtol: float, atol: Vector) -> tuple[float, float]:
    """One Dormand–Prince step of ``h_use`` from ``t`` (state ``x``, its derivative ``k1``): the stages ``k2`` ..
    ``k7`` (stage states in ``xt``), the 5th-order solution in ``xn``. Returns the squared error norm and the sum of
    the new states (non-finite when any state is)."""
    n = N_STATES
    t2, t3, t4, t5 = stage_times(t, h_use)
    for k in range(n):
        xt[k] = stage2(x[k], h_use, k1[k])
    input_at(u, bu, t2, u_t0, u_dt, uvec)
    rhs(t2, xt, pb, uvec, bus, k2)
    for k in range(n):
        xt[k] = stage3(x[k], h_use, k1[k], k2[k])
    input_at(u, bu, t3, u_t0, u_dt, uvec)
    rhs(t3, xt, pb, uvec, bus, k3)
    for k in range(n):
        xt[k] = stage4(x[k], h_use, k1[k], k2[k], k3[k])
    input_at(u, bu, t4, u_t0, u_dt, uvec)
    rhs(t4, xt, pb, uvec, bus, k4)
    for k in range(n):
        xt[k] = stage5(x[k], h_use, k1[k], k2[k], k3[k], k4[k])
    input_at(u, bu, t5, u_t0, u_dt, uvec)
    rhs(t5, xt, pb, uvec, bus, k5)
    for k in range(n):
        xt[k] = stage6(x[k], h_use, k1[k], k2[k], k3[k], k4[k], k5[k])
    input_at(u, bu, t_new, u_t0, u_dt, uvec)
    rhs(t_new, xt, pb, uvec, bus, k6)
    for k in range(n):
        xn[k] = solution5(x[k], h_use, k1[k], k3[k], k4[k], k5[k], k6[k])
    rhs(t_new, xn, pb, uvec, bus, k7)
    err2 = 0.0
    total = 0.0
    for k in range(n):
        r = error_ratio(h_use, k1[k], k3[k], k4[k], k5[k], k6[k], k7[k], atol[k], rtol, x[k], xn[k])
        err2 += r * r
        total += xn[k]
    return err2 / n, total


def dense_outputs(b: Index, j: int, t: float, t_new: float, h_use: float, x: Vector, k1: Vector, k3: Vector,
                  k4: Vector, k5: Vector, k6: Vector, k7: Vector, xn: Vector, xo: Vector, dx: Vector, t_out: Vector,
                  pb: Vector, u: Array3, bu: Index, u_t0: float, u_dt: float, uvec: Vector, bus: Vector, yv: Vector,
                  y: Array3, xs: Array3, bs: Array3, record_x: bool, record_bus: bool) -> int:
    """Emit every output time inside the accepted step ``(t, t_new]`` (start ``x``, stages ``k1`` .. ``k7``, end
    ``xn``) from the dense output (into ``xo``), starting at output ``j``; returns the next output index."""
    n = N_STATES
    nout = t_out.shape[0]
    while j < nout and output_due(t_out[j], t_new):
        th = (t_out[j] - t) / h_use
        if th >= 1.0:
            for k in range(n):
                xo[k] = xn[k]
        else:
            q = dense_weights(th)
            for k in range(n):
                xo[k] = dense_point(x[k], h_use, q, k1[k], k3[k], k4[k], k5[k], k6[k], k7[k])
        emit(b, j, t_out[j], xo, pb, u, bu, u_t0, u_dt, uvec, bus, dx, yv, y, xs, bs, record_x, record_bus)
        j += 1
    return j


def nan_from(b: Index, j: int, nout: int, y: Array3, xs: Array3, record_x: bool) -> None:
    """NaN outputs (and recorded states) of member ``b`` from output ``j`` on: where a stopped member stopped."""
    for jj in range(j, nout):
        for k in range(y.shape[2]):
            y[b, jj, k] = np.nan
        if record_x:
            for k in range(N_STATES):
                xs[b, jj, k] = np.nan


def finish(b: Index, code: int, j: int, nout: int, x: Vector, y: Array3, xs: Array3, record_x: bool) -> None:
    """After the last step: NaN outputs (and states) from output ``j`` on for a member that stopped early, else the
    final state exactly at the end of the interval (the stepper continues from it)."""
    if code != 0:
        nan_from(b, j, nout, y, xs, record_x)
    elif record_x:
        for k in range(N_STATES):
            xs[b, nout - 1, k] = x[k]


def one(b: Index, x0: Matrix, p: Matrix, u: Array3, u_t0: float, u_dt: float, t_out: Vector, rtol: float,
        atol: Vector, h_max: float, h_min: float, max_steps: int, y: Array3, xs: Array3, bs: Array3,
        record_x: bool, record_bus: bool, status: IntVector, nsteps: IntVector, nrej: IntVector, w: Matrix,
        bus: Vector, uvec: Vector, yv: Vector) -> None:
    """Integrate member ``b`` over ``t_out``; ``w``: (12, N_STATES) work rows, allocated once per chunk (no
    allocation per member or per step): the state, the seven stages, the stage input, the 5th-order solution, the
    dense output and the derivative at an output."""
    bu = np.int64(b) if u.shape[0] > 1 else np.int64(0)
    x, k1, k2, k3, k4, k5, k6, k7 = w[0], w[1], w[2], w[3], w[4], w[5], w[6], w[7]
    xt, xn, xo, dx = w[8], w[9], w[10], w[11]
    for k in range(N_STATES):
        x[k] = x0[b, k]
    pb = p[b]
    nout = t_out.shape[0]
    t = t_out[0]
    t_end = t_out[nout - 1]
    emit(b, 0, t, x, pb, u, bu, u_t0, u_dt, uvec, bus, dx, yv, y, xs, bs, record_x, record_bus)
    input_at(u, bu, t, u_t0, u_dt, uvec)
    rhs(t, x, pb, uvec, bus, k1)
    h, log_err_prev, after_reject, pi_on = control_start(h_max)
    steps = 0
    rejected = 0
    code = 0
    j = 1
    while j < nout:
        h_use, last = step_to_take(h, t_end - t)
        t_new = t_end if last else t + h_use
        err2, total = attempt(t, h_use, t_new, x, k1, k2, k3, k4, k5, k6, k7, xt, xn, pb, u, bu, u_t0, u_dt, uvec,
                              bus, rtol, atol)
        steps += 1
        if not (np.isfinite(total) and np.isfinite(err2)):
            # a non-finite state anywhere makes the sum non-finite (one test instead of one per state)
            rejected += 1
            if h_use <= h_min:
                code = 1
                break
            h = step_after_nonfinite(h_use)
            after_reject = True
            continue
        log_err = log_error(err2)
        if err2 <= 1.0:
            j = dense_outputs(b, j, t, t_new, h_use, x, k1, k3, k4, k5, k6, k7, xn, xo, dx, t_out, pb, u, bu,
                              u_t0, u_dt, uvec, bus, yv, y, xs, bs, record_x, record_bus)
            t = t_new
            for k in range(N_STATES):
                x[k] = xn[k]
                k1[k] = k7[k]
            h, log_err_prev, after_reject = control_accepted(h, h_use, log_err, log_err_prev, pi_on, after_reject,
                                                             last, h_max)
        else:
            rejected += 1
            h, after_reject, pi_on = control_rejected(h_use, log_err)
            if h < h_min:
                code = 2
                break
        if steps >= max_steps:
            code = 3
            break
    finish(b, code, j, nout, x, y, xs, record_x)
    status[b] = code
    nsteps[b] = steps
    nrej[b] = rejected


def run_chunk_stats(lo: int, hi: int, x0: Matrix, p: Matrix, u: Array3, u_t0: float, u_dt: float, t_out: Vector,
                    rtol: float, atol: Vector, h_max: float, h_min: float, max_steps: int, y: Array3, xs: Array3,
                    bs: Array3, record_x: bool, record_bus: bool, status: IntVector, nsteps: IntVector,
                    nrej: IntVector) -> None:
    """Members ``lo .. hi - 1``; ``nsteps[b]``: attempted steps of member b; ``nrej[b]``: of which rejected."""
    w = np.empty((12, N_STATES))
    bus = np.zeros(N_BUS)
    uvec = np.zeros(u.shape[2])
    yv = np.zeros(y.shape[2])
    for b in range(lo, hi):
        one(np.int64(b), x0, p, u, u_t0, u_dt, t_out, rtol, atol, h_max, h_min, max_steps,
            y, xs, bs, record_x, record_bus, status, nsteps, nrej, w, bus, uvec, yv)


def run_chunk(lo: int, hi: int, x0: Matrix, p: Matrix, u: Array3, u_t0: float, u_dt: float, t_out: Vector,
              rtol: float, atol: Vector, h_max: float, h_min: float, max_steps: int, y: Array3, xs: Array3,
              bs: Array3, record_x: bool, record_bus: bool, status: IntVector, nsteps: IntVector) -> None:
    """:func:`run_chunk_stats` without the rejection count."""
    nrej = np.empty(max(hi, 1), dtype=np.int64)
    run_chunk_stats(lo, hi, x0, p, u, u_t0, u_dt, t_out, rtol, atol, h_max, h_min, max_steps,
                    y, xs, bs, record_x, record_bus, status, nsteps, nrej)


#: the functions of this module in the order the kernel module defines them, those inlined where called, and
#: the helpers whose bodies are written into their caller (numba's inlining would cost a reference count per array
#: argument per attempted step, ~20 % of it: plant.integrate_splice)
FUNCTIONS = (input_at, emit, nan_from, finish, one, run_chunk_stats, run_chunk)
INLINE = (finish,)
SPLICED = {one: (attempt, dense_outputs)}
