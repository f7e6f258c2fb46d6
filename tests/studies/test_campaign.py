"""Monte-Carlo campaign: ranges, draws, Wilson intervals, bit-for-bit reproducibility across executions, crash
reporting and resume, the result store, the ROC view, and the CLI's errors (small n throughout)."""

from __future__ import annotations

import functools
import json
import math

import numpy as np
import pytest
from campaign_crash_helper import crash_process_on, raise_on

from firmware_sim.condition_monitor import evaluate
from shm_cli.main import main
from studies.campaign import (
    CampaignStoreError,
    DeviationRange,
    build_spec,
    draw_deviations,
    load_traces,
    parse_ranges,
    roc_sweep,
    run_campaign,
    verdicts_at,
    wilson_interval,
)


def _arrays_equal(r1, r2) -> None:
    assert np.array_equal(r1.range_index, r2.range_index) and np.array_equal(r1.run_index, r2.run_index)
    assert np.array_equal(r1.rel_dev, r2.rel_dev) and np.array_equal(r1.values, r2.values)
    assert list(r1.mbits) == list(r2.mbits)
    for k in r1.mbits:
        a, b = r1.mbits[k], r2.mbits[k]
        for name in ("t", "z3_model", "z3_meas", "eps", "fault", "max_count", "max_eps", "status"):
            assert np.array_equal(getattr(a, name), getattr(b, name)), f"{k}.{name} differs"
        assert np.array_equal(a.fault_time, b.fault_time, equal_nan=True)


# --- ranges, draws, statistics -----------------------------------------------------------------------------


def test_parse_ranges_forms():
    assert [(r.lo, r.hi) for r in parse_ranges("0:50:10")] == [(0.0, 0.1), (0.1, 0.2), (0.2, 0.3), (0.3, 0.4),
                                                               (0.4, 0.5)]
    assert [(r.lo, r.hi) for r in parse_ranges("20:40")] == [(0.2, 0.4)]
    assert [(r.lo, r.hi) for r in parse_ranges("10-20, 40-50")] == [(0.1, 0.2), (0.4, 0.5)]
    assert parse_ranges("0:50:10")[2].label == "20-30%"


@pytest.mark.parametrize("spec, message", [
    ("", "empty"), ("0:50:0", "STEP must be positive"), ("50:0:10", "STOP"), ("0:45:10", "does not divide"),
    ("a:50:10", "not a number"), ("0:50:10:5", "START:STOP:STEP"), ("10-5", "HI > LO"), ("10", "not LO-HI"),
    ("-10:50:10", "percentage >= 0"), ("10-20,10-20", "listed twice"),
])
def test_parse_ranges_errors(spec, message):
    with pytest.raises(ValueError, match=message):
        parse_ranges(spec)


def test_wilson_interval_known_values():
    z2 = 1.959963984540054 ** 2
    lo, hi = wilson_interval(0, 100)
    assert lo == 0.0 and hi == pytest.approx(z2 / (100 + z2))  # the "rule of three"-like bound, 3.7 %
    lo, hi = wilson_interval(76, 100)
    assert (lo, hi) == pytest.approx((0.6677, 0.8331), abs=1e-4)
    lo2, hi2 = wilson_interval(24, 100)
    assert (lo2, hi2) == pytest.approx((1 - hi, 1 - lo))  # symmetric under k -> n - k
    assert all(math.isnan(v) for v in wilson_interval(0, 0))
    with pytest.raises(ValueError):
        wilson_interval(5, 4)


