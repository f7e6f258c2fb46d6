"""The plant integrator as it was before issue 14 (Dormand–Prince 5(4), elementary step-size control
``h_new = h · clip(0.9 · err^(-1/5), 0.2, 5)``), kept verbatim except for a rejection counter so that
``bench_plant`` times the old and the new integrator on the same inputs in the same run (a ratio, not a
remembered number). Not used by the package itself.

What it shares with today's member-by-member integrator to the letter is taken from there instead of written again:
an output (``emit``) and the end of a member (``finish``: NaN from where a stopped member stopped, else the final
state), both the same operations as the old text; the input interpolation, the step and the controller are the old
ones, below."""

from plant.integrate import kernel_source
from plant.integrate_scalar import emit, finish, nan_from

_STEPPER_BEFORE = r'''
@numba.njit(cache=CACHE, nogil=True, error_model="numpy")
def input_at(u, bu, t, u_t0, u_dt, uvec):
    m = u.shape[1]
    if m == 1:
        for k in range(u.shape[2]):
            uvec[k] = u[bu, 0, k]
        return
    s = (t - u_t0) / u_dt
    if s <= 0.0:
        i = 0
        f = 0.0
    elif s >= m - 1:
        i = m - 2
        f = 1.0
    else:
        i = int(s)
        if i > m - 2:
            i = m - 2
        f = s - i
    for k in range(u.shape[2]):
        uvec[k] = u[bu, i, k] * (1.0 - f) + u[bu, i + 1, k] * f

@numba.njit(cache=CACHE, nogil=True, error_model="numpy")
def one(b, x0, p, u, u_t0, u_dt, t_out, rtol, atol, h_max, h_min, max_steps,
        y, xs, bs, record_x, record_bus, status, nsteps, nrej):
    n = N_STATES
    rejected = 0
    bu = np.int64(0)
    if u.shape[0] > 1:
        bu = np.int64(b)
    x = x0[b].copy()
    pb = p[b]
    bus = np.zeros(N_BUS)
    dx = np.zeros(n)
    uvec = np.zeros(u.shape[2])
    k1 = np.zeros(n)
    k2 = np.zeros(n)
    k3 = np.zeros(n)
    k4 = np.zeros(n)
    k5 = np.zeros(n)
    k6 = np.zeros(n)
    k7 = np.zeros(n)
    xt = np.zeros(n)
    xn = np.zeros(n)
    xo = np.zeros(n)
    yv = np.zeros(y.shape[2])
    nout = t_out.shape[0]
    t = t_out[0]
    t_end = t_out[nout - 1]
    emit(b, 0, t, x, pb, u, bu, u_t0, u_dt, uvec, bus, dx, yv, y, xs, bs, record_x, record_bus)
    input_at(u, bu, t, u_t0, u_dt, uvec)
    rhs(t, x, pb, uvec, bus, k1)
    h = min(h_max, 1e-4)
    steps = 0
    code = 0
    j = 1
    while j < nout:
        remaining = t_end - t
        last = False
        if h >= remaining * (1.0 - 1e-9):
            h_use = remaining
            last = True
        else:
            h_use = h
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
        err = 0.0
        finite = True
        for k in range(n):
            e = h_use * (_E1 * k1[k] + _E3 * k3[k] + _E4 * k4[k] + _E5 * k5[k] + _E6 * k6[k] + _E7 * k7[k])
            sc = atol[k] + rtol * max(abs(x[k]), abs(xn[k]))
            r = e / sc
            err += r * r
            if not np.isfinite(xn[k]):
                finite = False
        err = np.sqrt(err / n)
        steps += 1
        if not finite or not np.isfinite(err):
            if h_use <= h_min:
                code = 1
                break
            h = h_use * 0.2
            rejected += 1
            continue
        if err <= 1.0:
            # dense output (4th order, Dormand-Prince) for every output time inside (t, t_new]
            while j < nout and t_out[j] <= t_new + 1e-12 * abs(t_new):
                th = (t_out[j] - t) / h_use
                if th >= 1.0:
                    for k in range(n):
                        xo[k] = xn[k]
                else:
                    th2 = th * th
                    th3 = th2 * th
                    th4 = th3 * th
                    q1 = th + _P12 * th2 + _P13 * th3 + _P14 * th4
                    q3 = _P32 * th2 + _P33 * th3 + _P34 * th4
                    q4 = _P42 * th2 + _P43 * th3 + _P44 * th4
                    q5 = _P52 * th2 + _P53 * th3 + _P54 * th4
                    q6 = _P62 * th2 + _P63 * th3 + _P64 * th4
                    q7 = _P72 * th2 + _P73 * th3 + _P74 * th4
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
            fac = 5.0 if err == 0.0 else min(5.0, max(0.2, 0.9 * err ** -0.2))
            if last:
                h = max(h, h_use * fac)
            else:
                h = h_use * fac
            h = min(h, h_max)
        else:
            rejected += 1
            h = h_use * max(0.2, 0.9 * err ** -0.25)
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


@numba.njit(cache=CACHE, nogil=True, error_model="numpy")
def run_chunk_stats(lo, hi, x0, p, u, u_t0, u_dt, t_out, rtol, atol, h_max, h_min, max_steps,
                    y, xs, bs, record_x, record_bus, status, nsteps, nrej):
    for b in range(lo, hi):
        one(np.int64(b), x0, p, u, u_t0, u_dt, t_out, rtol, atol, h_max, h_min, max_steps,
            y, xs, bs, record_x, record_bus, status, nsteps, nrej)


@numba.njit(cache=CACHE, nogil=True, error_model="numpy")
def run_chunk(lo, hi, x0, p, u, u_t0, u_dt, t_out, rtol, atol, h_max, h_min, max_steps,
              y, xs, bs, record_x, record_bus, status, nsteps):
    nrej = np.zeros(max(hi, 1), dtype=np.int64)
    run_chunk_stats(lo, hi, x0, p, u, u_t0, u_dt, t_out, rtol, atol, h_max, h_min, max_steps,
                    y, xs, bs, record_x, record_bus, status, nsteps, nrej)

'''

#: the old integrator's source for :meth:`plant.PlantModel.with_integrator_source` (entry points ``run_chunk``,
#: ``run_chunk_stats``)
INTEGRATOR_SOURCE_BEFORE = kernel_source((emit, nan_from, finish), inline=(finish,)) + "\n\n" + _STEPPER_BEFORE
