"""Regime changes and MBIT verdicts of the shipped scenarios against a golden record (issue 14, point 3).

``tests/data/board_golden_timeline.json`` was produced by the board + simulated rig *before* the speed work of issue
14 (PI step controller carried across calls, per-tick Python trimmed): every speed-up must leave the tick of every
regime change, every MBIT verdict and every visit verdict exactly as they were. Regenerate only for a deliberate
behaviour change: ``SHM_REGEN_GOLDEN=1 pytest tests/firmware_sim/test_board_golden_timeline.py``.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

GOLDEN = Path(__file__).parents[1] / "data" / "board_golden_timeline.json"
SCENARIOS = ("default", "maintenance", "degraded", "patch_leakage", "faults")


def _timeline(name: str) -> dict[str, list]:
    from board_config.board import load_board_config
    from board_config.scenario import load_scenario
    from drivers.sim_link import InProcessLink
    from firmware_sim.board import Board
    from firmware_sim.runner import BoardRunner
    from hil_stub.rig import SimulatedRig

    sc = load_scenario(name)
    cfg = load_board_config(overrides=sc.board_overrides, overrides_source=sc.source)
    rig = SimulatedRig(sc, tick=cfg.tick_period)
    link = InProcessLink(rig, tick=cfg.tick_period)
    board = Board(cfg, nominal=sc.rig.params)
    runner = BoardRunner(board, link, rearm_times=[e.at for e in sc.events_of("rearm")], trace_every=None)
    link.open()
    res = runner.run(sc.duration)
    return {
        "regime_changes": [[e.tick, e.data["from_regime"], e.data["to_regime"]]
                           for e in res.events if e.kind == "regime_change"],
        "mbit_verdicts": [[e.data["label"], e.data["verdict"]] for e in res.events if e.kind == "mbit_result"],
        "maintenance_verdicts": [[e.tick, e.data["verdict"]]
                                 for e in res.events if e.kind == "maintenance_verdict"],
    }


@pytest.mark.parametrize("name", SCENARIOS)
def test_timeline_matches_golden(name: str) -> None:
    got = _timeline(name)
    if os.environ.get("SHM_REGEN_GOLDEN"):
        data = json.loads(GOLDEN.read_text()) if GOLDEN.exists() else {}
        data[name] = got
        GOLDEN.write_text(json.dumps(data, indent=1))
    want = json.loads(GOLDEN.read_text())[name]
    assert got["regime_changes"] == want["regime_changes"]
    assert got["mbit_verdicts"] == want["mbit_verdicts"]
    assert got["maintenance_verdicts"] == want["maintenance_verdicts"]
    assert want["regime_changes"], "a golden timeline without a single regime change checks nothing"
