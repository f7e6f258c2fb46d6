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


#: run in a fresh interpreter (a worker's first task): the fleet's warm-up, then one board's health task as a worker
#: runs it; prints the modules of the project and its numerical libraries that the task imported, and how many
#: compiled kernels it loaded — what each worker's first board paid beyond the others (0.5-0.7 s of CPU before)
_FIRST_TASK = """
import functools, gc, json, sys
from pathlib import Path
from numba.core.registry import CPUDispatcher
from shm_cli.batch_records import run_command_task, warm_workbench
from shm_cli.fleet_cmd import _board_files
from shm_cli.main import build_parser
from studies.batch.runner import timed_task

board = Path(sys.argv[1])
args = build_parser().parse_args(["health", "--fleet", str(board), *sys.argv[3:], "--out", sys.argv[2]])
args.command = "health"
warm_workbench("health")

def kernels():
    return sum(len(d.overloads) for d in gc.get_objects() if isinstance(d, CPUDispatcher))

before, loaded = set(sys.modules), kernels()
result = timed_task(run_command_task, board.name, _board_files(board), {}, args)
rooms = ("studies", "workbench", "plant", "reporting", "board_config", "scipy", "matplotlib", "numba")
print(json.dumps({"code": result.code, "kernels_loaded": kernels() - loaded,
                  "imported": sorted(m for m in set(sys.modules) - before if m.split(".")[0] in rooms)}))
"""


def test_a_workers_warm_up_leaves_a_fleet_boards_task_nothing_to_import_or_load(fleet):
    """Issue 31 point 5: each worker is warm before its first board — the health rooms, the fit room and scipy.stats
    / .optimize / .interpolate under them imported, the nominal model's lane integrator (a fit's batches) loaded —
    so a worker's first board runs as long as the others (measured: 0.5-0.7 s of CPU longer before)."""
    import subprocess
    import sys

    tmp, boards = fleet
    out = subprocess.run([sys.executable, "-c", _FIRST_TASK, str(boards / "board000"), str(tmp / "first"), *HEALTH],
                         capture_output=True, text=True, check=True, timeout=300)
    got = json.loads(out.stdout.strip().splitlines()[-1])
    assert got["code"] == 0
    assert got["imported"] == [] and got["kernels_loaded"] == 0, got
