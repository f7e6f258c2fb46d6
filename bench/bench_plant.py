"""Plant benchmark: one 20 s MBIT.a-like run and a batch of 1000 runs with deviated (k3, alpha_h, beta_h).

Every figure is a ratio against a baseline timed in the same run, on the same inputs and tolerances:

* the integrator as it was before issue 14 (:mod:`bench.integrator_before`: elementary step-size control,
  member by member), compiled from its source beside the current one — before/after batch time, steps and
  rejection rates; and the current integrator member by member (``lanes=False``) against the lane integrator
  (groups of ``LANES`` members sharing a step, SIMD across members: what ``simulate`` uses for this batch);
* numbalsoda (LSODA in Fortran, called from a numba ``prange`` loop on the same compiled right-hand side; the
  optional extra ``mfc-shm[bench]``, which needs gfortran) — skipped with the reason when it is not installed;
* the floor: a bare Dormand–Prince step of this 12-state model (a minimal numba loop calling the same compiled
  right-hand side, fixed step, no error control, no output), against our cost per attempted step;
* the baseline a user would write: scipy ``solve_ivp(LSODA)`` on a plain-Python right-hand side, one trajectory
  at a time.

The machine may be shared: the load average is recorded before and after, and each timing is the best of a few
repetitions (interleaved between the integrators compared). Accuracy is checked against solve_ivp at rtol 1e-9.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from scipy.integrate import solve_ivp

import plant.integrate_steps as tableau
from bench.integrator_before import INTEGRATOR_SOURCE_BEFORE
from board_config import load_parameter_set
from plant import PlantModel, sine_drive
from plant.integrate import LANES
from plant.reference import make_solve_ivp_rhs

RTOL = 1e-6


def _baseline_run(prm: dict, inp, t_out: np.ndarray, rtol: float) -> tuple[np.ndarray, float]:
    f = make_solve_ivp_rhs(prm, inp.t, inp.values[0])
    t0 = time.perf_counter()
    atol = np.array([1e-3] * 3 + [1e-2] * 3 + [1e-3] * 6) * rtol
    r = solve_ivp(f, (t_out[0], t_out[-1]), np.zeros(12), method="LSODA", rtol=rtol, atol=atol, t_eval=t_out)
    wall = time.perf_counter() - t0
    if not r.success:
        raise RuntimeError(f"baseline solve_ivp failed: {r.message}")
    return r.y[0] + r.y[1] + r.y[2], wall


def _best_of(fns: dict[str, Callable[[], Any]], repeats: int) -> tuple[dict[str, float], dict[str, Any]]:
    """Best wall time of each function over ``repeats`` interleaved rounds, and its last result."""
    best = {k: float("inf") for k in fns}
    last: dict[str, Any] = {}
    for _ in range(repeats):
        for k, fn in fns.items():
            t0 = time.perf_counter()
            last[k] = fn()
            best[k] = min(best[k], time.perf_counter() - t0)
    return best, last


def _bare_step_kernel():
    """A minimal fixed-step Dormand–Prince loop (6 right-hand sides per step, FSAL) around a compiled ``rhs``, on the
    integrators' own stage formulas (:mod:`plant.integrate_steps`, inlined as there)."""
    import numba

    times, s2, s3, s4, s5, s6, s7 = (numba.njit(inline="always")(f) for f in (
        tableau.stage_times, tableau.stage2, tableau.stage3, tableau.stage4, tableau.stage5, tableau.stage6,
        tableau.solution5))

    @numba.njit(nogil=True, error_model="numpy")
    def bare(rhs, x0, p, u, n_bus, h, n_steps):  # pragma: no cover - compiled
        n = x0.shape[0]
        x = x0.copy()
        bus = np.zeros(n_bus)
        w = np.zeros((7, n))  # the six stages and the stage state
        k1, k2, k3, k4, k5, k6, xt = w[0], w[1], w[2], w[3], w[4], w[5], w[6]
        t = 0.0
        rhs(t, x, p, u, bus, k1)
        for _ in range(n_steps):
            t2, t3, t4, t5 = times(t, h)
            for k in range(n):
                xt[k] = s2(x[k], h, k1[k])
            rhs(t2, xt, p, u, bus, k2)
            for k in range(n):
                xt[k] = s3(x[k], h, k1[k], k2[k])
            rhs(t3, xt, p, u, bus, k3)
            for k in range(n):
                xt[k] = s4(x[k], h, k1[k], k2[k], k3[k])
            rhs(t4, xt, p, u, bus, k4)
            for k in range(n):
                xt[k] = s5(x[k], h, k1[k], k2[k], k3[k], k4[k])
            rhs(t5, xt, p, u, bus, k5)
            for k in range(n):
                xt[k] = s6(x[k], h, k1[k], k2[k], k3[k], k4[k], k5[k])
            rhs(t + h, xt, p, u, bus, k6)
            for k in range(n):
                x[k] = s7(x[k], h, k1[k], k3[k], k4[k], k5[k], k6[k])
            t += h
            rhs(t, x, p, u, bus, k1)
        return x

    return bare


