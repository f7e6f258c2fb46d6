"""What ``shm run`` writes once the board stopped, each step named so that no failure loses an earlier one.

By the time these steps run, ``usage.db`` and the visit records are written (the board's run commits them as it
goes). Then: the summary, the timeline, the traces, ``summary.json``, the figures and ``report.html``. A step that
fails is recorded in ``deco.failed`` (step -> ``"Type: message"``; the command exits 1) and the steps after it still
run; ``summary.json`` is always written, with what the summary could hold and the failed steps (issue 29, point 1).
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from studies.board_run.summary import build_summary, closing_line, write_traces

if TYPE_CHECKING:
    from board_config.board import BoardConfig
    from board_config.scenario import Scenario
    from firmware_sim.board import Board
    from firmware_sim.runner import RunResult


@dataclass
class RunContext:
    """What a finished board run hands to its outputs (as :func:`build_summary` takes it)."""

    link_url: str
    scenario: Scenario
    seed: int
    params: str
    cfg: BoardConfig
    board: Board
    result: RunResult
    #: the in-process simulated rig (its describe() and truth() go into summary.json); None on a real link
    rig: Any
    setup_s: float
    paced: bool
    db_path: Path
    run_id: int | None


# ``summary``: summary.json itself (the JSON document at the edge): written once before the figures and again after,
# with whatever steps succeeded, so it stays a document rather than a result object (issue 29 pt 1)
def _minimal_summary(ctx: RunContext) -> dict[str, Any]:
    """The summary's identity and size when the full summary could not be built."""
    return {"scenario": ctx.scenario.name, "seed": ctx.seed, "params": ctx.params, "link": ctx.link_url,
            "run_id": ctx.run_id, "database": str(ctx.db_path), "ticks": ctx.result.ticks,
            "board_time_s": ctx.result.duration_s, "expected_verdict": None, "verdict_as_expected": None}


def link_stats(link: Any, lost_exchanges: int | None = None) -> dict[str, Any]:
    """What the link counted (its incident counters) and ``lost_exchanges``: the board ticks that got no sample (a
    lost or late reply, the link down), as the board's runner counted them."""
    stats = dict(getattr(link, "stats", {}) or {})
    if hasattr(link, "failures"):
        stats.update(exchanges=int(getattr(link, "exchanges", 0)), failures=int(link.failures))
    if lost_exchanges is not None:
        stats["lost_exchanges"] = int(lost_exchanges)
    return {k: (int(v) if isinstance(v, int | float) and float(v).is_integer() else v) for k, v in stats.items()}


def write_run_outputs(ctx: RunContext, status: str, interrupted_by: str | None, printer: Any, out: Path, link: Any,
                      deco: Any, dump_json: Callable[[Any], str], lost_exchanges: int | None = None
                      ) -> dict[str, Any]:
    """Write the run's outputs into ``out`` (see the module docstring) and return the summary.

    ``printer`` keeps the timeline lines (``add_line``, ``lines``); ``deco.attempt(step, fn)`` runs a step and
    records its failure (:class:`shm_cli.common.Decorations`)."""
    result = ctx.result
    summary = deco.attempt("the run summary", lambda: build_summary(
        ctx.link_url, ctx.scenario, ctx.seed, ctx.params, ctx.cfg, ctx.board, result, ctx.rig, ctx.setup_s,
        ctx.paced, ctx.db_path, ctx.run_id)) or _minimal_summary(ctx)
    summary["status"] = status
    summary["link_stats"] = link_stats(link, lost_exchanges)
    if interrupted_by is not None:
        summary["interrupted_by"] = interrupted_by
        printer.add_line(f"{result.duration_s:9.2f} s    interrupted by {interrupted_by}: the board closed, the log "
                         "and this report cover the part that ran")
    complete = "maintenance_verdicts" in summary
    if complete:
        printer.add_line(closing_line(summary))
    deco.attempt("timeline.txt", lambda: (out / "timeline.txt").write_text("\n".join(printer.lines) + "\n"))
    deco.attempt("trace.npz and trace.csv", lambda: write_traces(out, result.trace))
    # the numbers first (usage.db is written; summary.json, traces), then the figures and report.html: a plotting
    # failure never loses them, and summary.json says which figures exist
    summary["figures"] = []
    _write_summary(out, summary, deco, dump_json)
    if complete:
        from studies.board_run.report import write_plots_and_report

        summary["figures"] = deco.attempt("the figures and report.html",
                                          lambda: write_plots_and_report(out, summary, result, printer.lines)) or []
    if deco.failed:
        summary["failed"] = dict(deco.failed)
    _write_summary(out, summary, deco, dump_json)
    return summary


def _write_summary(out: Path, summary: dict[str, Any], deco: Any, dump_json: Callable[[Any], str]) -> None:
    try:
        text = dump_json(summary)
    except (TypeError, ValueError) as exc:  # a value JSON cannot hold: written as text, and said
        deco.failed.setdefault("summary.json", f"{type(exc).__name__}: {exc}")
        text = json.dumps(summary, default=str, indent=1)
    (out / "summary.json").write_text(text)
