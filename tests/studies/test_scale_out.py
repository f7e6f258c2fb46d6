"""Issue 31 (scale out), the fast parts: a folder or glob becomes tasks (a subfolder a named group), the runner
orders results by key whatever the completion order, bad --scheduler input is one clear line (exit 2)."""

from __future__ import annotations

import pytest

from board_config.errors import InputError
from shm_cli.main import main
from studies.batch import TaskResult, expand_inputs, is_batch_input, run_tasks
from studies.batch.runner import check_scheduler
from studies.batch.summary import scalar_columns


def _tree(tmp_path):
    (tmp_path / "recs" / "group").mkdir(parents=True)
    for name in ("recs/b.csv", "recs/a.tdms", "recs/group/x.csv", "recs/group/y.csv", "recs/notes.txt"):
        (tmp_path / name).write_text(name)
    (tmp_path / "recs" / "empty").mkdir()
    return tmp_path / "recs"


def test_a_folder_is_one_task_per_record_and_one_per_named_group(tmp_path):
    recs = _tree(tmp_path)
    tasks = expand_inputs([str(recs)])
    assert [(t.key, [f.name for f in t.files]) for t in tasks] == [
        ("a", ["a.tdms"]), ("b", ["b.csv"]), ("group", ["x.csv", "y.csv"])]
    assert tasks[2].read() == {"x.csv": b"recs/group/x.csv", "y.csv": b"recs/group/y.csv"}
    assert [t.key for t in expand_inputs([str(recs / "*.csv")])] == ["b"]
    assert is_batch_input([str(recs)]) and is_batch_input(["x/*.csv"]) and not is_batch_input([str(recs / "b.csv")])


def test_same_stem_in_two_places_and_missing_inputs(tmp_path):
    recs = _tree(tmp_path)
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "b.csv").write_text("b")
    assert [t.key for t in expand_inputs([str(recs / "b.csv"), str(tmp_path / "other" / "b.csv")])] == [
        "other__b", "recs__b"]
    with pytest.raises(InputError, match="matches no file"):
        expand_inputs([str(tmp_path / "nothing*.csv")])
    with pytest.raises(InputError, match="no record files"):
        expand_inputs([str(recs / "empty")])
    with pytest.raises(InputError, match="tcp://HOST:PORT"):
        check_scheduler("127.0.0.1:8786")


def _slow_first(key, files, shared, options):
    return TaskResult(key, 0, f"{key}:{files['f']!r}:{shared['p']!r}:{options}")


def test_results_are_ordered_by_key_and_see_shared_inputs():
    out = run_tasks([("z", {"f": b"1"}), ("a", {"f": b"2"})], _slow_first, "opt", shared={"p": b"P"},
                    scheduler="synchronous")
    assert [r.message for r in out.results] == ["a:b'2':b'P':opt", "z:b'1':b'P':opt"]


def test_summary_columns_carry_units():
    row = scalar_columns({"verdict": "missing", "held_rms_sigma": 1.5, "n": 3, "wall_s": 2.0, "flag": True},
                         skip=("wall_s",))
    assert row == {"verdict": "missing", "held_rms_sigma": 1.5}


def test_scheduler_with_files_only_is_a_usage_error(tmp_path, capsys):
    rec = tmp_path / "r.csv"
    rec.write_text("t\n")
    assert main(["diagnose", str(rec), "--scheduler", "local", "--out", str(tmp_path / "o")]) == 2
    assert "--scheduler runs one task per record of a folder" in capsys.readouterr().err
    assert main(["compare", str(tmp_path), "--scheduler", "nowhere", "--out", str(tmp_path / "o")]) == 2
    assert "expected local, synchronous or tcp://HOST:PORT" in capsys.readouterr().err


def test_board_rates_scatter_deterministically_and_scale_only_the_life_laws():
    from studies.batch.fleet import board_rate_factor, scaled_life

    factors = [board_rate_factor(3, i) for i in range(50)]
    assert factors[:2] == [board_rate_factor(3, 0), board_rate_factor(3, 1)] and len(set(factors)) == 50
    assert 0.8 < float(sorted(factors)[25]) < 1.25 and min(factors) > 0
    text = ("[rig]\nbattery = { value = 3.0, unit = \"V\" }\n[[life.law]]\nparameter = \"k3\"\n"
            "rate = { value = -2.0e-4, unit = \"1/h\" }\n[[life.law]]\namplitude = { value = 0.15, unit = \"1\" }\n"
            "[[phase]]\nrate = { value = 7, unit = \"1\" }\n")
    out = scaled_life(text, 2.0)
    assert "rate = { value = -0.0004, unit" in out and "amplitude = { value = 0.3, unit" in out
    assert "battery = { value = 3.0," in out and "rate = { value = 7, unit" in out  # outside [[life.law]]: kept


def test_fleet_ranks_faulty_first_then_earliest_forecast():
    from studies.batch.fleet import fleet_row, rank_fleet

    def doc(t, verdict, faulty=False):
        return {"forecast": {"trip_operating_hours": t, "trip_interval_90": [t and t - 10, t and t + 10],
                             "rul_hours": t and t - 900, "already_faulty": faulty},
                "visits": [{"operating_hours": 900.0, "board_verdict": verdict}],
                "location": {"parameter": "k3", "section": 3}}

    rows = rank_fleet([fleet_row("c", doc(1500.0, "PASS"), 0, ""), fleet_row("a", doc(None, "PASS"), 0, ""),
                       fleet_row("b", doc(1200.0, "PASS"), 0, ""), fleet_row("d", doc(950.0, "FAULT", True), 0, "")])
    assert [(r["rank"], r["board"]) for r in rows] == [(1, "d"), (2, "b"), (3, "c"), (4, "a")]
    assert rows[1]["first_fault_90_lo_h"] == 1190.0 and rows[1]["where"] == "k3 (section 3)"


