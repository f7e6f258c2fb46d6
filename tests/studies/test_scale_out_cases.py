"""Issue 31 point 3: the challenges' and benches' case loops on the scale-out runner (``python -m bench --scheduler``):
cases are tasks keyed by their position, their results and the per-case log come back in case order whatever order
the workers finish them in, a failing case is named, and a small subset gives the same results in this process
(``synchronous``) as on two local Dask workers. Point 3 of the fleet too: a board's life inside a Dask task runs its
visits in the task (no pool of its own sized to the CPU count)."""

from __future__ import annotations

import json
import operator
import sys
import types
from pathlib import Path

import pytest
from timings_support import timeless

import studies.batch.cases as cases_mod
from studies.batch import TaskResult
from studies.batch.cases import CaseFailed, case_key, run_case_task, run_cases
from studies.batch.runner import BatchOutcome


def _boom(x: int) -> int:
    if x == 2:
        raise ValueError("two is not allowed")
    return x


def test_cases_run_in_this_process_give_the_loops_results_in_case_order():
    seen = []
    results, outcome = run_cases(operator.mul, [(i, 3) for i in range(12)], scheduler="synchronous",
                                 on_result=seen.append, warm=None)
    assert results == seen == [3 * i for i in range(12)]
    assert [r.key for r in outcome.results] == [case_key(i) for i in range(12)]
    assert case_key(3) < case_key(10)  # zero-padded: the runner's key order is the case order


def test_results_reach_on_result_in_case_order_whatever_order_they_arrive_in(monkeypatch):
    def reversed_arrival(tasks, fn, options, *, on_result, **_):
        done = [fn(key, files, {}, options) for key, files in reversed(tasks)]
        for r in done:
            on_result(r)
        return BatchOutcome(sorted(done, key=lambda r: r.key), "fake", 2)

    monkeypatch.setattr(cases_mod, "run_tasks", reversed_arrival)
    seen = []
    results, _ = run_cases(operator.add, [(i, 100) for i in range(5)], on_result=seen.append, warm=None)
    assert seen == results == [100, 101, 102, 103, 104]


def test_a_failing_case_stops_the_run_naming_the_case_and_its_exception():
    seen = []
    with pytest.raises(CaseFailed, match=r"case00002 failed: ValueError: two is not allowed") as err:
        run_cases(_boom, [(0,), (1,), (2,), (3,)], scheduler="synchronous", on_result=seen.append, warm=None)
    assert seen == [0, 1]
    assert "_boom" in str(err.value)  # the worker's traceback comes with it
    r = run_case_task("case00000", {"case.pkl": __import__("pickle").dumps((2,))}, {}, _boom)
    assert isinstance(r, TaskResult) and r.code == 1


def test_bench_passes_scheduler_to_the_benchmarks_that_take_it(monkeypatch, tmp_path):
    import bench.__main__ as bench_main

    got = {}

    def run_takes(out, quick, scheduler=None):
        got["takes"] = scheduler
        return {}

    def run_plain(out, quick):
        got["plain"] = quick
        return {}

    takes, plain = types.ModuleType("fake_takes"), types.ModuleType("fake_plain")
    takes.run, plain.run = run_takes, run_plain
    monkeypatch.setitem(sys.modules, "fake_takes", takes)
    monkeypatch.setitem(sys.modules, "fake_plain", plain)
    monkeypatch.setattr(bench_main, "BENCHMARKS", ("fake_takes", "fake_plain"))
    assert bench_main.main(["--out", str(tmp_path), "--quick", "--scheduler", "synchronous"]) == 0
    assert got == {"takes": "synchronous", "plain": True}


def test_bench_refuses_a_bad_scheduler_in_one_line(capsys, tmp_path):
    import bench.__main__ as bench_main

    with pytest.raises(SystemExit) as ex:
        bench_main.main(["--out", str(tmp_path), "--scheduler", "my-laptop"])
    assert ex.value.code == 2
    assert "--scheduler 'my-laptop': expected local, synchronous or tcp://HOST:PORT" in capsys.readouterr().err


