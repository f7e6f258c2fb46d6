"""Scale out (issue 31): a 40-record ``shm diagnose`` (1 s MBIT.b records, two candidates, no discovery step) and a
fleet's ``shm health --fleet`` (8 boards of a short aging life, made by ``shm run --boards``) each on a local Dask
cluster of 1 worker and of 2 workers in the same run — speed-up, per-task overhead (wall per task on the cluster
minus the task's own time) and bytes moved (scattered inputs, returned reports), from batch.json / fleet.json.

The commands run as subprocesses (``shm diagnose DIR --scheduler tcp://...``, ``shm health --fleet ... --scheduler
tcp://...``) against a ``distributed.LocalCluster`` started here with the wanted number of single-thread worker
processes: cold workers (each run's warm-up loads the rooms and kernels: seconds per worker inside the run), and
for the diagnose also preloaded ones (``--preload shm_cli.batch_records``: a standing cluster's workers loaded them
when they started). Each run's fixed part and its pieces are reported. Noisy on a shared machine: quote as such.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

from workbench.records import write_record
from workbench.simulation import synth_record, synth_test, truth_model

CANDIDATES = ["--candidates", "geometric_stiffening,m3", "--no-discover"]
SHM = str(Path(sys.executable).parent / "shm")


def _records(folder: Path, n: int) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    for i in range(n):
        rec = synth_record(synth_test("mbit-b", duration_s=1.0),
                           truth_model("table2", ["geometric_stiffening"], {"kappa_nl": 1e4 * (1 + i % 4)}),
                           noise={"z3": 2e-6}, seed=i)
        write_record(rec, folder / f"rec{i:03d}.csv")


def _fleet(base: Path, n: int) -> list[Path]:
    """``n`` boards of the aging life shortened to 5 visits every 250 h (``shm run --boards n --seed 3``)."""
    from board_config.scenario import load_scenario

    text = Path(load_scenario("aging").source).read_text(encoding="utf-8")
    short = text.replace('visits = { value = 24, unit = "1" }', 'visits = { value = 5, unit = "1" }').replace(
        'visit_interval = { value = 100, unit = "h" }', 'visit_interval = { value = 250, unit = "h" }')
    if short == text:
        raise RuntimeError("bench_scale_out: the aging scenario's visits/visit_interval lines changed")
    base.mkdir(parents=True, exist_ok=True)
    (base / "short.toml").write_text(short, encoding="utf-8")
    subprocess.run([SHM, "run", "--scenario", str(base / "short.toml"), "--boards", str(n), "--seed", "3", "--out",
                    str(base / "boards"), "--force"], check=True, stderr=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                   env=os.environ | {"MPLBACKEND": "Agg"})
    return sorted(p for p in (base / "boards").glob("board*") if p.is_dir())


def _on_cluster(argv: list[str], out: Path, n_workers: int, doc_name: str, preload: bool = False) -> dict:
    """``shm ARGV --scheduler <a fresh LocalCluster of n_workers> --out OUT``: its cost document and wall time.
    ``preload``: the workers load the commands' rooms and kernels when they start (``dask worker --preload
    shm_cli.batch_records``, a standing cluster), not in the run."""
    import dask
    from distributed import LocalCluster

    # the cluster's own processes check their event loops every second (the recommended standing cluster,
    # docs/scale-out.md; at Dask's default 20 ms the scheduler and nannies here took ~5 % of a core beside the run)
    with dask.config.set({"distributed.worker.daemon": False, "distributed.admin.tick.interval": "1000ms"}), \
            LocalCluster(n_workers=n_workers, threads_per_worker=1, processes=True, dashboard_address=None,
                         memory_limit=0, silence_logs=50,
                         preload=["shm_cli.batch_records"] if preload else []) as cluster:
        t0 = time.perf_counter()
        subprocess.run([SHM, *argv, "--scheduler", cluster.scheduler_address, "--out", str(out)], check=True,
                       stderr=subprocess.DEVNULL, stdout=subprocess.DEVNULL, env=os.environ | {"MPLBACKEND": "Agg"})
        wall = time.perf_counter() - t0
    cost = json.loads((out / doc_name).read_text())["cost"]
    return cost | {"command_wall_s": wall}


def _fleet_health(base: Path, n: int) -> dict:
    boards = _fleet(base, n)
    argv = ["health", "--fleet", *map(str, boards), "--follow", "never", "--locate", "never"]
    one = _on_cluster(argv, base / "health_one", 1, "fleet.json")
    two = _on_cluster(argv, base / "health_two", 2, "fleet.json")
    same = (base / "health_one" / "fleet.csv").read_bytes() == (base / "health_two" / "fleet.csv").read_bytes()
    return {"fleet_boards": len(boards), "fleet_wall_1_worker_s": one["wall_s"], "fleet_wall_2_workers_s":
            two["wall_s"], "fleet_speedup_2_vs_1": one["wall_s"] / two["wall_s"],
            "fleet_task_wall_mean_s": one["task_wall_s"] / len(boards),
            "fleet_task_cpu_mean_s": one["task_cpu_s"] / len(boards),
            # task CPU over wall: the cores the run really got (2 workers on a loaded machine may get no more than 1)
            "fleet_cores_obtained_1_worker": one["task_cpu_s"] / one["wall_s"],
            "fleet_cores_obtained_2_workers": two["task_cpu_s"] / two["wall_s"],
            "fleet_per_task_overhead_s": (one["wall_s"] - one["task_wall_s"]) / len(boards),
            "fleet_bytes_scattered": one["bytes_scattered"], "fleet_bytes_returned": one["bytes_returned"],
            "fleet_table_equal_1_vs_2_workers": same,
            # why the speed-up is what it is, from the runs' own per-task cost records (CPU, not the noisy ratio)
            "fleet_speedup_explained": explain_speedup(one, two)}


def list_makespan(durations: list[float], workers: int) -> float:
    """When the last task ends (s) if the tasks start in this order, each on the first worker free (what Dask does
    with one thread per worker)."""
    free = [0.0] * workers
    for d in durations:
        i = free.index(min(free))
        free[i] += d
    return max(free)


def explain_speedup(one: dict, two: dict, workers: int = 2) -> dict:
    """The speed-up ``workers`` vs 1 the 1-worker run's own cost record allows (Amdahl): its serial part (connect,
    the warm-up waited for, scatter, a worker's first task beyond the others — paid once per worker, in parallel) and
    its tasks' times in their start order, shared over the workers first free (the imbalance of the last wave); and
    what the run on ``workers`` lost beyond that: its tasks ran slower beside each other (wall and own-thread CPU,
    summed over the same tasks) and the workers' own threads (event loop, heartbeats, profiler) took CPU beside the
    task. Empty when the cost has no per-task record."""
    tasks1 = sorted(one.get("tasks") or [], key=lambda t: t.get("start_s") or 0.0)
    tasks2 = two.get("tasks") or []
    if not tasks1 or not tasks2:
        return {}
    ph1, ph2 = one.get("phases_s", {}), two.get("phases_s", {})
    first = max(0.0, ph1.get("first_task_extra", 0.0))
    serial = ph1.get("connect", 0.0) + ph1.get("warm", 0.0) + ph1.get("scatter", 0.0) + first
    steady = [t["wall_s"] for t in tasks1]
    steady[0] -= first
    makespan = list_makespan(steady, workers)
    ideal_wall = serial + makespan

    def other_threads(tasks: list[dict]) -> float:
        own = sum(t["thread_cpu_s"] for t in tasks)
        return (sum(t["cpu_s"] for t in tasks) - own) / own if own else 0.0

    return {"serial_s": serial, "serial_parts_s": {k: ph1.get(k, 0.0) for k in ("connect", "warm", "scatter")}
            | {"first_task_extra": first}, "task_wall_s": {t["key"]: t["wall_s"] for t in tasks1},
            "tasks_s": sum(steady), "makespan_on_workers_s": makespan,
            "imbalance": makespan / (sum(steady) / workers),
            "ideal_wall_s": ideal_wall, "ideal_speedup": one["wall_s"] / ideal_wall,
            "task_wall_slowdown": sum(t["wall_s"] for t in tasks2) / sum(t["wall_s"] for t in tasks1),
            "task_thread_cpu_slowdown": sum(t["thread_cpu_s"] for t in tasks2) / max(
                1e-9, sum(t["thread_cpu_s"] for t in tasks1)),
            "worker_threads_cpu_share_1_worker": other_threads(tasks1),
            "worker_threads_cpu_share_workers": other_threads(tasks2),
            "measured_speedup": one["wall_s"] / two["wall_s"],
            "serial_s_workers_run": sum(ph2.get(k, 0.0) for k in ("connect", "warm", "scatter", "first_task_extra"))}


def _fixed_part(cost: dict, n: int) -> dict:
    """Where a run's wall went beside its tasks' steady work (s): connect, the warm-up waited for, scatter, what a
    worker's first task took beyond the others (imports, kernels, fonts the warm-up left), and the rest of the tasks
    phase beyond the steady work shared over the workers (waiting, the last wave, results coming back)."""
    ph, w = cost.get("phases_s", {}), max(1, cost["workers"])
    first = ph.get("first_task_extra", 0.0)
    steady = (cost["task_wall_s"] - w * first) / w
    parts = {"connect": ph.get("connect", 0.0), "warm": ph.get("warm", 0.0), "scatter": ph.get("scatter", 0.0),
             "first_task_extra": first, "tasks_beyond_steady": ph.get("tasks", 0.0) - first - steady}
    return {"fixed_s": cost["wall_s"] - steady, "fixed_parts_s": parts, "steady_task_mean_s": steady * w / n}


def run(out_dir: Path, quick: bool) -> dict:
    n = 8 if quick else 40
    base = Path(out_dir) / "scale_out"
    records = base / "records"
    _records(records, n)
    argv = ["diagnose", str(records), *CANDIDATES]
    one = _on_cluster(argv, base / "one", 1, "batch.json")
    two = _on_cluster(argv, base / "two", 2, "batch.json")
    same = (base / "one" / "summary.csv").read_bytes() == (base / "two" / "summary.csv").read_bytes()
    # the same on a standing cluster whose workers loaded the rooms and kernels when they started
    one_p = _on_cluster(argv, base / "one_preloaded", 1, "batch.json", preload=True)
    two_p = _on_cluster(argv, base / "two_preloaded", 2, "batch.json", preload=True)
    return {
        "records": n,
        "wall_1_worker_s": one["wall_s"], "wall_2_workers_s": two["wall_s"],
        "speedup_2_vs_1": one["wall_s"] / two["wall_s"],
        "task_wall_mean_s": one["task_wall_s"] / n, "task_cpu_mean_s": one["task_cpu_s"] / n,
        "cores_obtained_1_worker": one["task_cpu_s"] / one["wall_s"],
        "cores_obtained_2_workers": two["task_cpu_s"] / two["wall_s"],
        "per_task_overhead_s": (one["wall_s"] - one["task_wall_s"]) / n,
        "warm_s_per_worker": max(one["warm_s"].values()),
        "bytes_scattered": one["bytes_scattered"], "bytes_returned": one["bytes_returned"],
        "bytes_per_task": (one["bytes_scattered"] + one["bytes_returned"]) / n,
        "summary_equal_1_vs_2_workers": same,
        "command_wall_1_worker_s": one["command_wall_s"], "command_wall_2_workers_s": two["command_wall_s"],
        # the fixed part of each run (s) and its pieces; the steady task time of the 2-worker run against the
        # 1-worker run's says how much slower a task ran beside another one (shared cores, caches)
        "fixed_1_worker": _fixed_part(one, n), "fixed_2_workers": _fixed_part(two, n),
        "task_wall_mean_2_workers_s": two["task_wall_s"] / n,
        "preloaded_wall_1_worker_s": one_p["wall_s"], "preloaded_wall_2_workers_s": two_p["wall_s"],
        "preloaded_speedup_2_vs_1": one_p["wall_s"] / two_p["wall_s"],
        "preloaded_fixed_1_worker": _fixed_part(one_p, n), "preloaded_fixed_2_workers": _fixed_part(two_p, n),
        "speedup_explained": explain_speedup(one, two),
        "preloaded_summary_equal": (base / "one_preloaded" / "summary.csv").read_bytes() == (
            base / "one" / "summary.csv").read_bytes() == (base / "two_preloaded" / "summary.csv").read_bytes(),
        **_fleet_health(base / "fleet", 4 if quick else 8),
        "load_average_1min": os.getloadavg()[0],
    }