def _bare_step_cost_s(model: PlantModel, repeats: int, n_steps: int) -> float:
    """Seconds per bare Dormand–Prince step of the model (one thread, best of ``repeats``)."""
    from plant import layout as L

    bare = _bare_step_kernel()
    rhs = model.kernels().rhs
    x0 = np.zeros(model.n_states)
    x0[0] = 1e-4
    u = np.array([300.0, -300.0, 0.0])
    p = np.ascontiguousarray(model.p_nominal)
    bare(rhs, x0, p, u, L.N_BUS, 4e-3, 10)  # compile
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        bare(rhs, x0, p, u, L.N_BUS, 4e-3, n_steps)
        best = min(best, time.perf_counter() - t0)
    return best / n_steps


def _numbalsoda_batch(model: PlantModel) -> Callable[[np.ndarray, Any, np.ndarray, float], np.ndarray]:
    """A batch runner on numbalsoda: LSODA (Fortran) per member in a numba ``prange`` loop, calling the same
    compiled right-hand side through a C callback. LSODA takes one scalar absolute tolerance, so it integrates
    the state divided by the model's state scales (same per-state tolerances as ours). Raises ImportError."""
    import numba
    from numbalsoda import lsoda, lsoda_sig

    from plant import layout as L

    rhs = model.kernels().rhs
    input_position = numba.njit(inline="always")(tableau.input_position)  # the integrators' input interpolation
    n = model.n_states
    n_p = len(model.param_names)
    n_bus = L.N_BUS
    # data row: [u_t0, u_dt, n_samples, params (n_p), scales (n), x (n), dx (n), bus (n_bus), uvec (3), u (m*3)]
    o_p = 3
    o_s = o_p + n_p
    o_x = o_s + n
    o_dx = o_x + n
    o_bus = o_dx + n
    o_u = o_bus + n_bus
    o_samples = o_u + 3

    @numba.cfunc(lsoda_sig)
    def f(t, xs_ptr, dxs_ptr, data_ptr):  # pragma: no cover - compiled
        xs = numba.carray(xs_ptr, (n,))
        dxs = numba.carray(dxs_ptr, (n,))
        d = numba.carray(data_ptr, (o_samples,))
        m = int(d[2])
        samples = numba.carray(data_ptr, (o_samples + 3 * m,))
        x = d[o_x:o_dx]
        dx = d[o_dx:o_bus]
        uvec = d[o_u:o_samples]
        for k in range(n):
            x[k] = xs[k] * d[o_s + k]
        i_u, fr = input_position(t, m, d[0], d[1])
        i = int(i_u)
        for k in range(3):
            uvec[k] = samples[o_samples + 3 * i + k] * (1.0 - fr) + samples[o_samples + 3 * (i + 1) + k] * fr
        rhs(t, x, d[o_p:o_s], uvec, d[o_bus:o_u], dx)
        for k in range(n):
            dxs[k] = dx[k] / d[o_s + k]

    fptr = f.address

    @numba.njit(parallel=True)
    def run_all(x0s, t_out, data, rtol, atol, z3):  # pragma: no cover - compiled
        for b in numba.prange(data.shape[0]):
            usol, ok = lsoda(fptr, x0s, t_out, data=data[b], rtol=rtol, atol=atol, mxstep=1_000_000)
            for j in range(t_out.shape[0]):
                z3[b, j] = (usol[j, 0] * data[b, o_s] + usol[j, 1] * data[b, o_s + 1] + usol[j, 2] * data[b, o_s + 2]
                            if ok else np.nan)

    def run_batch(pb: np.ndarray, inp, t_out: np.ndarray, rtol: float) -> np.ndarray:
        m = inp.values.shape[1]
        data = np.zeros((pb.shape[0], o_samples + 3 * m))
        data[:, 0], data[:, 1], data[:, 2] = inp.t0, inp.dt, m
        data[:, o_p:o_s] = pb
        data[:, o_s:o_x] = model.state_scales
        data[:, o_samples:] = inp.values[0].reshape(-1)
        z3 = np.empty((pb.shape[0], t_out.size))
        run_all(np.zeros(n), np.ascontiguousarray(t_out), data, rtol, rtol, z3)
        return z3

    return run_batch