@pytest.mark.parametrize("extra, needle", [
    (["--live", "127.0.0.1:0"], "--live"),
    (["--duration-s", "5"], "--duration-s"),
    (["--realtime"], "--realtime"),
    (["--seed", "-3"], "--seed"),
])
def test_a_fleet_refuses_what_a_life_refuses_before_any_task(tmp_path, capsys, extra, needle):
    code = main(["run", "--scenario", "aging", "--boards", "2", "--scheduler", "synchronous",
                 "--out", str(tmp_path / "fleet"), *extra])
    err = capsys.readouterr().err
    assert code == 2 and needle in err and "Traceback" not in err
    assert not list((tmp_path / "fleet").glob("board*"))


def test_a_fleet_does_not_overwrite_an_earlier_fleet(tmp_path, capsys):
    out = tmp_path / "fleet"
    (out / "board000").mkdir(parents=True)
    (out / "board000" / "summary.json").write_text("{}")
    code = main(["run", "--scenario", "aging", "--boards", "1", "--scheduler", "synchronous", "--out", str(out)])
    assert code == 2 and "earlier fleet" in capsys.readouterr().err
    assert (out / "board000" / "summary.json").read_text() == "{}"


def _fake_board(folder):
    folder.mkdir(parents=True)
    (folder / "usage.db").write_bytes(b"")
    return folder


def test_fleet_health_writes_neither_into_a_board_nor_over_another_commands_run(tmp_path, capsys):
    a, b = _fake_board(tmp_path / "a"), _fake_board(tmp_path / "b")
    code = main(["health", "--fleet", str(a), str(b), "--scheduler", "synchronous", "--out", str(a)])
    assert code == 2 and "one of the --fleet boards" in capsys.readouterr().err
    foreign = tmp_path / "cmp"
    foreign.mkdir()
    (foreign / "compare.json").write_text("{}")
    code = main(["health", "--fleet", str(a), str(b), "--scheduler", "synchronous", "--out", str(foreign)])
    assert code == 2 and "shm compare" in capsys.readouterr().err
    assert sorted(p.name for p in foreign.iterdir()) == ["compare.json"]


@pytest.mark.slow
def test_a_single_life_takes_the_scheduler_and_refuses_a_bad_one_before_any_worker(tmp_path, capsys, monkeypatch):
    """shm run on a [life] scenario runs its visits on Dask: --scheduler reaches the life's runner; a bad one is one
    line (exit 2) before anything is written."""
    import studies.health.life as life_mod

    code = main(["run", "--scenario", "aging", "--scheduler", "my-laptop", "--out", str(tmp_path / "a")])
    err = capsys.readouterr().err
    assert code == 2 and "--scheduler 'my-laptop'" in err and "Traceback" not in err
    assert not (tmp_path / "a" / "usage.db").exists()
    asked = []

    def no_life(*_a, scheduler=None, **_k):
        asked.append(scheduler)
        raise KeyboardInterrupt  # the command's "stopped at once" path: nothing written

    monkeypatch.setattr(life_mod, "run_life", no_life)
    main(["run", "--scenario", "aging", "--scheduler", "tcp://127.0.0.1:1", "--out", str(tmp_path / "b")])
    assert asked == ["tcp://127.0.0.1:1"]


def test_a_life_on_the_synchronous_scheduler_runs_its_visits_in_this_process(monkeypatch):
    """shm run --scenario LIFE --scheduler synchronous: no cluster, every visit here, in visit order."""
    import studies.board_run.life_pool as pool_mod
    import studies.health.life as life_mod
    from board_config.scenario import load_scenario

    def no_pool(*_a, **_k):
        raise AssertionError("a Dask cluster was started")

    monkeypatch.setattr(pool_mod, "LifePool", no_pool)
    monkeypatch.setattr(life_mod, "run_visit", lambda *a: a[1])  # the visit's number
    result = life_mod.run_life(load_scenario("aging"), seed=1, params="table2", workers=2, scheduler="synchronous")
    assert result.visits == list(range(1, 25)) and not result.interrupted


def test_first_task_extra_is_a_workers_first_task_beyond_the_others_median() -> None:
    from studies.batch import TaskResult
    from studies.batch.runner import first_task_extra

    arrived = [TaskResult("a", 0, "", wall_s=3.0, worker="w1"), TaskResult("b", 0, "", wall_s=2.0, worker="w2"),
               TaskResult("c", 0, "", wall_s=1.0, worker="w1"), TaskResult("d", 0, "", wall_s=1.2, worker="w2"),
               TaskResult("e", 0, "", wall_s=0.8, worker="w1")]
    assert first_task_extra(arrived) == pytest.approx(2.5 - 1.0)
    assert first_task_extra(arrived[:1]) == 0.0


def test_a_preloaded_worker_has_every_commands_rooms_before_a_run() -> None:
    """``dask worker --preload shm_cli.batch_records`` runs its dask_setup: the rooms, the figure fonts and the nominal
    kernel loaded once for the worker's life (a fresh interpreter, as a worker is)."""
    import subprocess
    import sys

    code = ("import sys, shm_cli.batch_records as b; b.dask_setup(None); "
            "print(' '.join(m for m in ('workbench.diagnose', 'workbench.localise', 'workbench.compare', "
            "'workbench.discover', 'matplotlib.pyplot') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=120)
    assert out.stdout.split() == ["workbench.diagnose", "workbench.localise", "workbench.compare",
                                  "workbench.discover", "matplotlib.pyplot"]