def test_a_board_life_in_a_dask_task_runs_its_visits_in_the_task(monkeypatch):
    """shm run --boards: the board's life must not start a pool sized to the CPU count inside a worker."""
    import studies.health.life as life_mod
    from shm_cli.fleet_cmd import _board_life_task
    from shm_cli.main import build_parser

    asked = []

    def no_life(*_a, workers=None, **_k):
        asked.append(workers)
        raise RuntimeError("stop here")

    monkeypatch.setattr(life_mod, "run_life", no_life)
    from board_config.scenario import load_scenario

    text = open(load_scenario("aging").source, encoding="utf-8").read().encode()
    args = build_parser().parse_args(["run", "--scenario", "aging", "--boards", "2", "--out", "unused"])
    args.command, args.quiet = "run", True
    r = _board_life_task("board001", {"scenario.toml": text}, {}, (args, 7))
    assert asked == [1], r.message


@pytest.mark.slow
def test_a_task_on_a_dask_worker_integrates_on_one_thread(monkeypatch):
    """A worker runs one task per thread and has one core: a task whose fits split each batch over every CPU of the
    machine (the default outside Dask) competes with the next worker's task — the fleet's 2-vs-1 speed-up was 1.6x.
    The worker plugin pins the integrator to one thread, whatever the worker inherited (here 2)."""
    from plant.stepper import default_threads

    monkeypatch.setenv("MFC_SHM_THREADS", "2")
    results, _ = run_cases(default_threads, [(), ()], scheduler="local", workers=1, warm=None)
    assert results == [1, 1]


@pytest.mark.slow
def test_longest_first_starts_the_tasks_with_the_most_input_first():
    """8 boards on 2 workers: a long board started last would run alone at the end. With ``longest_first`` the
    tasks start by their input's bytes, largest first (ties by key); here one worker, so start order = run order.
    Without it nothing about the order is promised (Dask breaks ties among equal priorities as it likes: a, c, b
    was seen on a clean clone), only that every task runs."""
    import pickle
    import time

    from studies.batch import run_tasks
    from studies.batch.cases import CASE_FILE, RESULT_FILE

    tasks = [(k, {CASE_FILE: pickle.dumps(()), "pad": b"x" * n}) for k, n in (("a", 10), ("b", 3000), ("c", 900))]
    for longest_first in (True, False):
        out = run_tasks(tasks, run_case_task, time.monotonic, scheduler="local", workers=1,
                        longest_first=longest_first)
        started = {r.key: pickle.loads(r.files[RESULT_FILE]) for r in out.results}
        if longest_first:
            assert sorted(started, key=started.__getitem__) == ["b", "c", "a"]
        else:
            assert sorted(started) == ["a", "b", "c"]


# --- the real loops on a small subset: this process vs two local Dask workers (slow) ---------------------------
@pytest.mark.slow
def test_hidden_effect_subset_is_the_same_in_this_process_and_on_two_local_workers(tmp_path):
    from bench import bench_hidden_effect as b

    todo = b.cases(True)
    subset = [todo[0], todo[5]]  # a null case and a hidden effect (MBIT.b, 2 µm)
    here, n_here = b.run_cases_logged(subset, tmp_path / "here.jsonl", "synchronous")
    local, n_local = b.run_cases_logged(subset, tmp_path / "local.jsonl", "local")
    assert (n_here, n_local) == (1, 2)
    assert [r.effect for r in here] == [r.effect for r in local] == [t[0].label for t in subset]
    dump = [json.dumps(timeless(r.to_dict()), sort_keys=True) for r in here]
    assert dump == [json.dumps(timeless(r.to_dict()), sort_keys=True) for r in local]
    logged = [json.loads(line) for line in (tmp_path / "local.jsonl").read_text().splitlines()]
    assert [x["effect"] for x in logged] == [t[0].label for t in subset]


@pytest.mark.slow
def test_health_challenge_subset_is_the_same_in_this_process_and_on_two_local_workers():
    from studies.health.challenge import challenge_lives, run_challenge

    lives = challenge_lives("smoke")[:2]
    lines: list[str] = []
    here = run_challenge(lives, workers=2, scheduler="synchronous")
    local = run_challenge(lives, workers=2, scheduler="local", progress=lines.append)
    assert [x.life for x in local.lives] == [x.life for x in here.lives] == [life.name for life in lives]
    assert timeless(local.to_json()["lives"]) == timeless(here.to_json()["lives"])
    assert json.dumps(local.summary.to_json(), sort_keys=True, default=str) == json.dumps(
        here.summary.to_json(), sort_keys=True, default=str)
    assert [ln.split()[0] for ln in lines] == [life.name for life in lives]