@dataclass
class _Batch:
    """The deviated batch every integrator runs: parameters (k3, alpha_h, beta_h deviated by up to ±50 %)."""

    pb: np.ndarray
    k3: np.ndarray
    alpha: np.ndarray
    beta: np.ndarray

    def member_params(self, params: Any, i: int) -> dict:
        return dict(params.values, k3=self.k3[i], alpha_h=self.alpha[i], beta_h=self.beta[i])


def _deviated_batch(model: PlantModel, params: Any, n_batch: int) -> _Batch:
    rng = np.random.default_rng(2024)
    dev = rng.uniform(-0.5, 0.5, size=(n_batch, 3))
    k3 = params["k3"] * (1 + dev[:, 0])
    alpha = np.clip(params["alpha_h"] * (1 + dev[:, 1]), 0.0, 1.0)
    beta = params["beta_h"] * (1 + dev[:, 2])
    return _Batch(model.param_batch(k3=k3, alpha_h=alpha, beta_h=beta), k3, alpha, beta)


def _batch_runners(model: PlantModel, before: PlantModel, inp: Any, pb: np.ndarray, t_out: np.ndarray
                   ) -> tuple[dict[str, Callable[[], Any]], str]:
    """The batch, before (previous integrator) and after (current), same inputs, tolerances and threads; and
    numbalsoda when it is installed (else why it is skipped)."""
    runners: dict[str, Callable[[], Any]] = {
        "before": lambda: before.simulate(inp, dt_out=0.01, params=pb, rtol=RTOL),
        "member_by_member": lambda: model.simulate(inp, dt_out=0.01, params=pb, rtol=RTOL, lanes=False),
        "after": lambda: model.simulate(inp, dt_out=0.01, params=pb, rtol=RTOL),
    }
    try:
        nbl = _numbalsoda_batch(model)
        nbl(pb[:2], inp, t_out, RTOL)  # compile
        runners["numbalsoda"] = lambda: nbl(pb, inp, t_out, RTOL)
    except ImportError as exc:
        return runners, (f"numbalsoda not installed ({exc}); install the bench extra: pip install -e '.[bench]' "
                         f"(needs gfortran and cmake)")
    except Exception as exc:  # a peer failing to build must not stop the benchmark
        return runners, f"numbalsoda failed: {type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}"
    return runners, ""


def _per_attempt_s(model: PlantModel, before: PlantModel, inp: Any, pb: np.ndarray, quick: bool, repeats: int
                   ) -> tuple[dict[str, float], float]:
    """Seconds per attempted step, one thread, of each integrator on whole lane groups; and of the bare-step
    floor (same compiled right-hand side)."""
    n_small = (1 if quick else 2) * LANES  # whole lane groups
    best1, last1 = _best_of({
        "before": lambda: before.simulate(inp, dt_out=0.01, params=pb[:n_small], threads=1),
        "member_by_member": lambda: model.simulate(inp, dt_out=0.01, params=pb[:n_small], threads=1, lanes=False),
        "after": lambda: model.simulate(inp, dt_out=0.01, params=pb[:n_small], threads=1, lanes=True),
    }, 3 * repeats)  # short runs: more repetitions for a stable minimum on a shared machine
    per_attempt = {k: best1[k] / float(last1[k].n_steps.sum()) for k in best1}
    return per_attempt, _bare_step_cost_s(model, 3 * repeats, 20_000 if quick else 100_000)


