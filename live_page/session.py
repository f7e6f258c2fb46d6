"""What ``shm run --live`` and ``shm hil serve --live`` call: parse the address, start the server, say how to reach
it, attach the board (or the rig), keep the final state after the run.

Safe by default: the page binds 127.0.0.1 unless a host is given; it is read-only (no route changes anything); on
another interface it prints a warning, since anyone who can reach that address and port sees the board's state.
From another machine the page is reached through an SSH tunnel (``ssh -L PORT:127.0.0.1:PORT HOST``).

After the run the page keeps its final state and links the report. The process goes on serving until Ctrl-C
(SIGINT or SIGTERM), or for ``--live-linger SECONDS`` (0: exit at once); the exit code is the run's. A run
stopped by a signal does not linger.
"""

from __future__ import annotations

import argparse
import ipaddress
import signal
import sys
import threading
from pathlib import Path
from typing import Any, TextIO

from live_page.snapshot import Snapshot, SnapshotSlot

DEFAULT_HOST = "127.0.0.1"


def live_address(text: str) -> tuple[str, int]:
    """argparse ``type=`` of ``[HOST:]PORT`` (``[::1]:PORT`` for IPv6; port 0: any free port)."""
    host, sep, port = text.strip().rpartition(":")
    host = host.strip("[]") if sep else DEFAULT_HOST
    if not port.isdigit() or not 0 <= int(port) <= 65535:
        raise argparse.ArgumentTypeError(f"'{text}': expected [HOST:]PORT with PORT a number in 0 .. 65535 "
                                         "(0: any free port)")
    if sep and not host:
        raise argparse.ArgumentTypeError(f"'{text}': no host before ':{port}' (leave out the host for 127.0.0.1)")
    return host, int(port)


def is_loopback(host: str) -> bool:
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


class LiveSession:
    """The live page of one command: a slot, its server, and the feed attached later."""

    def __init__(self, address: tuple[str, int], *, report: Path | None = None, linger_s: float | None = None,
                 stream: TextIO | None = None) -> None:
        from live_page.server import LiveServer

        self.slot = SnapshotSlot(Snapshot(status="starting", source=""))  # until a board or rig is attached
        self._report = report
        self.linger_s = linger_s
        self._stream = stream if stream is not None else sys.stderr
        self.server = LiveServer(self.slot, address[0], address[1], report=self._report_file)
        self.feed: Any = None

    def _report_file(self) -> Path | None:
        return self._report if self._report is not None and self._report.is_file() else None

    def say(self, text: str) -> None:
        print(text, file=self._stream, flush=True)

    def start(self) -> None:
        """Bind and serve (``OSError`` if the address cannot be bound); print the URL and how to reach it."""
        self.server.start()
        host, port = self.server.host, self.server.port
        self.say(f"live page: {self.server.url} (read-only; updates up to 20 per second)")
        if is_loopback(host):
            self.say(f"  from another machine: ssh -L {port}:127.0.0.1:{port} THIS_HOST, then open "
                     f"http://127.0.0.1:{port}/ there")
        else:
            self.say(f"  WARNING: serving on {host}, not on loopback: anyone who can reach this address and port "
                     "sees the board's state (read-only, unencrypted, no login); the safe way is the default "
                     f"127.0.0.1 and ssh -L {port}:127.0.0.1:{port} THIS_HOST")

    # --- the board (shm run) ------------------------------------------------------------------------------
    def attach_board(self, board: Any, link: Any, scheduler: Any, *, title: str, planned_s: float,
                     paced: bool) -> tuple[Any, Any]:
        """Publish ``board``'s state from now on: returns the (timed) link and the (publishing) scheduler to run
        with."""
        from live_page.board_feed import BoardFeed, PublishingScheduler, TimedLink

        timed = TimedLink(link)
        self.feed = BoardFeed(self.slot, board, title=title, planned_s=planned_s, paced=paced, link=timed)
        return timed, PublishingScheduler(scheduler, self.feed)

    # --- the rig (shm hil serve) ----------------------------------------------------------------------------
    def attach_rig(self, service: Any, *, title: str) -> None:
        """Publish the state of ``service`` (a :class:`hil_stub.service.HilService`) 20 times a second from a
        thread of its own."""
        from live_page.rig_feed import RigFeed

        self.feed = RigFeed(self.slot, service, title=title)
        self.feed.start()

    def on_event(self, ev: Any) -> None:
        if self.feed is not None:
            self.feed.on_event(ev)

    def finish(self, status: str) -> None:
        """The run has ended (``status``: finished, interrupted, failed): publish its last state, with the report
        link when the report exists."""
        if self.feed is not None and not self.slot.latest().finished:
            self.feed.finish(status, "/report" if self._report_file() is not None else None)
            self.feed = None

    # --- the end ------------------------------------------------------------------------------------------
    def linger(self, exit_code: int, interrupted: bool = False) -> int:
        """Serve the final state until Ctrl-C / SIGTERM or ``linger_s``; stop the server; return ``exit_code``."""
        self.finish("interrupted" if interrupted else "failed")  # a run that ended without saying how
        sys.stdout.flush()  # --json: the run's document reaches its reader now, not when the page stops
        if not interrupted and (self.linger_s is None or self.linger_s > 0):
            how = "until Ctrl-C" if self.linger_s is None else f"for {self.linger_s:g} s (or until Ctrl-C)"
            self.say(f"live page: the run has ended; {self.server.url} keeps its final state {how}")
            wait_for_signal(self.linger_s)
        self.server.stop()
        return exit_code


def wait_for_signal(seconds: float | None) -> None:
    """Wait ``seconds`` (None: for ever) or until SIGINT / SIGTERM (main thread only), whichever comes first."""
    done = threading.Event()
    old: dict[signal.Signals, Any] = {}
    if threading.current_thread() is threading.main_thread():
        for sig in (signal.SIGINT, signal.SIGTERM):
            old[sig] = signal.signal(sig, lambda *_: done.set())
    try:
        done.wait(seconds)
    finally:
        for sig_, handler in old.items():
            signal.signal(sig_, handler)
