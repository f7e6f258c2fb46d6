"""Issue 17 points 3 and 2 (the parts added last): where a stiffness loss is (each section stiffness freed alone,
scored on held-out data) and flights ticked between the visits of a [life] scenario."""

from __future__ import annotations

import json
import re
import subprocess
import sys

import pytest
from scenario_text_support import gust, life_scenario, phases

from board_config.errors import ConfigError
from board_config.scenario import load_scenario


def _synth(path, test, hours, seed, *dev):
    args = [sys.executable, "-m", "shm_cli.main", "synth", "--test", test, "--params", "table2",
            "--operating-hours", str(hours), "--seed", str(seed), "--out", str(path)]
    for d in dev:
        args += ["--deviation", d]
    r = subprocess.run(args, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    return str(path)


@pytest.fixture(scope="module")
def nominal_visit(tmp_path_factory):
    d = tmp_path_factory.mktemp("nominal")
    return [_synth(d / f"{t}.csv", t, 0, 5) for t in ("mbit-a", "mbit-b")]


def test_a_k2_loss_is_not_placed_in_section_3(tmp_path, nominal_visit):
    """Truth: section 2 loses 12 % of its stiffness. The health fit frees k3 (and sees a k3 change); the page must
    not claim section 3: it names section 2 or says the records cannot tell 1 from 2 and names the separating test."""
    files = nominal_visit + [_synth(tmp_path / f"{t}.csv", t, 500, 7, "k2=-0.12") for t in ("mbit-a", "mbit-b")]
    r = subprocess.run([sys.executable, "-m", "shm_cli.main", "health", *files, "--params", "table2", "--workers",
                        "1", "--locate-visits", "2", "--json", "--out", str(tmp_path / "h")],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    doc = json.loads(r.stdout)
    loc = doc["location"]
    # --locate-visits 2: the nominal visit too — nothing to place there
    assert [h["operating_hours"] for h in loc["history"]] == [0, 500]
    assert loc["history"][0]["distinguishable"] is None and loc["history"][1]["section"] == loc["section"]
    assert loc["run"] and loc["operating_hours"] == 500  # auto: k3 moved at the latest visit
    assert loc["section"] != 3 and 3 not in loc["possible_sections"] and 2 in loc["possible_sections"]
    k2 = next(c for c in loc["candidates"] if c["name"] == "k2")
    assert k2["relative"] == pytest.approx(-0.12, abs=0.01)
    assert loc["ranking"][0] == "k2"
    where = doc["levels"]["where"]
    assert "section 3 (" not in where and "in section 3" not in where
    if loc["distinguishable"]:
        assert loc["section"] == 2 and "stiffness loss in section 2" in where
    else:
        assert loc["separating_test"] and "second mode" in where and "section 3 is ruled out" in where
    assert "Where?" in (tmp_path / "h" / "report.html").read_text()


def test_a_k3_loss_is_placed_in_section_3(tmp_path, nominal_visit):
    """The positive control on the same records' kind: a tip-section loss is placed, with its size."""
    from studies.health.locate import locate_stiffness, location_sentence
    from workbench.records import load_record

    recs = [load_record(_synth(tmp_path / f"{t}.csv", t, 500, 9, "k3=-0.12")) for t in ("mbit-a", "mbit-b")]
    loc = locate_stiffness(recs, "table2", operating_hours=500.0)
    p = loc.placement
    assert p.distinguishable is True and p.section == 3 and p.parameter == "k3"
    assert p.relative == pytest.approx(-0.12, abs=0.005)
    assert re.match(r"stiffness loss in section 3 \(k3 -1[12]\.\d+ ± \d\.\d+ %\)", location_sentence(loc.to_json()))
    # nothing moved: nothing to place
    loc0 = locate_stiffness([load_record(p) for p in nominal_visit], "table2")
    assert loc0.placement.distinguishable is None and loc0.placement.section is None


FLIGHT = ('[scenario]\nname = "short-flight"\n' + phases(("ground", "1", "taxi"), ("flight", "3", "cruise"))
          + gust("2", "15.0", "1.2") + phases(("maintenance", "30")))

LIFE = life_scenario("tick-life", 2, 100, laws=(), more_life=(
    'flights_between_visits = { value = 40, unit = "1" }\ntick_flights = { value = TICK, unit = "1" }\n'
    'flight_scenario = "flight.toml"\n'))


def test_ticked_flights_run_the_board_through_the_flight_phases_before_each_visit(tmp_path):
    from studies.health.life import run_life, visit_line, with_ticked_flights

    (tmp_path / "flight.toml").write_text(FLIGHT)
    (tmp_path / "life.toml").write_text(LIFE.replace("TICK", "2"))
    sc = load_scenario(tmp_path / "life.toml")
    assert sc.life is not None and sc.life.tick_flights == 2 and sc.life.flight_scenario == "flight.toml"
    composed, flight_s = with_ticked_flights(sc, 2)
    assert flight_s == pytest.approx(8.0)  # two flights of 1 + 3 s (the flight scenario's maintenance is not one)
    assert [p.kind for p in composed.phases] == ["ground", "flight"] * 2 + ["ground", "maintenance"]
    assert [e.at for e in composed.events_of("gust")] == [2.0, 6.0]
    life = run_life(sc, seed=3, params="table2", workers=1)
    v1, v2 = life.visits
    assert v1.flights is None  # entry into service: no flights before the first visit
    assert v2.flights is not None and v2.flights.ticked == 2 and v2.flights.board_time_s == pytest.approx(8.0)
    assert v2.flights.events  # the board ran (and logged) through the flights
    start = [next(e.time for e in v.events if e.kind == "mbit_start") for v in (v1, v2)]
    assert start[1] - start[0] == pytest.approx(8.0, abs=0.02)  # the visit comes after the ticked flights
    assert "after 2 ticked flight(s)" in visit_line(v2) and [v.verdict for v in life.visits] == ["PASS", "PASS"]
    (tmp_path / "bad.toml").write_text(LIFE.replace("TICK", "-1"))
    with pytest.raises(ConfigError, match="tick_flights"):
        load_scenario(tmp_path / "bad.toml")
