"""The board on a short maintenance scenario, over any link: what the board-over-links tests share
(``tests/drivers/test_links_board.py``, ``tests/firmware_sim/test_board_edges.py``, ``test_board_link_delay.py``).

The scenario is the shipped ``maintenance`` one with its parked and disconnected phases trimmed (same rig, same
MBITs, 29.5 s instead of 60 s of board time) to keep the suite fast.
"""

from __future__ import annotations

from pathlib import Path

from links_support import maintenance_scenario


def scenario_text(expect: str, deviations: str, maintenance_s: float = 28) -> str:
    """The shipped maintenance scenario with trimmed parked/disconnected phases, ``deviations`` (a TOML table)."""
    return maintenance_scenario(
        "maintenance-short", "The shipped maintenance scenario with trimmed parked/disconnected phases.",
        maintenance_s, verdict=expect, rig=f"deviations = {deviations}\n")


def scenario(tmp_path: Path, degraded: bool = False, extra: str = ""):
    from board_config.scenario import load_scenario

    dev = "{ k3 = -0.35, alpha_h = 0.35, beta_h = -0.35 }" if degraded else "{}"
    path = tmp_path / ("degraded-short.toml" if degraded else "maintenance-short.toml")
    path.write_text(scenario_text("FAULT" if degraded else "PASS", dev) + extra)
    return load_scenario(path)


def run_board(scen, link, duration: float | None = None, realtime: bool = False):
    from board_config.board import load_board_config
    from firmware_sim.board import Board
    from firmware_sim.runner import BoardRunner
    from firmware_sim.scheduler import Scheduler, VirtualClock, WallClock

    cfg = load_board_config(None, overrides=scen.board_overrides, overrides_source=scen.source)
    runner = BoardRunner(Board(cfg, nominal=scen.rig.params), link,
                         scheduler=Scheduler(cfg.tick_rate, WallClock() if realtime else VirtualClock()),
                         rearm_times=[e.at for e in scen.events_of("rearm")])
    link.open()
    try:
        return runner.run(scen.duration if duration is None else duration)
    finally:
        link.close()


def verdicts(result):
    mbits = [(e.data["label"], e.data["verdict"], e.data["max_count"], e.data["n_exceed"], e.data["max_eps"])
             for e in result.events if e.kind == "mbit_result"]
    final = [e.data["verdict"] for e in result.events if e.kind == "maintenance_verdict"]
    return mbits, final
