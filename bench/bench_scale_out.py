"""Scale out (issue 31): a batch ``shm diagnose`` over board visits (each task one visit's two records as the board
runs them — MBIT.a, 20 s, and MBIT.b, 3 s — diagnosed with the shipped candidate library, no discovery step: ≈ 3.5 s
of CPU per task) and a fleet's ``shm health --fleet`` (boards of a short aging life, made by ``shm run --boards``),
each on a local Dask cluster of 1 worker and of 2 workers in the same run, **interleaved** (1, 2, 1, 2 …): the
median ratio 2 vs 1 worker and its spread over the repeats.

Each run's wall is split into its **start-up** (connect, the warm-up waited for, scatter, what a worker's first task
took beyond the others: paid once per worker, in parallel) and its **steady** part (the tasks phase without the first
task's extra); the bench quotes both ratios: end to end (wall / wall) and steady throughput (tasks per second of the
steady part), and what end-to-end ratio the measured start-up and throughput give for a batch of 40 such tasks
and on a standing cluster whose workers preloaded the rooms (``--preload shm_cli.batch_records``: a short pair of
runs of MBIT.b records measures that start-up). Also per-task overhead, bytes moved, the cores each run
obtained, and whether every run's summary / fleet table is the same. Noisy on a shared machine: quote as such.

The commands run as subprocesses (``shm diagnose DIR --scheduler tcp://...``, ``shm health --fleet ... --scheduler
tcp://...``) against a ``distributed.LocalCluster`` started here with the wanted number of single-thread worker
processes (cold workers: each run's warm-up loads the rooms and kernels).
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

from workbench.records import write_record
from workbench.simulation import synth_record, synth_test, truth_model

#: the shipped candidate library (the command's default), no discovery step (a separate, longer command)
DIAGNOSE_OPTIONS = ["--no-discover"]
#: the tests a board runs at a visit: one diagnose task per visit
VISIT = ("mbit-a", "mbit-b")
SHM = str(Path(sys.executable).parent / "shm")
#: (visits, repeats of the 1-then-2-worker pair) of the diagnose; (boards, repeats) of the fleet; MBIT.b records of
#: the preloaded pair (its start-up only). Full: the issue's 40 records (20 visits of MBIT.a + MBIT.b), two pairs;
#: ≈ 7 min on 2 quiet cores. 4 boards: their sizes left the last wave 12 % unbalanced (an ideal of 1.72x before any
#: loss); 6: 0.4 % over 2 workers.
FULL = {"visits": 20, "repeats": 2, "boards": 6, "fleet_repeats": 2, "preloaded_records": 4}
QUICK = {"visits": 4, "repeats": 2, "boards": 2, "fleet_repeats": 1, "preloaded_records": 4}
#: the issue's batch size (tasks), for the projected end-to-end ratio
ISSUE_TASKS = 40


def _records(folder: Path, n: int, tests: tuple[str, ...] = ("mbit-b",)) -> None:
    """``n`` tasks of records as the board runs them (the shipped tests: MBIT.a 20 s, MBIT.b 3 s), each task a
    different geometric stiffening and noise seed: one record ``recNNN.csv`` per task for one test, a subfolder
    ``visitNNN/`` with one record per test (a named group: one task) for several."""
    folder.mkdir(parents=True, exist_ok=True)
    for i in range(n):
        truth = truth_model("table2", ["geometric_stiffening"], {"kappa_nl": 1e4 * (1 + i % 4)})
        for test in tests:
            rec = synth_record(synth_test(test), truth, noise={"z3": 2e-6}, seed=i)
            if len(tests) == 1:
                write_record(rec, folder / f"rec{i:03d}.csv")
            else:
                (folder / f"visit{i:03d}").mkdir(exist_ok=True)
                write_record(rec, folder / f"visit{i:03d}" / f"{test}.csv")


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


# --- arithmetic (pure) ---------------------------------------------------------------------------------------------
def spread(values: list[float]) -> dict:
    """The median of ``values``, their least and greatest, and the range as a share of the median (0.1: the repeats
    lay within 10 % of the median's size)."""
    med = statistics.median(values)
    lo, hi = min(values), max(values)
    return {"median": med, "min": lo, "max": hi, "range_of_median": (hi - lo) / med if med else 0.0,
            "values": list(values)}


def start_up_and_steady(cost: dict) -> dict:
    """A run's wall (s) split in two: ``start_up_s``, everything before the first task could run — connect, the
    warm-up waited for (every worker at once), scatter — and ``steady_s``, the tasks phase (first submission to last
    result). A worker's first task still runs longer than the others (modules, kernels, fonts the warm-up left:
    ``first_task_extra``, once per worker, in parallel); that stays in the steady part, because the runner's estimate
    of it (the first task against the median of the others) is the difference in size too when the largest tasks
    start first (seen: 12.9 s and -2.1 s on a 4-board fleet): the steady ratio is then slightly below the pure one."""
    ph = cost.get("phases_s") or {}
    steady = max(1e-9, ph.get("tasks", cost["wall_s"]))
    return {"start_up_s": max(0.0, cost["wall_s"] - steady), "steady_s": steady,
            "start_up_parts_s": {k: ph.get(k, 0.0) for k in ("connect", "warm", "scatter")},
            "first_task_extra_s": ph.get("first_task_extra", 0.0)}


def end_to_end_ratio(start_up_1_s: float, steady_1_s: float, start_up_2_s: float, throughput_ratio: float) -> float:
    """The end-to-end ratio 2 vs 1 worker that a start-up and a steady throughput ratio give: the 1-worker wall
    (start-up + steady work) over the 2-worker one (its start-up + the same work at ``throughput_ratio`` times the
    rate). With a run's own parts it gives that run's measured ratio; with the work of a larger batch or a
    standing cluster's start-up, what those would measure."""
    return (start_up_1_s + steady_1_s) / (start_up_2_s + steady_1_s / throughput_ratio)


def pair_ratios(one: dict, two: dict) -> dict:
    """One repeat (the 1-worker run's cost, then the 2-worker run's): the end-to-end ratio, the steady throughput
    ratio, both start-ups, the task's own-thread CPU side by side against alone, and the cores each run obtained."""
    a, b = start_up_and_steady(one), start_up_and_steady(two)

    def own(cost: dict) -> float:
        return cost.get("task_thread_cpu_s") or sum(t.get("thread_cpu_s", 0.0) for t in cost.get("tasks") or [])

    return {"wall_1_worker_s": one["wall_s"], "wall_2_workers_s": two["wall_s"],
            "end_to_end": one["wall_s"] / two["wall_s"], "throughput": a["steady_s"] / b["steady_s"],
            "start_up_1_worker_s": a["start_up_s"], "start_up_2_workers_s": b["start_up_s"],
            "steady_1_worker_s": a["steady_s"], "steady_2_workers_s": b["steady_s"],
            "start_up_parts_1_worker_s": a["start_up_parts_s"], "start_up_parts_2_workers_s": b["start_up_parts_s"],
            "first_task_extra_1_worker_s": a["first_task_extra_s"],
            "first_task_extra_2_workers_s": b["first_task_extra_s"],
            "task_thread_cpu_2_vs_1": own(two) / own(one) if own(one) else None,
            "cores_obtained_1_worker": one["task_cpu_s"] / one["wall_s"],
            "cores_obtained_2_workers": two["task_cpu_s"] / two["wall_s"]}


def summarise_pairs(pairs: list[dict], n_tasks: int, project_to: int | None = None,
                    start_up_standing_s: tuple[float, float] | None = None) -> dict:
    """The repeats' medians and spreads: end-to-end and throughput ratio, start-up on 1 and 2 workers, steady time
    per task; and the end-to-end ratio those medians give for ``project_to`` tasks of the same kind and, with a
    standing cluster's start-ups (1 worker, 2 workers), for the same batch there."""
    med = {k: statistics.median(p[k] for p in pairs) for k in
           ("start_up_1_worker_s", "start_up_2_workers_s", "steady_1_worker_s", "throughput")}
    out = {"repeats": len(pairs), "end_to_end_ratio": spread([p["end_to_end"] for p in pairs]),
           "throughput_ratio": spread([p["throughput"] for p in pairs]),
           "start_up_1_worker_s": spread([p["start_up_1_worker_s"] for p in pairs]),
           "start_up_2_workers_s": spread([p["start_up_2_workers_s"] for p in pairs]),
           # task CPU / wall: below ~0.95 and ~1.9 the machine did not give the run its cores (the ratio says little)
           "cores_obtained_1_worker": spread([p["cores_obtained_1_worker"] for p in pairs]),
           "cores_obtained_2_workers": spread([p["cores_obtained_2_workers"] for p in pairs]),
           "steady_task_1_worker_s": med["steady_1_worker_s"] / n_tasks,
           "end_to_end_from_medians": end_to_end_ratio(med["start_up_1_worker_s"], med["steady_1_worker_s"],
                                                       med["start_up_2_workers_s"], med["throughput"])}
    if project_to:
        work = med["steady_1_worker_s"] * project_to / n_tasks
        out[f"end_to_end_at_{project_to}_tasks"] = end_to_end_ratio(
            med["start_up_1_worker_s"], work, med["start_up_2_workers_s"], med["throughput"])
    if start_up_standing_s:
        out["end_to_end_on_a_standing_cluster"] = end_to_end_ratio(
            start_up_standing_s[0], med["steady_1_worker_s"], start_up_standing_s[1], med["throughput"])
    return out


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


# --- the runs ------------------------------------------------------------------------------------------------------
def interleaved(run_once: Callable[[int, int], dict], repeats: int) -> list[tuple[dict, dict]]:
    """``run_once(workers, repeat)`` in the order 1, 2, 1, 2 … (a drift of the machine's speed during the bench
    then touches both sides of every pair alike): the pairs (1-worker cost, 2-worker cost)."""
    pairs = []
    for i in range(repeats):
        one = run_once(1, i)
        pairs.append((one, run_once(2, i)))
    return pairs


def _series(pairs: list[tuple[dict, dict]], n_tasks: int, project_to: int | None = None,
            standing: tuple[float, float] | None = None) -> tuple[dict, list[dict], dict]:
    """(the medians and spreads, each repeat's ratios, the Amdahl breakdown of the pair whose end-to-end ratio is
    the median — the lower middle one for an even number of repeats)."""
    rows = [pair_ratios(one, two) for one, two in pairs]
    summary = summarise_pairs(rows, n_tasks, project_to, standing)
    middle = sorted(range(len(rows)), key=lambda i: rows[i]["end_to_end"])[(len(rows) - 1) // 2]
    return summary, rows, explain_speedup(*pairs[middle])


def _headline(prefix: str, summary: dict) -> dict:
    """The scalars ``python -m bench`` prints: both ratios' median, least and greatest, and the start-ups."""
    out = {}
    for name, key in (("speedup_2_vs_1", "end_to_end_ratio"), ("throughput_speedup_2_vs_1", "throughput_ratio"),
                      ("start_up_1_worker_s", "start_up_1_worker_s"),
                      ("start_up_2_workers_s", "start_up_2_workers_s"),
                      ("cores_obtained_1_worker", "cores_obtained_1_worker"),
                      ("cores_obtained_2_workers", "cores_obtained_2_workers")):
        out[f"{prefix}{name}"] = summary[key]["median"]
        out[f"{prefix}{name}_min"], out[f"{prefix}{name}_max"] = summary[key]["min"], summary[key]["max"]
    return out


def _same_files(folders: list[Path], name: str) -> bool:
    return len({(f / name).read_bytes() for f in folders}) == 1


def _fleet_health(base: Path, n: int, repeats: int = 1) -> dict:
    boards = _fleet(base, n)
    argv = ["health", "--fleet", *map(str, boards), "--follow", "never", "--locate", "never"]
    outs: list[Path] = []

    def once(workers: int, i: int) -> dict:
        outs.append(base / f"health_w{workers}_r{i}")
        return _on_cluster(argv, outs[-1], workers, "fleet.json")

    pairs = interleaved(once, repeats)
    summary, rows, explained = _series(pairs, len(boards))
    one = pairs[0][0]
    return {"fleet_boards": len(boards), **_headline("fleet_", summary), "fleet": summary, "fleet_repeats": rows,
            "fleet_task_wall_mean_s": one["task_wall_s"] / len(boards),
            "fleet_task_cpu_mean_s": one["task_cpu_s"] / len(boards),
            "fleet_per_task_overhead_s": (one["wall_s"] - one["task_wall_s"]) / len(boards),
            "fleet_bytes_scattered": one["bytes_scattered"], "fleet_bytes_returned": one["bytes_returned"],
            "fleet_table_equal_1_vs_2_workers": _same_files(outs, "fleet.csv"),
            # why the ratio is what it is, from the median pair's own per-task cost records
            "fleet_speedup_explained": explained}


def _diagnose_batch(base: Path, n: int, repeats: int, n_preloaded: int) -> dict:
    records = base / "visits"
    _records(records, n, VISIT)
    outs: list[Path] = []

    def once(workers: int, i: int, folder: Path = records, preload: bool = False) -> dict:
        outs.append(base / f"{'preloaded' if preload else 'diagnose'}_w{workers}_r{i}")
        return _on_cluster(["diagnose", str(folder), *DIAGNOSE_OPTIONS], outs[-1], workers, "batch.json", preload)

    pairs = interleaved(once, repeats)
    cold_outs = list(outs)
    # a standing cluster (workers preloaded the rooms when they started): a short pair, for its start-up only
    _records(base / "records_preloaded", n_preloaded)
    pre = [once(w, 0, base / "records_preloaded", True) for w in (1, 2)]
    standing = (start_up_and_steady(pre[0])["start_up_s"], start_up_and_steady(pre[1])["start_up_s"])
    summary, rows, explained = _series(pairs, n, ISSUE_TASKS, standing)
    ones = [p[0] for p in pairs]
    warm = [max(c["warm_s"].values()) for p in pairs for c in p]
    return {"tasks": n, "records": n * len(VISIT),
            "record_lengths_s": {t: synth_test(t).duration_s for t in VISIT}, **_headline("", summary),
            f"end_to_end_at_{ISSUE_TASKS}_tasks": summary[f"end_to_end_at_{ISSUE_TASKS}_tasks"],
            "end_to_end_on_a_standing_cluster": summary["end_to_end_on_a_standing_cluster"],
            "diagnose": summary, "diagnose_repeats": rows,
            "task_wall_mean_s": statistics.median(c["task_wall_s"] for c in ones) / n,
            "task_cpu_mean_s": statistics.median(c["task_cpu_s"] for c in ones) / n,
            "per_task_overhead_s": statistics.median((c["wall_s"] - c["task_wall_s"]) / n for c in ones),
            # the warm-up runs on every worker at once: its wall on 2 workers against 1 (≈ 1: in parallel)
            "warm_s_per_worker": statistics.median(warm[0::2]),
            "warm_2_vs_1_workers": statistics.median(warm[1::2]) / statistics.median(warm[0::2]),
            "bytes_scattered": ones[0]["bytes_scattered"], "bytes_returned": ones[0]["bytes_returned"],
            "bytes_per_task": (ones[0]["bytes_scattered"] + ones[0]["bytes_returned"]) / n,
            "summary_equal_1_vs_2_workers": _same_files(cold_outs, "summary.csv"),
            "preloaded_start_up_1_worker_s": standing[0], "preloaded_start_up_2_workers_s": standing[1],
            "preloaded_start_up_parts_s": [start_up_and_steady(c)["start_up_parts_s"] for c in pre],
            "preloaded_first_task_extra_s": [start_up_and_steady(c)["first_task_extra_s"] for c in pre],
            "preloaded_summary_equal": _same_files(outs[-2:], "summary.csv"),
            "speedup_explained": explained}


def run(out_dir: Path, quick: bool) -> dict:
    size = QUICK if quick else FULL
    base = Path(out_dir) / "scale_out"
    load_before = os.getloadavg()[0]
    return {**_diagnose_batch(base, size["visits"], size["repeats"], size["preloaded_records"]),
            **_fleet_health(base / "fleet", size["boards"], size["fleet_repeats"]),
            "load_average_1min_before": load_before, "load_average_1min": os.getloadavg()[0]}
