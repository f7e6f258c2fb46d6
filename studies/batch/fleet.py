"""A fleet of boards: one row per board from its ``shm health`` document, ranked by forecast first FAULT, and the
seeded scatter of degradation rates that ``shm run --scenario aging --boards N`` gives each board (pure)."""

from __future__ import annotations

import math
import re
from typing import Any

import numpy as np

#: spread of a board's degradation rates around the scenario's: a log-normal factor with this sigma
RATE_SCATTER_SIGMA = 0.25
_LAW_VALUE = re.compile(r"^(\s*(?:rate|amplitude)\s*=\s*\{\s*value\s*=\s*)([-+0-9.eE]+)(.*)$")


def board_rate_factor(seed: int, board: int) -> float:
    """The board's degradation-rate factor (log-normal, median 1), seeded by the fleet's seed and the board index:
    the same board gets the same factor whatever the scheduler and the number of boards."""
    rng = np.random.default_rng([seed, board])
    return float(np.exp(RATE_SCATTER_SIGMA * rng.standard_normal()))


def scaled_life(scenario_text: str, factor: float) -> str:
    """The scenario TOML with every ``[[life.law]]`` rate and amplitude multiplied by ``factor``."""
    lines, in_law = [], False
    for line in scenario_text.splitlines():
        stripped = line.strip()
        if stripped.startswith("["):
            in_law = stripped == "[[life.law]]"
        m = _LAW_VALUE.match(line) if in_law else None
        if m:
            line = f"{m.group(1)}{float(m.group(2)) * factor!r}{m.group(3)}"
        lines.append(line)
    return "\n".join(lines) + "\n"


def _where(doc: dict[str, Any]) -> str:
    loc = doc.get("location") or {}
    if loc.get("parameter") and loc.get("section"):
        return f"{loc['parameter']} (section {loc['section']})"
    where = str((doc.get("levels") or {}).get("where") or "")
    return where.split(";")[0][:80]


def fleet_row(board: str, doc: dict[str, Any], code: int, message: str) -> dict[str, Any]:
    """One board's row: forecast first FAULT (median and 90 % interval, h), remaining life (h), where, last verdict."""
    f = doc.get("forecast") or {}
    interval = f.get("trip_interval_90") or [None, None]
    visits = doc.get("visits") or []
    last = visits[-1] if visits else {}
    return {"board": board, "exit_code": code,
            "first_fault_h": f.get("trip_operating_hours"),
            "first_fault_90_lo_h": interval[0], "first_fault_90_hi_h": interval[1],
            "rul_h": f.get("rul_hours"), "first_fault_visit": f.get("trip_visit"),
            "already_faulty": f.get("already_faulty"), "where": _where(doc),
            "last_visit_h": last.get("operating_hours"), "last_verdict": last.get("board_verdict"),
            "message": "" if code == 0 else message}


def rank_fleet(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Boards already FAULT first, then by forecast first FAULT (earliest first), boards without one last; ties by
    board name (deterministic)."""
    def key(r: dict[str, Any]) -> tuple[int, float, str]:
        t = r.get("first_fault_h")
        t = math.inf if t is None or not math.isfinite(float(t)) else float(t)
        return (0 if r.get("already_faulty") or r.get("last_verdict") == "FAULT" else 1, t, str(r["board"]))
    ranked = sorted(rows, key=key)
    return [{"rank": i, **r} for i, r in enumerate(ranked, start=1)]
