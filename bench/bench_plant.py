"""Plant benchmark: one 20 s MBIT.a-like run and a batch of 1000 runs with deviated (k3, alpha_h, beta_h),
against the baseline a user would write — scipy ``solve_ivp(LSODA)`` on a plain-Python right-hand side, in a loop,
one trajectory at a time — measured in the same run. Accuracy is checked against solve_ivp at rtol 1e-9."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp

from board_config import load_parameter_set
from plant import PlantModel, sine_drive
from plant.reference import make_solve_ivp_rhs


def _baseline_run(prm: dict, inp, t_out: np.ndarray, rtol: float) -> tuple[np.ndarray, float]:
    f = make_solve_ivp_rhs(prm, inp.t, inp.values[0])
    t0 = time.perf_counter()
    atol = np.array([1e-3] * 3 + [1e-2] * 3 + [1e-3] * 6) * rtol
    r = solve_ivp(f, (t_out[0], t_out[-1]), np.zeros(12), method="LSODA", rtol=rtol, atol=atol, t_eval=t_out)
    wall = time.perf_counter() - t0
    if not r.success:
        raise RuntimeError(f"baseline solve_ivp failed: {r.message}")
    return r.y[0] + r.y[1] + r.y[2], wall


def run(out_dir: Path, quick: bool) -> dict:
    n_batch = 100 if quick else 1000
    n_baseline = 2 if quick else 5
    params = load_parameter_set("table2")
    model = PlantModel(params)
    inp = sine_drive(600.0, 0.1, 20.0, dt=1e-3)
    t0 = time.perf_counter()
    model.simulate(sine_drive(1.0, 1.0, 0.05), dt_out=0.01)  # load/compile the kernels
    load_s = time.perf_counter() - t0

    t0 = time.perf_counter()
    single = model.simulate(inp, dt_out=0.01, threads=1)
    single_s = time.perf_counter() - t0
    t_out = single.t

    rng = np.random.default_rng(2024)
    dev = rng.uniform(-0.5, 0.5, size=(n_batch, 3))
    k3 = params["k3"] * (1 + dev[:, 0])
    alpha = np.clip(params["alpha_h"] * (1 + dev[:, 1]), 0.0, 1.0)
    beta = params["beta_h"] * (1 + dev[:, 2])
    pb = model.param_batch(k3=k3, alpha_h=alpha, beta_h=beta)
    t0 = time.perf_counter()
    batch = model.simulate(inp, dt_out=0.01, params=pb)
    batch_s = time.perf_counter() - t0

    # the user's baseline: LSODA, plain Python rhs, one trajectory at a time (same tolerance as ours: 1e-6)
    base_walls = []
    for i in range(n_baseline):
        prm = dict(params.values, k3=k3[i], alpha_h=alpha[i], beta_h=beta[i])
        _, w = _baseline_run(prm, inp, t_out, 1e-6)
        base_walls.append(w)
    base_per_run = float(np.median(base_walls))

    # accuracy: a few batch members against solve_ivp at rtol 1e-9
    errs = []
    for i in range(3):
        prm = dict(params.values, k3=k3[i], alpha_h=alpha[i], beta_h=beta[i])
        z_ref, _ = _baseline_run(prm, inp, t_out, 1e-9)
        errs.append(float(np.max(np.abs(batch["z3"][i] - z_ref)) / np.max(np.abs(z_ref))))

    throughput = n_batch / batch_s
    res = {
        "kernel_load_s": load_s,
        "single_mbit_a_20s_wall_s": single_s,
        "single_ratio_vs_lsoda": base_per_run / single_s,
        "batch_size": n_batch,
        "batch_wall_s": batch_s,
        "batch_throughput_runs_per_s": throughput,
        "baseline_lsoda_per_run_s": base_per_run,
        "baseline_runs_timed": n_baseline,
        "baseline_throughput_runs_per_s": 1.0 / base_per_run,
        "batch_throughput_ratio_vs_lsoda": throughput * base_per_run,
        "accuracy_worst_rel_err_z3_vs_rtol1e-9": max(errs),
        "batch_all_ok": bool(batch.ok),
        "mean_steps_per_run": float(np.mean(batch.n_steps)),
    }
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(6, 3.5))
        ax.bar(["solve_ivp LSODA\n(one at a time)", "mfc-shm batch"], [1.0 / base_per_run, throughput])
        ax.set_yscale("log")
        ax.set_ylabel("20 s MBIT.a runs per second")
        ax.set_title(f"Plant throughput: {res['batch_throughput_ratio_vs_lsoda']:.0f}x baseline")
        fig.tight_layout()
        fig.savefig(out_dir / "plant_throughput.png", dpi=110)
        plt.close(fig)
    except Exception as exc:  # the numbers matter more than the figure
        res["figure_error"] = str(exc)
    return res
