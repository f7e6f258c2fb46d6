"""Issue 31 point 6: the scale-out bench's arithmetic. Runs 1 worker, 2 workers, 1, 2 … interleaved; each run's wall
split into its start-up (connect, warm-up, scatter, a first task's extra: once per worker, in parallel) and its
steady part; the median ratio over the repeats and its spread, end to end and in steady throughput, and the
end-to-end ratio those give for a larger batch or a standing cluster's start-up. The cluster runs themselves are
replaced by recorders here (the real run is ``python -m bench --only scale_out``)."""

from __future__ import annotations

from pathlib import Path

import pytest

import bench.bench_scale_out as bso


def _cost(wall: float, tasks_phase: float, first_extra: float, workers: int, own_cpu: float = 30.0) -> dict:
    return {"wall_s": wall, "workers": workers, "task_wall_s": 30.0, "task_cpu_s": 30.0, "task_thread_cpu_s": own_cpu,
            "warm_s": {f"w{i}": 1.5 for i in range(workers)}, "bytes_scattered": 100, "bytes_returned": 1000,
            "phases_s": {"connect": 0.3, "warm": 1.5, "scatter": 0.1, "tasks": tasks_phase,
                         "first_task_extra": first_extra}}


def test_spread_is_the_median_the_extremes_and_the_range_as_a_share_of_the_median():
    got = bso.spread([1.9, 1.6, 1.8])
    assert got["median"] == 1.8 and got["min"] == 1.6 and got["max"] == 1.9
    assert got["range_of_median"] == pytest.approx(0.3 / 1.8)
    assert bso.spread([1.0, 2.0])["median"] == 1.5  # an even number of repeats: the mean of the middle two


def test_a_runs_wall_is_start_up_plus_steady_work():
    # 20 s: connect 0.3 + warm 1.5 + scatter 0.1 + 0.1 s of writing, then 18 s of tasks; the first task's estimated
    # extra (1 s) stays in the steady part (the estimate is the size difference too when the largest start first)
    got = bso.start_up_and_steady(_cost(20.0, 18.0, 1.0, 1))
    assert got["steady_s"] == pytest.approx(18.0) and got["start_up_s"] == pytest.approx(2.0)
    assert got["start_up_parts_s"] == {"connect": 0.3, "warm": 1.5, "scatter": 0.1}
    assert got["first_task_extra_s"] == 1.0
    # a cost without phases (an old document): all of it steady
    assert bso.start_up_and_steady({"wall_s": 5.0}) == {"start_up_s": 0.0, "steady_s": 5.0, "first_task_extra_s": 0.0,
                                                        "start_up_parts_s": dict.fromkeys(
                                                            ("connect", "warm", "scatter"), 0.0)}


def test_the_end_to_end_ratio_is_explained_by_start_up_and_throughput():
    one, two = _cost(37.0, 35.0, 1.0, 1), _cost(21.2, 19.0, 1.0, 2, own_cpu=33.0)
    row = bso.pair_ratios(one, two)
    assert row["end_to_end"] == pytest.approx(37.0 / 21.2)
    assert row["throughput"] == pytest.approx(35.0 / 19.0)  # steady: the tasks phases
    assert row["start_up_1_worker_s"] == pytest.approx(2.0) and row["start_up_2_workers_s"] == pytest.approx(2.2)
    assert row["task_thread_cpu_2_vs_1"] == pytest.approx(1.1)
    # the run's own parts give its measured ratio back ...
    assert bso.end_to_end_ratio(2.0, 35.0, 2.2, row["throughput"]) == pytest.approx(row["end_to_end"])
    # ... twice the work: the start-up weighs half as much; no start-up: the throughput ratio itself
    assert bso.end_to_end_ratio(3.0, 68.0, 3.2, 34 / 18) == pytest.approx(71.0 / (3.2 + 36.0))
    assert bso.end_to_end_ratio(0.0, 34.0, 0.0, 1.9) == pytest.approx(1.9)


