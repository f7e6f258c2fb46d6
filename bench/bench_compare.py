"""``shm compare`` on a 60 s record at 1 kHz (MBIT.a waveform repeated, table2 truth + 2 µm laser noise).

Reports the wall time of the whole command (load, replay, k-step prediction, metrics, residual tests,
localisation, PNG figures, HTML, JSON) and its breakdown. Baseline measured in the same run: the free-run
simulation a user would first write — scipy ``solve_ivp(LSODA)`` on a plain-Python right-hand side
(``plant.reference``), sampled at the record's 60 001 instants — against our compiled replay of the same record.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp

from board_config import load_parameter_set
from plant.reference import make_solve_ivp_rhs
from workbench.compare import CompareOptions, compare, write_report
from workbench.records import Record, load_record, write_record
from workbench.simulation import model_for, replay, synth_record, synth_test, truth_model


def _load_time_record(path: Path) -> Record:
    rec = load_record(path)
    if not isinstance(rec, Record):
        raise TypeError(f"{path}: expected a time record, got a frequency-response table")
    return rec


def run(out_dir: Path, quick: bool) -> dict:
    duration = 10.0 if quick else 60.0
    out = Path(out_dir) / "compare"
    out.mkdir(parents=True, exist_ok=True)
    rec_path = out / "mbit_a_60s.csv"
    truth = truth_model("table2")
    write_record(synth_record(synth_test("mbit-a", duration_s=duration), truth, seed=1), rec_path)

    # warm-up: kernels and matplotlib's first-use costs are per process, not per comparison
    warm = _load_time_record(rec_path).slice(0.0, 1.0)
    write_report([compare(model_for(warm, "table2"), warm)], out / "warmup")

    phases: dict[str, float] = {}
    c0 = time.process_time()
    t0 = time.perf_counter()
    rec = _load_time_record(rec_path)
    phases["load_s"] = time.perf_counter() - t0
    t1 = time.perf_counter()
    model = model_for(rec, "table2")
    model.kernels()
    phases["model_s"] = time.perf_counter() - t1
    t2 = time.perf_counter()
    cmp = compare(model, rec, CompareOptions())
    phases["compare_s"] = time.perf_counter() - t2
    phases.update({f"compare.{k}": v for k, v in cmp.wall_s.items() if k != "compare_s"})
    t3 = time.perf_counter()
    write_report([cmp], out / "report")
    phases["report_s"] = time.perf_counter() - t3
    total = time.perf_counter() - t0
    cpu = time.process_time() - c0

    # the baseline free run vs ours, same record, same tolerance (rtol 1e-6)
    prm = dict(load_parameter_set("table2").values)
    u = rec.input_matrix()
    f = make_solve_ivp_rhs(prm, rec.t, u)
    atol = np.array([1e-3] * 3 + [1e-2] * 3 + [1e-3] * 6) * 1e-6
    tb = time.perf_counter()
    ref = solve_ivp(f, (rec.t[0], rec.t[-1]), np.zeros(12), method="LSODA", rtol=1e-6, atol=atol, t_eval=rec.t)
    base_s = time.perf_counter() - tb
    if not ref.success:
        raise RuntimeError(f"baseline solve_ivp failed: {ref.message}")
    to = time.perf_counter()
    ours = replay(model, rec, predict=False)
    ours_s = time.perf_counter() - to
    z_ref = ref.y[0] + ref.y[1] + ref.y[2]
    dev = float(np.max(np.abs(ours.channels["z3"].simulated - z_ref)) / np.max(np.abs(z_ref)))
    return {
        "record": str(rec_path), "duration_s": duration, "samples": rec.n_samples,
        "compare_total_wall_s": total, "compare_total_cpu_s": cpu, "realtime_factor": duration / total, **phases,
        "verdict": cmp.verdicts()["z3"], "fit_pct": cmp.metrics["z3"].fit_pct,
        "baseline_solve_ivp_lsoda_s": base_s, "replay_simulation_s": ours_s,
        "replay_speedup_vs_solve_ivp": base_s / ours_s, "replay_vs_solve_ivp_max_rel_dev": dev,
        "note": "total = load + model + compare (replay, prediction, metrics, tests, localisation) + report "
                "(5 PNGs, HTML, JSON); kernels and matplotlib warmed up once before timing; cpu = this process's CPU "
                "time (single-threaded work: close to the wall time on an idle machine)",
    }