def test_draws_are_per_run_and_follow_the_sign_convention():
    r = DeviationRange(0.1, 0.2)
    all_runs = draw_deviations(5, r, np.arange(10), 3, "both")
    assert np.all((np.abs(all_runs) >= 0.1) & (np.abs(all_runs) < 0.2))
    assert (all_runs < 0).any() and (all_runs > 0).any()
    # a run's draw does not depend on which batch (or campaign size) it is drawn in
    assert np.array_equal(draw_deviations(5, r, np.arange(6, 10), 3, "both"), all_runs[6:])
    minus = draw_deviations(5, r, np.arange(10), 3, "minus")
    plus = draw_deviations(5, r, np.arange(10), 3, "plus")
    assert np.all(minus < 0) and np.all(plus > 0)
    assert np.array_equal(-minus, plus) and np.array_equal(np.abs(all_runs), plus)  # same magnitudes
    assert not np.array_equal(draw_deviations(6, r, np.arange(10), 3), all_runs)
    assert not np.array_equal(np.abs(draw_deviations(5, DeviationRange(0.2, 0.3), np.arange(10), 3)) - 0.1,
                              np.abs(all_runs))


def test_spec_validation():
    with pytest.raises(ValueError, match="--n must be a positive integer"):
        build_spec(n_runs=0)
    with pytest.raises(ValueError, match="unknown MBIT 'c'"):
        build_spec(mbits="c")
    with pytest.raises(ValueError, match=r"alpha_h at 1\.089"):
        build_spec(ranges="0:80:40", sign="plus")  # +80 % would put alpha_h = 0.605 * 1.8 outside [0, 1]
    with pytest.raises(ValueError, match="k3 at 0"):
        build_spec(ranges="0:100:50", sign="minus")
    with pytest.raises(ValueError, match="unknown parameter 'k9'"):
        build_spec(deviated=("k9",))
    with pytest.raises(ValueError, match="seed"):
        build_spec(seed=-1)


# --- running ----------------------------------------------------------------------------------------------

SMALL = {"params": "table2", "mbits": "both", "ranges": "0:30:10", "n_runs": 3, "seed": 11}


def test_bit_for_bit_whatever_the_workers_and_batching(tmp_path):
    serial = run_campaign(build_spec(**SMALL, batch_size=2), tmp_path / "serial", workers=1)
    pooled = run_campaign(build_spec(**SMALL, batch_size=1), tmp_path / "pool", workers=2)
    assert serial.complete and pooled.complete and "process pool" in pooled.executor
    _arrays_equal(serial.result, pooled.result)
    # the units of a smaller campaign are the same units (prefix property; other ranges do not matter)
    sub = run_campaign(build_spec(**{**SMALL, "ranges": "10-20", "n_runs": 2, "mbits": "b"}), tmp_path / "sub",
                       workers=1)
    full_b = serial.result.mbits["b"]
    rows = np.flatnonzero((serial.result.range_index == 1) & (serial.result.run_index < 2))
    assert np.array_equal(sub.result.mbits["b"].eps, full_b.eps[rows])
    assert np.array_equal(sub.result.values, serial.result.values[rows])
    # verdicts are the monitor's on the stored traces
    for key, runs in serial.result.mbits.items():
        tr = evaluate(runs.eps, serial.spec.monitor, runs.t)
        assert np.array_equal(tr.detected, runs.fault), key
    stats = serial.result.summary()
    assert sum(s.n_runs for s in stats if s.mbit == "a") == 9
    assert {s.mbit for s in stats} == {"a", "b", "any"}


def test_physics_sanity_tiny_deviation_never_alarms_large_one_is_caught(tmp_path):
    out = run_campaign(build_spec(ranges="0-0.01,40-50", n_runs=3, seed=2), tmp_path, workers=1)
    res = out.result
    tiny = res.range_index == 0
    for runs in res.mbits.values():
        assert not runs.fault[tiny].any() and runs.max_eps[tiny].max() < 0.01
    assert res.mbits["b"].fault[~tiny].all()  # 40-50 % deviations of (k3, alpha_h, beta_h)