def _lsoda_per_run_s(params: Any, batch: _Batch, inp: Any, t_out: np.ndarray, n_baseline: int) -> float:
    """The user's baseline: LSODA, plain Python rhs, one trajectory at a time (same tolerance as ours): median
    seconds per run."""
    walls = [_baseline_run(batch.member_params(params, i), inp, t_out, RTOL)[1] for i in range(n_baseline)]
    return float(np.median(walls))


def _accuracy(params: Any, batch: _Batch, inp: Any, t_out: np.ndarray, last: dict[str, Any]
              ) -> tuple[list[float], list[float]]:
    """Worst relative z3 error of a few batch members (ours, numbalsoda's) against solve_ivp at rtol 1e-9."""
    errs, errs_nbl = [], []
    for i in range(3):
        z_ref, _ = _baseline_run(batch.member_params(params, i), inp, t_out, 1e-9)
        errs.append(float(np.max(np.abs(last["after"]["z3"][i] - z_ref)) / np.max(np.abs(z_ref))))
        if "numbalsoda" in last:
            errs_nbl.append(float(np.max(np.abs(last["numbalsoda"][i] - z_ref)) / np.max(np.abs(z_ref))))
    return errs, errs_nbl


def _step_counts(r: Any, n_batch: int) -> tuple[float, float, float]:
    """Attempted and accepted steps per run, and the rejection rate."""
    att = float(r.n_steps.sum())
    rej = float(r.n_rejected.sum())
    return att / n_batch, (att - rej) / n_batch, rej / att


def _results(load_before: tuple[float, ...], timing: dict[str, Any], batch_best: dict[str, float],
             last: dict[str, Any], per_attempt: dict[str, float], bare_s: float, base_per_run: float,
             n_baseline: int, errs: list[float], repeats: int) -> dict[str, Any]:
    """The benchmark's figures (every speed a ratio against a baseline timed in the same run)."""
    n_batch = int(last["after"].y.shape[0])
    batch_s = batch_best["after"]
    att_b, acc_b, rej_b = _step_counts(last["before"], n_batch)
    att_a, acc_a, rej_a = _step_counts(last["after"], n_batch)
    throughput = n_batch / batch_s
    return {
        "load_average_1_5_15min_before": " ".join(f"{v:.2f}" for v in load_before),
        "timing": f"best of {repeats} interleaved repetitions on a possibly shared machine",
        "kernel_load_s": timing["load_s"],
        "single_mbit_a_20s_wall_s": timing["single_s"],
        "single_ratio_vs_lsoda": base_per_run / timing["single_s"],
        "batch_size": n_batch,
        "batch_wall_s_before": batch_best["before"],
        "batch_wall_s": batch_s,
        "batch_speedup_vs_before": batch_best["before"] / batch_s,
        "batch_speedup_target": 3.0,
        "lanes": LANES,
        "batch_wall_s_member_by_member": batch_best["member_by_member"],
        "lanes_speedup_vs_member_by_member": batch_best["member_by_member"] / batch_s,
        # load-independent part of the speed-up: attempted steps before / after (same inputs and tolerances)
        "attempt_ratio_before_over_after": att_b / att_a,
        "attempted_steps_per_run_before": att_b,
        "attempted_steps_per_run": att_a,
        "accepted_steps_per_run_before": acc_b,
        "accepted_steps_per_run": acc_a,
        "rejection_rate_before": rej_b,
        "rejection_rate": rej_a,
        "us_per_attempt_before_1thread": per_attempt["before"] * 1e6,
        "us_per_attempt_1thread": per_attempt["after"] * 1e6,
        "us_per_attempt_member_by_member_1thread": per_attempt["member_by_member"] * 1e6,
        "us_bare_dopri_step_1thread": bare_s * 1e6,
        "per_attempt_over_bare_step": per_attempt["after"] / bare_s,
        "batch_throughput_runs_per_s": throughput,
        "baseline_lsoda_per_run_s": base_per_run,
        "baseline_runs_timed": n_baseline,
        "baseline_throughput_runs_per_s": 1.0 / base_per_run,
        "batch_throughput_ratio_vs_lsoda": throughput * base_per_run,
        "accuracy_worst_rel_err_z3_vs_rtol1e-9": max(errs),
        "batch_all_ok": bool(last["after"].ok),
        "mean_steps_per_run": float(np.mean(last["after"].n_steps)),
    }


