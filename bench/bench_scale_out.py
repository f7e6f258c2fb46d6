"""Scale out (issue 31): a 40-record ``shm diagnose`` (1 s MBIT.b records, two candidates, no discovery step) on a
local Dask cluster of 1 worker and of 2 workers in the same run — speed-up, per-task overhead (wall per task on the
cluster minus the task's own time) and bytes moved (scattered records, returned reports), from batch.json.

The command runs as a subprocess (``shm diagnose DIR --scheduler tcp://...``) against a ``distributed.LocalCluster``
started here with the wanted number of single-thread worker processes. Noisy on a shared machine: quote as such.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

from workbench.records import write_record
from workbench.synth import synth_record, synth_test, truth_model

CANDIDATES = ["--candidates", "geometric_stiffening,m3", "--no-discover"]


def _records(folder: Path, n: int) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    for i in range(n):
        rec = synth_record(synth_test("mbit-b", duration_s=1.0),
                           truth_model("table2", ["geometric_stiffening"], {"kappa_nl": 1e4 * (1 + i % 4)}),
                           noise={"z3": 2e-6}, seed=i)
        write_record(rec, folder / f"rec{i:03d}.csv")


def _diagnose_on(records: Path, out: Path, n_workers: int) -> dict:
    import dask
    from distributed import LocalCluster

    with dask.config.set({"distributed.worker.daemon": False}), \
            LocalCluster(n_workers=n_workers, threads_per_worker=1, processes=True, dashboard_address=None,
                         memory_limit=0, silence_logs=50) as cluster:
        t0 = time.perf_counter()
        subprocess.run([str(Path(sys.executable).parent / "shm"), "diagnose", str(records), *CANDIDATES,
                        "--scheduler", cluster.scheduler_address, "--out", str(out)], check=True,
                       stderr=subprocess.DEVNULL, env=os.environ | {"MPLBACKEND": "Agg"})
        wall = time.perf_counter() - t0
    cost = json.loads((out / "batch.json").read_text())["cost"]
    return cost | {"command_wall_s": wall}


def run(out_dir: Path, quick: bool) -> dict:
    n = 8 if quick else 40
    base = Path(out_dir) / "scale_out"
    records = base / "records"
    _records(records, n)
    one = _diagnose_on(records, base / "one", 1)
    two = _diagnose_on(records, base / "two", 2)
    same = (base / "one" / "summary.csv").read_bytes() == (base / "two" / "summary.csv").read_bytes()
    return {
        "records": n,
        "wall_1_worker_s": one["wall_s"], "wall_2_workers_s": two["wall_s"],
        "speedup_2_vs_1": one["wall_s"] / two["wall_s"],
        "task_wall_mean_s": one["task_wall_s"] / n, "task_cpu_mean_s": one["task_cpu_s"] / n,
        "per_task_overhead_s": (one["wall_s"] - one["task_wall_s"]) / n,
        "warm_s_per_worker": max(one["warm_s"].values()),
        "bytes_scattered": one["bytes_scattered"], "bytes_returned": one["bytes_returned"],
        "bytes_per_task": (one["bytes_scattered"] + one["bytes_returned"]) / n,
        "summary_equal_1_vs_2_workers": same,
        "command_wall_1_worker_s": one["command_wall_s"], "command_wall_2_workers_s": two["command_wall_s"],
    }