def test_a_crashed_worker_is_reported_and_the_rerun_resumes(tmp_path):
    spec = build_spec(**{**SMALL, "mbits": "b"}, batch_size=1)
    keys = [b.key for b in spec.batches()]
    crash = functools.partial(crash_process_on, key=keys[-1])
    broken = run_campaign(spec, tmp_path, workers=2, batch_fn=crash)
    assert not broken.complete and broken.failures
    assert keys[-1] in {f.key for f in broken.failures}
    assert all("worker process died" in f.message for f in broken.failures)
    assert "rerun the same command" in broken.failure_message()
    stored = {p.stem for p in (tmp_path / "batches").glob("*.npz")}
    assert stored == set(keys) - {f.key for f in broken.failures}
    resumed = run_campaign(spec, tmp_path, workers=1)
    assert resumed.complete and resumed.n_reused == len(stored)
    assert resumed.n_reused + resumed.n_computed == len(keys)
    clean = run_campaign(spec, tmp_path / "clean", workers=1)
    _arrays_equal(resumed.result, clean.result)


def test_a_failing_batch_loses_nothing_else(tmp_path):
    spec = build_spec(**{**SMALL, "mbits": "b"}, batch_size=2)
    keys = [b.key for b in spec.batches()]
    out = run_campaign(spec, tmp_path, workers=1, batch_fn=functools.partial(raise_on, key=keys[1]))
    assert [f.key for f in out.failures] == [keys[1]] and "injected failure" in out.failures[0].message
    assert out.n_computed == len(keys) - 1 and out.result is None
    again = run_campaign(spec, tmp_path, workers=1)
    assert again.complete and again.n_reused == len(keys) - 1 and again.n_computed == 1


def test_store_refuses_a_different_campaign_unless_fresh(tmp_path):
    spec = build_spec(**{**SMALL, "mbits": "b", "n_runs": 1})
    run_campaign(spec, tmp_path, workers=1)
    other = build_spec(**{**SMALL, "mbits": "b", "n_runs": 1, "seed": 12})
    with pytest.raises(CampaignStoreError, match=r"different campaign \(seed: stored 11, requested 12\)"):
        run_campaign(other, tmp_path, workers=1)
    assert len(list((tmp_path / "batches").glob("*.npz"))) == 3  # nothing lost
    out = run_campaign(other, tmp_path, workers=1, fresh=True)
    assert out.complete and out.n_reused == 0


def test_roc_reuses_stored_traces_and_agrees_with_the_verdicts(tmp_path):
    out = run_campaign(build_spec(**SMALL), tmp_path, workers=1)
    out.result.save(tmp_path)
    tr = load_traces(tmp_path)
    mon = tr.monitor
    for key in tr.eps:
        ok = tr.status[key] == 0
        assert np.array_equal(verdicts_at(tr.eps[key], mon, mon.eps_th, mon.count_max), tr.fault[key])
        table = roc_sweep(tr.eps[key], tr.range_lo, tr.range_hi, ok, np.array([0.1, mon.eps_th, 0.5]),
                          np.array([50, mon.count_max]), mon, healthy_max=0.1, faulty_min=0.1)
        healthy = tr.range_hi <= 0.1 + 1e-12
        assert table.n_healthy == healthy.sum() and table.n_degraded == (~healthy).sum()
        assert table.false_alarms[1, 1] == tr.fault[key][healthy].sum()
        assert table.detections[1, 1] == tr.fault[key][~healthy].sum()
        # raising the threshold or the counter limit can only remove faults
        assert np.all(np.diff(table.detections, axis=0) <= 0) and np.all(np.diff(table.detections, axis=1) <= 0)


# --- the command line --------------------------------------------------------------------------------------


# the command's bad options and their one-line errors: the bad-input corpus (tests/data/bad_inputs/options.txt)


