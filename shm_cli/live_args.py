"""The ``--live [HOST:]PORT`` and ``--live-linger SECONDS`` options of ``shm run`` and ``shm hil serve``
(docs/live.md), and the session they start."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from shm_cli.common import nonnegative_float


def add_live_args(p: argparse.ArgumentParser, what: str) -> None:
    """The live-page options (``what``: whose state the page shows)."""
    from live_page.session import live_address

    g = p.add_argument_group("live page (docs/live.md)")
    g.add_argument("--live", type=live_address, default=None, metavar="[HOST:]PORT",
                   help=f"serve a read-only live page of {what} on HOST:PORT (default host 127.0.0.1; port 0: any "
                        "free port); prints the URL")
    g.add_argument("--live-linger", type=nonnegative_float, default=None, metavar="SECONDS",
                   help="after the run, keep serving the page's final state this long (default: until Ctrl-C; "
                        "0: exit at once)")


def start_live(args: argparse.Namespace, report: Path | None = None) -> Any:
    """The started :class:`live_page.session.LiveSession` of ``--live`` (None without it); an address that cannot
    be bound is bad input (exit 2)."""
    from shm_cli.main import CliError

    if getattr(args, "live", None) is None:
        if getattr(args, "live_linger", None) is not None:
            raise CliError("--live-linger needs --live [HOST:]PORT")
        return None
    from live_page.session import LiveSession

    session = LiveSession(args.live, report=report, linger_s=args.live_linger)
    try:
        session.start()
    except OSError as exc:
        host, port = args.live
        raise CliError(f"--live {host}:{port}: cannot serve the live page there ({exc.strerror or exc})") from None
    return session


def refuse_live_for_a_life(args: argparse.Namespace, scenario: Any) -> None:
    """``--live`` follows one board run: a life (its visits run in parallel processes) is refused (exit 2)."""
    if getattr(args, "live", None) is not None:
        from shm_cli.main import CliError

        raise CliError(f"--live: scenario '{scenario.name}' is a life whose visits run in parallel processes; "
                       "the live page follows one board run (a maintenance or flight scenario)")


def attach_live_board(args: argparse.Namespace, board: Any, link: Any, scheduler: Any, scenario: str,
                      duration_s: float, paced: bool) -> tuple[Any, Any, Any]:
    """(the run's live session or None, the link and the scheduler to run with): with ``--live`` the link is timed
    and the scheduler publishes the board's state after each tick."""
    live = getattr(args, "live_session", None)
    if live is None:
        return None, link, scheduler
    link, scheduler = live.attach_board(board, link, scheduler, planned_s=duration_s, paced=paced, title=(
        f"scenario {scenario}, link {args.link}, {'real time' if paced else 'virtual time'}"))
    return live, link, scheduler