def _throughput_figure(out_dir: Path, res: dict[str, Any], batch_best: dict[str, float]) -> None:
    """Runs per second of each integrator (log scale), ``plant_throughput.png``."""
    from reporting.figures import pyplot

    plt = pyplot()
    n_batch = res["batch_size"]
    labels = ["solve_ivp LSODA\n(one at a time)", "before\n(issue 14)", "member by\nmember",
              "mfc-shm batch\n(lanes)"]
    values = [1.0 / res["baseline_lsoda_per_run_s"], n_batch / batch_best["before"],
              n_batch / batch_best["member_by_member"], res["batch_throughput_runs_per_s"]]
    if "numbalsoda" in batch_best:
        labels.insert(1, "numbalsoda\n(prange)")
        values.insert(1, n_batch / batch_best["numbalsoda"])
    fig, ax = plt.subplots(figsize=(7, 3.5))
    ax.bar(labels, values)
    ax.set_yscale("log")
    ax.set_ylabel("20 s MBIT.a runs per second")
    ax.set_title(f"Plant throughput: {res['batch_throughput_ratio_vs_lsoda']:.0f}x solve_ivp, "
                 f"{res['batch_speedup_vs_before']:.2f}x before")
    fig.tight_layout()
    fig.savefig(out_dir / "plant_throughput.png", dpi=110)
    plt.close(fig)


def run(out_dir: Path, quick: bool) -> dict:
    n_batch = 100 if quick else 1000
    n_baseline = 2 if quick else 5
    repeats = 2 if quick else 3
    load_before = os.getloadavg()
    params = load_parameter_set("table2")
    model = PlantModel(params)
    before = model.with_integrator_source(INTEGRATOR_SOURCE_BEFORE)
    inp = sine_drive(600.0, 0.1, 20.0, dt=1e-3)
    t0 = time.perf_counter()
    model.simulate(sine_drive(1.0, 1.0, 0.05), dt_out=0.01)  # load/compile the kernels
    timing = {"load_s": time.perf_counter() - t0}
    before.simulate(sine_drive(1.0, 1.0, 0.05), dt_out=0.01)
    t0 = time.perf_counter()
    single = model.simulate(inp, dt_out=0.01, threads=1)
    timing["single_s"] = time.perf_counter() - t0
    t_out = single.t

    batch = _deviated_batch(model, params, n_batch)
    runners, numbalsoda_skip = _batch_runners(model, before, inp, batch.pb, t_out)
    best, last = _best_of(runners, repeats)
    per_attempt, bare_s = _per_attempt_s(model, before, inp, batch.pb, quick, repeats)
    base_per_run = _lsoda_per_run_s(params, batch, inp, t_out, n_baseline)
    errs, errs_nbl = _accuracy(params, batch, inp, t_out, last)

    res = _results(load_before, timing, best, last, per_attempt, bare_s, base_per_run, n_baseline, errs, repeats)
    if "numbalsoda" in best:
        res["numbalsoda_batch_wall_s"] = best["numbalsoda"]
        res["numbalsoda_over_ours"] = best["numbalsoda"] / best["after"]
        res["numbalsoda_accuracy_worst_rel_err_z3_vs_rtol1e-9"] = max(errs_nbl)
    else:
        res["numbalsoda_skipped"] = numbalsoda_skip
    res["load_average_1_5_15min_after"] = " ".join(f"{v:.2f}" for v in os.getloadavg())
    try:
        _throughput_figure(out_dir, res, best)
    except Exception as exc:  # the numbers matter more than the figure
        res["figure_error"] = str(exc)
    return res
