"""What a board run leaves besides its log: the summary (``summary.json``), the timeline's closing line and the
per-tick traces."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from reporting.csv_columns import write_csv

if TYPE_CHECKING:
    from board_config.board import BoardConfig
    from board_config.scenario import Scenario
    from firmware_sim.board import Board
    from firmware_sim.runner import RunResult


def closing_line(s: dict[str, Any]) -> str:  # ``s``: summary.json as written (the JSON document at the edge)
    """The timeline's last line: ticks, time, final regime, verdict (against the expected one), incidents, the
    exchanges that got no sample (when any: ``link_stats.lost_exchanges``), battery."""
    v = s["maintenance_verdicts"]
    verdict = v[-1]["verdict"] if v else "no maintenance verdict"
    exp = s["expected_verdict"]
    as_expected = "as expected" if s["verdict_as_expected"] else "NOT AS EXPECTED: exit 1"
    check = "" if exp is None else f" (expected {exp}: {as_expected})"
    lost = s.get("link_stats", {}).get("lost_exchanges")
    link = f"; exchanges without a sample {lost}" if lost else ""
    return (f"end: {s['ticks']} ticks = {s['board_time_s']:.1f} s board time in {s['wall_s']:.2f} s wall "
            f"({s['realtime_factor']:.1f}x real time); final regime {s['final_regime']}; verdict {verdict}{check}; "
            f"incidents {s['incidents']}{link}; battery {s['battery_last_V']:.3f} V")


def build_summary(link: str, scenario: Scenario, seed: int, params: str, cfg: BoardConfig, board: Board,
                  result: RunResult, rig: Any, setup_s: float, paced: bool, db_path: Path,
                  run_id: int | None) -> dict[str, Any]:
    """The run's summary (``summary.json``): what ran, the board's events by kind, the verdicts against the
    scenario's expectation, time, charge and energy by regime, and the simulated rig's description."""
    ev = result.events
    verdicts = [dict(e.data, time_s=e.time) for e in ev if e.kind == "maintenance_verdict"]
    mbits = [dict(e.data, time_s=e.time) for e in ev if e.kind == "mbit_result"]
    changes = [dict(e.data, time_s=e.time) for e in ev if e.kind == "regime_change"]
    usage = [dict(e.data, time_s=e.time) for e in ev if e.kind == "usage_summary"]
    incidents = [dict(e.data, time_s=e.time) for e in ev if e.kind == "incident"]
    # the scenario's expected verdict is checked only when the run covered the whole scenario (not a shorter
    # --duration-s, not an interrupted run)
    whole = result.duration_s >= scenario.duration - 0.5 / cfg.tick_rate
    expected = scenario.expect_verdict if whole else None
    final_verdict = verdicts[-1]["verdict"] if verdicts else "NONE"
    time_in = board.ledger.time_by_regime()
    summary = {
        "scenario": scenario.name, "scenario_file": scenario.source, "seed": seed, "params": params,
        "link": link, "paced": paced, "run_id": run_id, "database": str(db_path),
        "ticks": result.ticks, "board_time_s": result.duration_s, "wall_s": result.wall_s, "setup_s": setup_s,
        "realtime_factor": result.realtime_factor, "tick_stats": result.stats.as_dict(),
        "final_regime": board.regime.value, "regime_changes": changes, "time_in_regime_s": time_in,
        "usage_summaries": usage, "mbit_results": mbits, "maintenance_verdicts": verdicts,
        "incidents_list": incidents, "incidents": len(incidents),
        "expected_verdict": expected,
        "verdict_as_expected": None if expected is None else (final_verdict == expected),
        "battery_first_V": board.ledger.v_first,
        "battery_last_V": board.ledger.v_last, "battery_min_V": board.ledger.v_min,
        "charge_used_C": board.ledger.charge_used, "energy_used_J": board.ledger.energy_used,
        "charge_by_regime_C": board.ledger.charge_by_regime(), "brownouts": board.power.brownouts,
        "board_config": cfg.as_dict(),
    }
    if rig is not None:
        summary["rig"] = rig.describe()
        summary["rig_truth_end"] = rig.truth()
    return summary


def write_traces(out: Path, trace) -> None:
    """``trace.npz`` (every tick) and ``trace.csv`` (~10 Hz) of a run's per-tick trace (nothing without one)."""
    if trace is None:
        return
    cols = trace.columns()
    np.savez_compressed(out / "trace.npz", **cols)
    every = max(1, round(10 / max(1, trace.every)))  # ~10 Hz for the CSV
    write_csv(out / "trace.csv", {k: v[::every] for k, v in cols.items()})
