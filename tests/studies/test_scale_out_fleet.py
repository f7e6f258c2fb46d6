"""Issue 31 point 2: a fleet — ``shm run --scenario ... --boards 2 --seed 3`` (scattered rates), then
``shm health --fleet`` on local Dask workers equals the in-process (synchronous) run bit for bit, ranked by
forecast first FAULT, one report per board, --json one document."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from timings_support import timeless

from shm_cli.fleet_cmd import BOARD_GLOB
from shm_cli.main import main

pytestmark = pytest.mark.slow
HEALTH = ["--follow", "never", "--locate", "never"]


@pytest.fixture(scope="module")
def fleet(tmp_path_factory):
    from board_config.scenario import load_scenario

    tmp = tmp_path_factory.mktemp("fleet")
    text = open(load_scenario("aging").source, encoding="utf-8").read()
    short = text.replace('visits = { value = 24, unit = "1" }', 'visits = { value = 5, unit = "1" }').replace(
        'visit_interval = { value = 100, unit = "h" }', 'visit_interval = { value = 250, unit = "h" }')
    assert short != text
    (tmp / "short.toml").write_text(short)
    boards = tmp / "boards"
    assert main(["run", "--scenario", str(tmp / "short.toml"), "--boards", "2", "--seed", "3",
                 "--out", str(boards)]) == 0
    return tmp, boards


def test_fleet_health_local_workers_equal_the_in_process_run(fleet, capsys):
    tmp, boards = fleet
    assert (boards / "board000" / "usage.db").is_file() and (boards / "boards.csv").is_file()
    # the pattern shm run --boards suggests for shm health --fleet names the boards and nothing else (boards.csv)
    assert sorted(p.name for p in boards.glob(BOARD_GLOB)) == ["board000", "board001"]
    sources = [str(boards / "board000"), str(boards / "board001")]
    assert main(["health", "--fleet", *sources, *HEALTH, "--scheduler", "synchronous", "--out",
                 str(tmp / "ref")]) == 0
    ranked = [ln for ln in capsys.readouterr().out.splitlines() if ln.lstrip()[:1].isdigit()]
    # README's fleet walk shows this fleet's table: it must be what the code prints today
    readme = (Path(__file__).resolve().parents[2] / "README.md").read_text(encoding="utf-8")
    assert ranked and all(ln in readme.splitlines() for ln in ranked), ranked
    assert main(["health", "--fleet", *sources, *HEALTH, "--json", "--out", str(tmp / "local")]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert [r["board"] for r in doc["fleet"]] == ["board000", "board001"]  # board000's rates x1.67: first FAULT
    assert doc["fleet"][0]["first_fault_h"] <= doc["fleet"][1]["first_fault_h"]
    assert doc["cost"]["workers"] == 2
    assert (tmp / "ref" / "fleet.csv").read_bytes() == (tmp / "local" / "fleet.csv").read_bytes()
    for b in ("board000", "board001"):
        ref = json.loads((tmp / "ref" / b / "health.json").read_text())
        assert timeless(ref) == timeless(json.loads((tmp / "local" / b / "health.json").read_text()))
        assert (tmp / "local" / b / "report.html").stat().st_size > 1000
    assert "board000" in (tmp / "local" / "fleet.html").read_text()