def test_cli_runs_writes_the_fig11_files_and_roc(tmp_path, capsys):
    out = tmp_path / "c"
    code = main(["campaign", "--mbit", "both", "--ranges", "0:20:10", "--n", "2", "--seed", "3", "--workers", "1",
                 "--json", "--no-progress", "--out", str(out)])
    assert code == 0
    data = json.loads(capsys.readouterr().out)
    assert [r["range_lo_pct"] for r in data["summary"] if r["mbit"] == "a"] == [0.0, 10.0]
    for name in ("fig11.png", "fig11.svg", "fig11_table.csv", "fig11_table.md", "runs.csv", "traces.npz",
                 "roc.png", "roc.csv", "error_traces.png", "campaign.json", "paper_comparison.csv"):
        assert (out / name).exists(), name
    assert "MBIT.a" in (out / "fig11_table.md").read_text()
    header = (out / "runs.csv").read_text().splitlines()[0]
    assert "k3_N_per_m" in header and "fault_time_b_s" in header and "dev_beta_h_pct" in header
    # rerunning resumes from the store; the ROC command sweeps the stored traces
    assert main(["campaign", "--mbit", "both", "--ranges", "0:20:10", "--n", "2", "--seed", "3", "--workers", "1",
                 "--no-progress", "--no-figures", "--out", str(out)]) == 0
    assert "resumed: 2 of 2 batches" in capsys.readouterr().err
    assert main(["campaign-roc", "--from", str(out), "--eps-th", "0.1:0.3:0.1", "--count-max", "100,200",
                 "--json", "--out", str(tmp_path / "roc")]) == 0
    roc = json.loads(capsys.readouterr().out)["roc"]
    assert len(roc) == 2 * 3 * 2 and {r["mbit"] for r in roc} == {"a", "b"}
    assert (tmp_path / "roc" / "roc.png").exists() and (tmp_path / "roc" / "roc.csv").exists()
    assert main(["campaign-roc", "--from", str(tmp_path / "nothing")]) == 2
    assert "no stored campaign traces" in capsys.readouterr().err


def test_cli_reports_unfinished_batches_with_exit_1_and_resumes(tmp_path, capsys, monkeypatch):
    import studies.campaign as campaign_pkg

    real = campaign_pkg.run_campaign
    spec = build_spec(**{**SMALL, "mbits": "b", "n_runs": 2})
    bad_key = spec.batches()[1].key

    def failing(spec_, out_, **kw):
        return real(spec_, out_, **{**kw, "batch_fn": functools.partial(raise_on, key=bad_key)})

    args = ["campaign", "--mbit", "b", "--ranges", "0:30:10", "--n", "2", "--seed", "11", "--workers", "1",
            "--no-progress", "--no-figures", "--json", "--out", str(tmp_path)]
    monkeypatch.setattr(campaign_pkg, "run_campaign", failing)
    assert main(args) == 1
    captured = capsys.readouterr()
    assert f"1 of 3 batches did not finish (2 finished and stored in {tmp_path / 'batches'})" in captured.err
    assert bad_key in captured.err and "rerun the same command" in captured.err
    status = json.loads(captured.out)
    assert status["complete"] is False and [f["key"] for f in status["batches"]["failed"]] == [bad_key]
    monkeypatch.setattr(campaign_pkg, "run_campaign", real)
    assert main(args) == 0
    captured = capsys.readouterr()
    assert "resumed: 2 of 3 batches" in captured.err and json.loads(captured.out)["complete"] is True


def test_a_second_campaign_on_an_out_in_use_is_refused_and_touches_nothing(tmp_path, capsys):
    """Two campaigns on one --out would mix their batches in one store: the second is refused, naming the first."""
    from shm_cli.run_lock import OutputLock

    out = tmp_path / "c"
    out.mkdir()
    (out / "campaign.json").write_text('{"complete": true}')  # a finished campaign of the holder
    with OutputLock(out, command="shm campaign --out c"):
        code = main(["campaign", "--mbit", "a", "--ranges", "0:10:10", "--n", "1", "--seed", "3", "--workers", "1",
                     "--no-progress", "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2
    assert "is in use by another running shm campaign" in err and "pid" in err and "Traceback" not in err
    assert (out / "campaign.json").read_text() == '{"complete": true}'
    assert not (out / "batches").exists()