def test_the_repeats_are_summed_up_by_their_medians_and_spreads():
    rows = [bso.pair_ratios(_cost(w1, w1 - 2.0, 1.0, 1), _cost(w2, w2 - 2.0, 1.0, 2))
            for w1, w2 in ((37.0, 21.0), (41.0, 21.0), (37.0, 25.0))]
    got = bso.summarise_pairs(rows, 20, project_to=40, start_up_standing_s=(1.0, 1.0))
    assert got["repeats"] == 3
    assert got["end_to_end_ratio"]["median"] == pytest.approx(37.0 / 21.0)
    assert got["end_to_end_ratio"]["values"] == pytest.approx([37 / 21, 41 / 21, 37 / 25])
    assert got["throughput_ratio"]["median"] == pytest.approx(35.0 / 19.0)
    assert got["throughput_ratio"]["min"] == pytest.approx(35.0 / 23.0)
    assert got["start_up_1_worker_s"]["median"] == pytest.approx(2.0)
    assert got["cores_obtained_2_workers"]["values"] == pytest.approx([30 / 21, 30 / 21, 30 / 25])
    assert got["steady_task_1_worker_s"] == pytest.approx(35.0 / 20)
    r = 35.0 / 19.0
    assert got["end_to_end_from_medians"] == pytest.approx(37.0 / (2.0 + 35.0 / r))
    assert got["end_to_end_at_40_tasks"] == pytest.approx((2.0 + 70.0) / (2.0 + 70.0 / r))
    assert got["end_to_end_on_a_standing_cluster"] == pytest.approx(36.0 / (1.0 + 35.0 / r))


def test_the_runs_alternate_one_and_two_workers():
    order = []
    pairs = bso.interleaved(lambda w, i: order.append((w, i)) or {"w": w, "i": i}, 3)
    assert order == [(1, 0), (2, 0), (1, 1), (2, 1), (1, 2), (2, 2)]
    assert [(a["w"], b["w"], a["i"]) for a, b in pairs] == [(1, 2, 0), (1, 2, 1), (1, 2, 2)]


def test_the_diagnose_part_runs_interleaved_then_a_short_preloaded_pair(monkeypatch, tmp_path):
    ran = []
    walls = iter([37.0, 21.0, 41.0, 21.0, 37.0, 25.0, 8.0, 5.0])

    def fake_cluster(argv, out, n_workers, doc_name, preload=False):
        ran.append((Path(argv[1]).name, n_workers, preload))
        out.mkdir(parents=True)
        (out / "summary.csv").write_text(argv[1])
        wall = next(walls)
        return _cost(wall, wall - 2.0, 1.0, n_workers) | {"tasks": []}

    monkeypatch.setattr(bso, "_records", lambda folder, n, tests=(): folder.mkdir(parents=True, exist_ok=True))
    monkeypatch.setattr(bso, "_on_cluster", fake_cluster)
    got = bso._diagnose_batch(tmp_path, 20, 3, 4)
    assert ran == [("visits", 1, False), ("visits", 2, False)] * 3 + [
        ("records_preloaded", 1, True), ("records_preloaded", 2, True)]
    assert got["speedup_2_vs_1"] == pytest.approx(37.0 / 21.0)
    assert (got["speedup_2_vs_1_min"], got["speedup_2_vs_1_max"]) == pytest.approx((37 / 25, 41 / 21))
    assert got["throughput_speedup_2_vs_1"] == pytest.approx(35.0 / 19.0)
    assert got["preloaded_start_up_1_worker_s"] == pytest.approx(2.0)
    assert got["warm_2_vs_1_workers"] == pytest.approx(1.0)
    assert got["summary_equal_1_vs_2_workers"] and got["preloaded_summary_equal"]
    assert len(got["diagnose_repeats"]) == 3 and got["end_to_end_at_40_tasks"] > got["speedup_2_vs_1"]


def test_a_diagnose_task_is_one_visits_records_as_a_named_group(monkeypatch, tmp_path):
    """The bench's diagnose task: a visit's MBIT.a and MBIT.b (a subfolder: one task over both records), the shipped
    tests' own lengths; the batch sees one task per visit."""
    from studies.batch import expand_inputs

    made = []
    monkeypatch.setattr(bso, "synth_record", lambda test, truth, noise, seed: (test.kind, test.duration_s, seed))
    monkeypatch.setattr(bso, "write_record", lambda rec, path: made.append(rec) or path.write_text(str(rec)))
    bso._records(tmp_path, 2, bso.VISIT)
    assert made == [("mbit-a", 20.0, 0), ("mbit-b", 3.0, 0), ("mbit-a", 20.0, 1), ("mbit-b", 3.0, 1)]
    tasks = expand_inputs([str(tmp_path)])
    assert [(t.key, sorted(f.name for f in t.files)) for t in tasks] == [
        ("visit000", ["mbit-a.csv", "mbit-b.csv"]), ("visit001", ["mbit-a.csv", "mbit-b.csv"])]