def test_the_docs_bench_commands_reach_benchmarks_that_take_the_scheduler(monkeypatch, tmp_path):
    """docs/scale-out.md's and README's ``python -m bench ... --scheduler`` lines: each names a benchmark whose run
    takes the option, and the option reaches it as written (the runs themselves replaced by a recorder)."""
    import importlib
    import inspect
    import shlex

    import bench.__main__ as bench_main

    root = Path(__file__).parents[2]
    doc = (root / "docs" / "scale-out.md").read_text(encoding="utf-8") + (root / "README.md").read_text("utf-8")
    lines = [ln.split("#")[0].strip() for ln in doc.splitlines()
             if ln.startswith("python -m bench ") and "--only" in ln]
    assert len(lines) >= 4
    for line in lines:
        argv = shlex.split(line)[3:]
        name = argv[argv.index("--only") + 1]
        module = importlib.import_module(f"bench.bench_{name}")
        assert "scheduler" in inspect.signature(module.run).parameters, name
        got = []
        monkeypatch.setattr(module, "run", lambda out, quick, scheduler=None, got=got: got.append(scheduler) or {})
        assert bench_main.main([*argv, "--out", str(tmp_path)]) == 0
        want = argv[argv.index("--scheduler") + 1] if "--scheduler" in argv else None
        assert got == [want], line


def test_bench_fleet_health_makes_a_short_fleet_and_compares_1_and_2_workers(monkeypatch, tmp_path):
    """bench_scale_out's fleet part: shm run --boards on the aging life cut to 5 visits, then shm health --fleet on
    a 1-worker and a 2-worker cluster (the runs replaced by recorders; the real run is make bench's)."""
    import bench.bench_scale_out as bso

    ran = []

    def fake_run(argv, **_):
        ran.append(argv)
        out = Path(argv[argv.index("--out") + 1])
        for i in range(int(argv[argv.index("--boards") + 1])):
            (out / f"board{i:03d}").mkdir(parents=True)

    cluster_runs = []

    def fake_cluster(argv, out, n_workers, doc_name):
        cluster_runs.append((out, n_workers))
        out.mkdir(parents=True)
        (out / "fleet.csv").write_text("same")
        return {"wall_s": 100.0 / n_workers ** 0.5, "task_wall_s": 90.0, "task_cpu_s": 30.0 * n_workers,
                "bytes_scattered": 10, "bytes_returned": 20, "workers": n_workers, "argv": argv}

    monkeypatch.setattr(bso.subprocess, "run", fake_run)
    monkeypatch.setattr(bso, "_on_cluster", fake_cluster)
    got = bso._fleet_health(tmp_path, 3, repeats=2)
    short = (tmp_path / "short.toml").read_text()
    assert 'visits = { value = 5, unit = "1" }' in short and 'visit_interval = { value = 250, unit = "h" }' in short
    assert ran[0][1:] == ["run", "--scenario", str(tmp_path / "short.toml"), "--boards", "3", "--seed", "3",
                          "--out", str(tmp_path / "boards"), "--force"]  # a rerun over the same --out
    assert got["fleet_boards"] == 3 and got["fleet_table_equal_1_vs_2_workers"]
    assert len(ran) == 1  # the fleet is made once, then run 1, 2, 1, 2 workers
    assert [(Path(o).name, w) for o, w in cluster_runs] == [
        ("health_w1_r0", 1), ("health_w2_r0", 2), ("health_w1_r1", 1), ("health_w2_r1", 2)]
    assert got["fleet_speedup_2_vs_1"] == pytest.approx(2 ** 0.5)
    assert got["fleet_repeats"][0]["cores_obtained_2_workers"] == pytest.approx(60 / (100 / 2 ** 0.5))


def test_a_lost_worker_during_the_cases_is_said_once_on_stderr(capsys):
    from studies.batch.runner import BatchProgress

    show = cases_mod._lost_workers_line("hidden-effect sweep")
    for p in (BatchProgress(1, 4, 2, 0, 0), BatchProgress(2, 4, 1, 1, 1), BatchProgress(3, 4, 1, 1, 1)):
        show(p)
    assert capsys.readouterr().err.splitlines() == [
        "hidden-effect sweep: 2/4 tasks done, 1 worker, 1 worker lost — 1 task rerun"]
