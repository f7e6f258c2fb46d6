"""Health over time (issue 17): [life] scenarios, degradation laws, visit records, trends, the done-when chain."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
from scenario_text_support import life_scenario

from board_config.errors import ConfigError
from board_config.scenario import load_scenario, parse_scenario
from studies.health.laws import deviations_at
from studies.health.trend import fit_trend


def _life_toml(laws: list[dict]) -> dict:
    return {"scenario": {"name": "t"}, "life": {"visits": {"value": 5, "unit": "1"},
                                                "visit_interval": {"value": 50, "unit": "h"}, "law": laws},
            "phase": [{"kind": "maintenance", "duration": {"value": 30, "unit": "s"}}]}


def test_life_laws_combine_and_are_validated():
    sc = parse_scenario(_life_toml([
        {"parameter": "k3", "kind": "linear", "rate": {"value": -1e-3, "unit": "1/h"}},
        {"parameter": "k3", "kind": "step", "size": {"value": -0.1, "unit": "1"}, "at": {"value": 120, "unit": "h"}},
        {"parameter": "alpha_h", "kind": "power", "amplitude": {"value": 0.1, "unit": "1"},
         "reference": {"value": 100, "unit": "h"}, "exponent": {"value": 2, "unit": "1"}},
        {"parameter": "beta_h", "kind": "exponential", "amplitude": {"value": 0.01, "unit": "1"},
         "time_constant": {"value": 100, "unit": "h"}},
    ]), "t.toml")
    assert sc.life is not None and sc.life.visit_hours() == [0, 50, 100, 150, 200]
    d = deviations_at(sc.life.laws, 150.0)
    assert d["k3"] == pytest.approx(-0.15 - 0.1)
    assert d["alpha_h"] == pytest.approx(0.1 * 1.5 ** 2)
    assert d["beta_h"] == pytest.approx(0.01 * np.expm1(1.5))
    assert deviations_at(sc.life.laws, 100.0)["k3"] == pytest.approx(-0.1)  # the step is not there yet
    with pytest.raises(ConfigError, match=r"life.law\[0\].rate.unit"):
        parse_scenario(_life_toml([{"parameter": "k3", "kind": "linear", "rate": {"value": 1e-3, "unit": "1/s"}}]),
                       "t.toml")
    with pytest.raises(ConfigError, match="allowed"):
        parse_scenario(_life_toml([{"parameter": "k3", "kind": "wobble"}]), "t.toml")


def test_shipped_aging_scenario_describes_a_life():
    sc = load_scenario("aging")
    assert sc.life is not None and sc.life.visits == 24
    assert {law.parameter for law in sc.life.laws} == {"k3", "alpha_h", "beta_h"}


def test_trend_choice_on_known_histories():
    rng = np.random.default_rng(3)
    h = np.arange(0, 1000, 100.0)
    se = np.full(h.size, 0.002)
    flat = fit_trend("k3", h, rng.normal(0, 0.002, h.size), se)
    assert not flat.significant and flat.model == "none"
    lin = fit_trend("k3", h, -2e-4 * h + rng.normal(0, 0.002, h.size), se)
    assert lin.significant and lin.model in ("linear", "power", "exponential")
    assert lin.rate_per_100h(500) == pytest.approx(-0.02, abs=0.005)
    pw = fit_trend("alpha_h", h, 0.15 * (h / 1200) ** 2.5 + rng.normal(0, 0.001, h.size), np.full(h.size, 0.001))
    assert pw.significant and pw.model in ("power", "exponential")
    step = fit_trend("k3", h, np.where(h >= 450, -0.08, 0.0) + rng.normal(0, 0.002, h.size), se)
    assert step.significant and step.model == "change_point" and 400 < step.best.tau < 500


@pytest.mark.slow
def test_done_when_aging_run_then_health_forecast_holds_the_first_fault(tmp_path):
    """shm run --scenario aging, then shm health --as-of a few visits before the board's first FAULT: the four
    levels are printed and the 90 % trip interval holds the visit at which the same run's board first said FAULT."""
    run = tmp_path / "run"
    r = subprocess.run([sys.executable, "-m", "shm_cli.main", "run", "--scenario", "aging", "--quiet", "--out",
                        str(run)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    life = json.loads((run / "life.json").read_text())
    first = life["first_fault_visit"]
    assert first is not None and 8 <= first <= 15
    hours = {v["visit"]: v["operating_hours"] for v in life["visits"]}
    # every completed MBIT left a record that the workbench reads, stamped with its operating time
    from workbench.records import load_record

    rec = load_record(run / "records" / "visit-002_mbit-a.csv")
    assert rec.meta["operating_hours"] == hours[2] and rec.meta["test"] == "mbit-a"
    as_of = hours[first - 3]
    h = tmp_path / "health"
    r = subprocess.run([sys.executable, "-m", "shm_cli.main", "health", str(run), "--params", "table2", "--as-of",
                        str(as_of), "--json", "--out", str(h)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    doc = json.loads(r.stdout)
    for level in ("DETECTED?", "WHERE?", "HOW MUCH?", "HOW LONG?"):
        assert level in r.stderr
    assert doc == json.loads((h / "health.json").read_text())
    assert all(v["operating_hours"] <= as_of for v in doc["visits"])
    assert {e["name"] for e in doc["visits"][0]["estimates"]} == {"k3", "alpha_h", "beta_h"}
    f = doc["forecast"]
    lo_v, hi_v = f["trip_visits_90"]
    assert lo_v <= first <= hi_v, (f, first)
    assert f["rul_hours"] > 0 and doc["trend"]["alpha_h"]["significant"]


def _smoke_challenge(effect_group: bool):
    """The challenge's smoke lives of the "effect" group (or all the others), one process: the two halves are two
    tests, so that ``pytest -n 2`` runs them side by side instead of one test holding a worker for both."""
    from studies.health.challenge import challenge_lives, run_challenge

    lives = [life for life in challenge_lives("smoke") if (life.group == "effect") == effect_group]
    assert lives
    return run_challenge(lives, workers=1).summary


def test_prognosis_challenge_fast_subset():
    """The challenge's smoke size without the effect life (a linear life that trips, a stable life, a sudden
    damage): the physics-based forecast holds the true first FAULT visit, the stable laminate shows no trend, the
    step is placed between the right visits, and the feature-only baseline is scored on the same lives."""
    s = _smoke_challenge(effect_group=False)
    assert s.physics.lives_scored == 1 and s.physics.predictions >= 2
    assert s.physics.coverage is not None and s.physics.coverage >= 0.85
    assert s.stable_no_trend == 1.0 and s.sudden_placed == 1.0
    assert s.baseline is not None and s.baseline.predictions >= 1
    assert s.baseline.coverage is not None and s.physics.coverage >= s.baseline.coverage


def test_prognosis_challenge_fast_subset_follows_a_growing_leakage_to_its_cause():
    """The smoke size's patch whose leakage grows: followed to its cause (G_leak re-estimated and trended), and the
    physics-based forecast holds the true first FAULT visit."""
    s = _smoke_challenge(effect_group=True)
    assert s.effect_cause_followed is not None and s.effect_cause_followed.followed_to_the_effect == 1.0
    effect = s.by_group["effect"].physics
    assert effect.coverage is not None and effect.coverage >= 0.85
    assert s.physics.lives_scored == 1 and s.physics.predictions >= 2
    assert s.baseline is not None and s.baseline.coverage is not None
    assert s.physics.coverage is not None and s.physics.coverage >= 0.85 and s.physics.coverage >= s.baseline.coverage


def test_metrics_follow_progpy_definitions():
    from studies.health.metrics import alpha_lambda, alpha_lambda_point, interval_covers, prognostic_horizon

    t_eol = 1000.0
    times = [400.0, 600.0, 800.0]
    good = [np.full(100, 1000.0)] * 3
    far = [np.full(100, 1500.0), np.full(100, 1050.0), np.full(100, 1000.0)]
    assert alpha_lambda(times, good, t_eol) is True
    # lambda = 0.5: t_lambda = 700 h -> ProgPy judges the first prediction at or after it, 800 h (1000 h inside
    # 1000 +- 0.2*200 h); the one before it (600 h, 1050 h inside +-80 h) is not the one judged
    assert alpha_lambda(times, far, t_eol) is True
    late = [np.full(100, 1500.0), np.full(100, 1000.0), np.full(100, 1100.0)]
    assert alpha_lambda(times, late, t_eol) is False  # at/before t_lambda (600 h) would have said True
    assert alpha_lambda(times, late, t_eol) == alpha_lambda_point(times, late, t_eol, lam=0.5)["ok"]
    assert alpha_lambda(times, [np.full(100, 1200.0)] * 3, t_eol) is False
    assert prognostic_horizon(times, far, t_eol) == pytest.approx(400.0)
    assert prognostic_horizon(times, [np.full(100, 2000.0)] * 3, t_eol) is None
    assert interval_covers([900, 1100], 1000) and not interval_covers([1100, 1200], 1000)


def test_every_completed_mbit_leaves_a_record_linked_in_the_log(tmp_path):
    """A plain maintenance run: MBIT.a and MBIT.b each write a full-rate record the workbench loads, and the log's
    mbit_records table links each MBIT result (and verdict) to its file."""
    import sqlite3

    from workbench.records import load_record

    out = tmp_path / "run"
    r = subprocess.run([sys.executable, "-m", "shm_cli.main", "run", "--scenario", "maintenance", "--quiet",
                        "--out", str(out)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    db = sqlite3.connect(out / "usage.db")
    links = db.execute("SELECT mbit, verdict, path, mbit_result_id, n_samples FROM mbit_records ORDER BY id").fetchall()
    results = db.execute("SELECT id, mbit, verdict FROM mbit_results ORDER BY id").fetchall()
    assert [(m, v) for m, v, *_ in links] == [(m, v) for _, m, v in results] == [("a", "PASS"), ("b", "PASS")]
    assert [x[3] for x in links] == [x[0] for x in results]
    a = load_record(out / links[0][2])
    b = load_record(out / links[1][2])
    assert a.meta["test"] == "mbit-a" and b.meta["test"] == "mbit-b"
    assert a.sample_rate_Hz == pytest.approx(100.0)
    assert a.n_samples == links[0][4] and b.n_samples == links[1][4]
    # the drive is MBIT.a's: 600 V differential sine on a +100 V common mode, after a 2 s settle at 0 V
    va = (a["v_ch1"] - a["v_ch2"]) / 2
    assert np.max(va) == pytest.approx(600.0, rel=1e-3) and np.all(a["v_ch1"][a.t < 1.9] == 0.0)
    # the response is the laminate's: millimetres of tip motion, not noise
    assert 1e-3 < np.max(np.abs(a["z3"])) < 2e-2
    # a visit's records are consecutive ticks (b starts where a ended)
    ta = a.meta["provenance"]["board_time_s"]
    tb = b.meta["provenance"]["board_time_s"]
    assert tb == pytest.approx(ta + a.t[-1] + 0.01, abs=1e-6)


def test_stable_laminate_gets_no_trend_and_a_lower_bound_not_a_date(tmp_path):
    """Records from shm synth stamped with --operating-hours, a laminate that does not change: no significant trend,
    the forecast's date fields are null and a lower bound on the remaining life is given."""
    files = []
    for i, h in enumerate((0, 150, 300, 450)):
        f = tmp_path / f"b{h}.csv"
        r = subprocess.run([sys.executable, "-m", "shm_cli.main", "synth", "--test", "mbit-b", "--params", "table2",
                            "--deviation", "k3=-0.05", "--operating-hours", str(h), "--seed", str(i + 1), "--out",
                            str(f)], capture_output=True, text=True)
        assert r.returncode == 0, r.stderr
        files.append(str(f))
    r = subprocess.run([sys.executable, "-m", "shm_cli.main", "health", *files, "--params", "table2", "--workers",
                        "1", "--json", "--out", str(tmp_path / "h")], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    doc = json.loads(r.stdout)
    assert [v["operating_hours"] for v in doc["visits"]] == [0, 150, 300, 450]
    assert not any(t["significant"] for t in doc["trend"].values())
    f = doc["forecast"]
    assert f["trip_operating_hours"] is None and f["trip_interval_90"] is None and f["rul_hours"] is None
    assert f["p_fault_next_visit"] is None and f["lower_bound_hours"] > 450
    assert "no significant trend" in doc["levels"]["how_long"]
    k3 = [next(e for e in v["estimates"] if e["name"] == "k3") for v in doc["visits"]]
    assert all(abs(e["relative"] + 0.05) < 0.02 for e in k3)  # the constant offset is measured, not trended


def test_a_life_is_reproducible_by_seed_whatever_the_workers(tmp_path):
    """Visits draw their rig seed from (seed, visit): in one process or on a pool, the same MBIT results and
    records; another seed changes the noise."""
    from studies.health.life import run_life

    toml = tmp_path / "tiny.toml"
    toml.write_text(life_scenario("tiny-life", 3, 400))
    sc = load_scenario(toml)

    def results(seed, workers):
        life = run_life(sc, seed=seed, params="table2", workers=workers)
        return ([(v.visit, v.operating_hours, v.verdict, [(m.label, m.verdict, m.max_count, m.max_eps)
                                                           for m in v.mbits]) for v in life.visits],
                [e.data["rows"] for v in life.visits for e in v.events if e.kind == "mbit_record"])

    a, b, c = results(3, 1), results(3, 2), results(4, 1)
    assert a == b
    assert [v[2] for v in a[0]] == ["PASS", "PASS", "FAULT"]  # alpha_h +0 %, +8 %, +16 % (the monitor: ~+15 %)
    assert a[1] != c[1]


def test_health_bad_input_is_one_line_and_exit_2(tmp_path):
    rec = tmp_path / "no_hours.csv"
    rec.write_text("# test = \"mbit-b\"\ntime_s,v_ch1_V,v_ch2_V,z3_m\n0,0,0,0\n0.01,0,0,0\n0.02,0,0,0\n")
    cases = [
        ([str(tmp_path / "missing")], "no such file or directory"),
        ([str(rec)], "no 'operating_hours' header key"),
        ([str(rec), "--free", "gamma_h"], "--free 'gamma_h'"),
        ([str(rec), "--as-of", "-1"], "--as-of must be"),
    ]
    for argv, msg in cases:
        r = subprocess.run([sys.executable, "-m", "shm_cli.main", "health", *argv, "--out", str(tmp_path / "h")],
                           capture_output=True, text=True)
        assert r.returncode == 2, (argv, r.stderr)
        assert msg in r.stderr and "Traceback" not in r.stderr
