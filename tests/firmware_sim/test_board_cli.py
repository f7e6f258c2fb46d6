"""``shm run`` end to end on a short scenario (flight + gust + maintenance), and its bad-input handling."""

from __future__ import annotations

import json
import sqlite3

import numpy as np
import pytest

from shm_cli.main import main

SHORT = """
[scenario]
name = "cli-short"
seed = 2
expect_verdict = "PASS"

[rig]
params = "table2"
{deviations}

[board.sensing]
quiet_period = {{ value = 1.0, unit = "s" }}

[board.maintenance]
settle = {{ value = 0.2, unit = "s" }}
hv_debounce = {{ value = 0.1, unit = "s" }}

[[phase]]
kind = "flight"
duration = {{ value = 3.0, unit = "s" }}
vibration_rms = {{ value = 0.5, unit = "m/s^2" }}

[[phase]]
kind = "maintenance"
duration = {{ value = 24.5, unit = "s" }}

[[phase]]
kind = "ground"
duration = {{ value = 0.5, unit = "s" }}

[[event]]
kind = "gust"
at = {{ value = 0.5, unit = "s" }}
peak = {{ value = 12.0, unit = "m/s^2" }}
duration = {{ value = 0.5, unit = "s" }}
"""


@pytest.fixture()
def short_scenario(tmp_path):
    p = tmp_path / "short.toml"
    p.write_text(SHORT.format(deviations=""))
    return p


def test_shm_run_end_to_end(tmp_path, short_scenario, capsys):
    out = tmp_path / "run"
    rc = main(["run", "--scenario", str(short_scenario), "--out", str(out), "--timeline-every-s", "0"])
    captured = capsys.readouterr()
    assert rc == 0, captured.err
    text = captured.out
    for needle in ("STANDBY_HARVEST -> SENSING", "SENSING -> STANDBY_HARVEST", "usage ",
                   "STANDBY_HARVEST -> MAINTENANCE", "MBIT.a PASS", "MBIT.b PASS", "MAINTENANCE VERDICT PASS",
                   "MAINTENANCE -> STANDBY_HARVEST", "expected PASS: as expected"):
        assert needle in text, needle
    for f in ("usage.db", "timeline.txt", "trace.csv", "trace.npz", "overview.png", "maintenance.png", "usage.png",
              "summary.json", "report.html"):
        assert (out / f).stat().st_size > 0, f
    summary = json.loads((out / "summary.json").read_text())
    assert summary["verdict_as_expected"] is True and summary["ticks"] == 2800
    assert summary["realtime_factor"] > 0 and summary["final_regime"] == "STANDBY_HARVEST"
    # the log holds what the timeline printed
    db = sqlite3.connect(out / "usage.db")
    assert db.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
    n_changes = db.execute("SELECT count(*) FROM regime_changes").fetchone()[0]
    assert n_changes == text.count(" -> ") == len(summary["regime_changes"]) == 4
    verdicts = db.execute("SELECT verdict FROM mbit_results ORDER BY id").fetchall()
    assert verdicts == [("PASS",), ("PASS",)]
    assert db.execute("SELECT status FROM runs").fetchone()[0] == "finished"
    assert db.execute("SELECT count(*) FROM usage_summaries").fetchone()[0] >= 1
    # self-contained HTML: figures embedded, nothing fetched from elsewhere
    html = (out / "report.html").read_text()
    assert html.count("data:image/png;base64,") == 3
    assert 'src="http' not in html and "<link" not in html
    header = (out / "trace.csv").read_text().splitlines()[0]
    assert header.startswith("time_s,regime_code,z3_m") and "v_battery_V" in header


def test_shm_run_catches_a_degraded_laminate(tmp_path, capsys):
    p = tmp_path / "degraded.toml"
    p.write_text(SHORT.format(deviations="deviations = { k3 = -0.35, alpha_h = 0.35, beta_h = -0.35 }")
                 .replace('expect_verdict = "PASS"', 'expect_verdict = "FAULT"'))
    rc = main(["run", "--scenario", str(p), "--out", str(tmp_path / "d"), "--quiet", "--json"])
    out = capsys.readouterr().out
    assert rc == 0
    summary = json.loads(out)
    assert [r["verdict"] for r in summary["mbit_results"]] == ["FAULT", "FAULT"]
    assert summary["maintenance_verdicts"][-1]["verdict"] == "FAULT" and summary["verdict_as_expected"] is True


@pytest.mark.parametrize(("args", "needle"), [
    (["--scenario", "no-such"], "unknown scenario"),
    (["--seed", "-1"], "--seed"),
    (["--duration-s", "0"], "--duration-s"),
    (["--link", "carrier-pigeon://x"], "unknown link URL"),
    (["--params", "no-such-set"], "unknown parameter set"),
])
def test_shm_run_bad_input_exits_2(tmp_path, capsys, args, needle):
    base = ["run", "--quiet", "--out", str(tmp_path / "x")]
    if "--scenario" not in args:
        base += ["--scenario", "maintenance"]
    rc = main(base + args)
    err = capsys.readouterr().err
    assert rc == 2 and needle in err, err


@pytest.mark.parametrize("name", ["maintenance", "degraded", "patch_leakage", "faults"])
def test_shipped_short_scenarios_reach_their_expected_verdict(name):
    """The shipped maintenance-visit scenarios end with the verdict they state (a degraded laminate and leaking
    patches must be caught, the healthy one must pass); the fault scenario ends without a visit."""
    from board_config.board import load_board_config
    from board_config.scenario import load_scenario
    from drivers.sim_link import InProcessLink
    from firmware_sim.board import Board
    from firmware_sim.runner import BoardRunner
    from hil_stub.rig import SimulatedRig

    sc = load_scenario(name)
    cfg = load_board_config(overrides=sc.board_overrides, overrides_source=sc.source)
    link = InProcessLink(SimulatedRig(sc))
    link.open()
    res = BoardRunner(Board(cfg, nominal=sc.rig.params), link, trace_every=None,
                      rearm_times=[e.at for e in sc.events_of("rearm")]).run(sc.duration)
    verdicts = [e.data["verdict"] for e in res.events if e.kind == "maintenance_verdict"]
    assert (verdicts[-1] if verdicts else "NONE") == sc.expect_verdict


def test_whole_run_replays_identically_from_a_seed():
    """Board + rig + link from the same scenario and seed: the same events, tick for tick; another seed differs."""
    from board_config.board import load_board_config
    from board_config.scenario import load_scenario
    from drivers.sim_link import InProcessLink
    from firmware_sim.board import Board
    from firmware_sim.runner import BoardRunner
    from hil_stub.rig import SimulatedRig

    sc = load_scenario("faults")
    cfg = load_board_config(overrides=sc.board_overrides, overrides_source=sc.source)

    def once(seed):
        link = InProcessLink(SimulatedRig(sc, seed=seed))
        link.open()
        res = BoardRunner(Board(cfg), link, trace_every=1, rearm_times=[e.at for e in sc.events_of("rearm")]).run(60.0)
        return [(e.kind, e.tick, dict(e.data)) for e in res.events], res.trace.columns()["z3_m"].copy()

    a, b, c = once(3), once(3), once(4)
    assert a[0] == b[0] and len(a[0]) > 10
    assert np.array_equal(a[1], b[1], equal_nan=True)  # NaN where the link was down or the sensor faulty
    assert not np.array_equal(a[1], c[1], equal_nan=True)
