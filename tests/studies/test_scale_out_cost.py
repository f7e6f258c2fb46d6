"""Issue 31 point 6: why a 2-worker run is not twice as fast, from the run's own cost record. Each task's start, wall,
process CPU and own-thread CPU are in the cost (``fleet.json`` / ``batch.json``); the bench turns the 1-worker
run's record into the speed-up Amdahl allows (serial part, last-wave imbalance); a Dask worker runs its tasks
without the statistical profiler, whose thread took CPU beside every task."""

from __future__ import annotations

import time

import pytest

from bench.bench_scale_out import explain_speedup, list_makespan
from studies.batch import TaskResult, run_tasks
from studies.batch.cases import run_cases
from studies.batch.warm import TICK_MS, profiler_running, refault_pages, tick_ms


def _burn(key: str, files: dict[str, bytes], shared: dict[str, bytes], options: float) -> TaskResult:
    t0 = time.thread_time()
    while time.thread_time() - t0 < options:
        sum(i * i for i in range(1000))
    return TaskResult(key, 0, "done")


def test_the_cost_records_each_tasks_start_wall_cpu_and_own_thread_cpu() -> None:
    outcome = run_tasks([("a", {}), ("b", {})], _burn, 0.05, scheduler="synchronous")
    tasks = outcome.cost()["tasks"]
    assert [t["key"] for t in tasks] == ["a", "b"]
    assert tasks[0]["start_s"] == 0.0 and tasks[1]["start_s"] >= 0.05
    for t in tasks:
        assert 0.05 <= t["thread_cpu_s"] <= t["cpu_s"] + 1e-3 and t["wall_s"] >= t["thread_cpu_s"] - 1e-3
    assert outcome.cost()["task_thread_cpu_s"] == pytest.approx(sum(t["thread_cpu_s"] for t in tasks))


def test_list_makespan_gives_each_task_to_the_first_free_worker() -> None:
    assert list_makespan([3.0, 1.0, 1.0, 1.0], 2) == 3.0
    assert list_makespan([1.0, 1.0, 1.0, 3.0], 2) == 4.0  # the long task left for the last wave
    assert list_makespan([2.0, 2.0], 1) == 4.0


def _cost(wall: float, phases: dict, tasks: list[tuple[str, float, float, float]]) -> dict:
    return {"wall_s": wall, "phases_s": phases,
            "tasks": [{"key": k, "start_s": s, "wall_s": w, "cpu_s": c, "thread_cpu_s": c * 0.9}
                      for k, (s, w, c) in zip("abc", [(t[1], t[2], t[3]) for t in tasks], strict=True)]}


def test_explain_speedup_is_amdahl_with_the_serial_part_and_the_last_wave() -> None:
    # 1 worker: connect 0.5 + warm 1 + a first task 0.5 s longer; three 3 s tasks -> 11 s
    one = _cost(11.0, {"connect": 0.5, "warm": 1.0, "scatter": 0.0, "first_task_extra": 0.5},
                [("c", 7.5, 3.0, 3.0), ("a", 0.0, 3.5, 3.5), ("b", 3.5, 3.0, 3.0)])
    two = _cost(9.5, {"connect": 0.5, "warm": 1.0, "scatter": 0.0, "first_task_extra": 0.5},
                [("a", 0.0, 4.0, 3.3), ("b", 0.0, 3.6, 3.3), ("c", 4.0, 3.6, 3.3)])
    got = explain_speedup(one, two)
    assert got["serial_s"] == pytest.approx(2.0)
    assert got["makespan_on_workers_s"] == pytest.approx(6.0)  # 3 tasks on 2 workers: two waves
    assert got["imbalance"] == pytest.approx(6.0 / 4.5)
    assert got["ideal_speedup"] == pytest.approx(11.0 / 8.0)
    assert got["task_wall_slowdown"] == pytest.approx(11.2 / 9.5)
    assert got["task_thread_cpu_slowdown"] == pytest.approx(9.9 / 9.5)
    assert got["worker_threads_cpu_share_1_worker"] == pytest.approx(1 / 9)
    assert explain_speedup({"wall_s": 1.0}, two) == {}  # a cost record without per-task times


@pytest.mark.slow
def test_a_dask_worker_runs_its_tasks_without_the_statistical_profiler() -> None:
    """Dask's worker samples its task thread's stack every 10 ms of wall time (for a dashboard nobody looks at here):
    4-18 % of a fleet task's CPU on a second thread, taken from the other worker's task on a full machine."""
    results, _ = run_cases(profiler_running, [()], scheduler="local", workers=1, warm=None)
    assert results == [False]


@pytest.mark.slow
def test_a_dask_worker_checks_its_event_loop_every_second_not_every_20_ms() -> None:
    """Dask's event-loop health check ran every 20 ms: ~2 % of a core per worker (and per scheduler, nanny) for the
    whole run, beside the tasks. Every second still reports a loop stuck for seconds."""
    results, _ = run_cases(tick_ms, [()], scheduler="local", workers=1, warm=None)
    assert results == [TICK_MS] and TICK_MS >= 1000


@pytest.mark.slow
def test_a_dask_worker_keeps_freed_memory_for_the_next_array() -> None:
    """A Dask nanny starts its worker with MALLOC_TRIM_THRESHOLD_=65536, which pins glibc's mmap threshold at 128 kB:
    every larger array was mapped fresh and its pages faulted in and zeroed again each time (a health task: 1.0-1.3 s
    of 5 s in the kernel). 2 MB: above that threshold, below numpy's 4 MB huge-page advice (512 faults of 4 kB)."""
    import platform

    results, _ = run_cases(refault_pages, [(2 << 20,)], scheduler="local", workers=1, warm=None)
    if platform.libc_ver()[0] == "glibc":  # elsewhere the worker's malloc is left as it is
        assert results[0] < 50, results
