"""What every hardware link does around its transport: statistics, rate-limited incident logging, reopening a lost
transport with a back-off, and reopening after too many timeouts in a row.

A lost transport (closed pty, reset socket, EIO) closes the link; it is reopened with a back-off counted in exchange
calls (1, 2, 4 … :data:`MAX_BACKOFF_CALLS`), so a dead port costs one cheap :class:`~drivers.link.LinkError` per tick
and never blocks the tick loop. ``reopen_after`` consecutive timeouts count as a lost transport (silence, not
slowness). Every incident is counted in :attr:`ReconnectingLink.stats` and logged through an
:class:`~drivers.incident_log.IncidentLog` (the first three of a kind, then every 10th, 100th …).

A link implements four transport hooks: :meth:`~ReconnectingLink._open_transport` (raise ``LinkError`` when it cannot),
:meth:`~ReconnectingLink._drop_transport` (after a loss), :attr:`~ReconnectingLink.is_open` and
:meth:`~ReconnectingLink._after_reconnect` (e.g. check the device behind the port again), and calls
:meth:`~ReconnectingLink._ensure_up` before each exchange, :meth:`~ReconnectingLink._link_down` on a lost transport and
:meth:`~ReconnectingLink._timed_out` on a missing reply.
"""

from __future__ import annotations

import logging
from abc import ABC, abstractmethod
from collections import Counter
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Self

from drivers.incident_log import IncidentLog, SilentLog
from drivers.link import LinkError

#: longest back-off between two reopen attempts, in exchange calls
MAX_BACKOFF_CALLS = 64


class ReconnectingLink(ABC):
    """Base of a link whose transport can be lost and reopened (see the module docstring).

    ``verb`` names the reopening in statistics and messages (``"reopen"``: ``reopen_failed``, ``reopened``,
    "reopening with back-off"); ``reconnected_note`` is the log line after a successful reopen.
    """

    verb = "reopen"
    reconnected_note = "reopened"

    def __init__(self, url: str, logger: logging.Logger, *, timeout: float, reopen_after: int) -> None:
        self.url = url
        self.timeout = timeout
        self.reopen_after = reopen_after
        self.stats: Counter[str] = Counter()
        self._log = IncidentLog(logger)
        self._backoff = 1
        self._calls_while_down = 0
        self._timeouts_in_row = 0

    # ------------------------------------------------------------------------------------------ transport hooks
    @property
    @abstractmethod
    def is_open(self) -> bool:
        """The transport is up."""

    @abstractmethod
    def _open_transport(self) -> None:
        """Open (or reconnect) the transport; ``LinkError`` when it cannot."""

    @abstractmethod
    def _drop_transport(self) -> None:
        """Close the transport after a loss (never raises)."""

    @abstractmethod
    def _after_reconnect(self) -> None:
        """Called after a successful reopen by :meth:`_ensure_up` (the device behind the port may have changed)."""

    @abstractmethod
    def open(self) -> None: ...

    @abstractmethod
    def close(self) -> None: ...

    # ------------------------------------------------------------------------------------------ lifecycle
    def __enter__(self) -> Self:
        self.open()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _bring_up(self) -> None:
        """Open the transport and start afresh: no back-off, no timeouts in a row."""
        self._open_transport()
        self._backoff = 1
        self._calls_while_down = 0
        self._timeouts_in_row = 0

    @contextmanager
    def _silenced(self) -> Iterator[None]:
        """Start-up checks: their failure is raised as one error, not logged as a warning per attempt."""
        log, self._log = self._log, SilentLog()
        try:
            yield
        finally:
            self._log = log

    # ------------------------------------------------------------------------------------------ incidents
    def _link_down(self, why: str) -> LinkError:
        """The transport is lost: count, log, drop it; the error to raise."""
        self.stats["link_down"] += 1
        self._log.warn("link_down", "%s: link down (%s); " + self.verb + "ing with back-off", self.url, why)
        self._drop_transport()
        self._calls_while_down = 0
        return LinkError(f"{self.url}: {why}")

    def _ensure_up(self) -> None:
        """Before an exchange: reopen a lost transport when its back-off has passed, else ``LinkError`` at once."""
        if self.is_open:
            return
        self._calls_while_down += 1
        if self._calls_while_down < self._backoff:
            self.stats["down_exchanges"] += 1
            raise LinkError(f"{self.url}: link down (next {self.verb} attempt in "
                            f"{self._backoff - self._calls_while_down} exchange(s))")
        self._calls_while_down = 0
        try:
            self._bring_up()
        except LinkError:
            self._backoff = min(2 * self._backoff, MAX_BACKOFF_CALLS)
            self.stats[f"{self.verb}_failed"] += 1
            raise
        self.stats[f"{self.verb}ed"] += 1
        self._log.warn(f"{self.verb}ed", "%s: " + self.reconnected_note, self.url)
        self._after_reconnect()

    def _timed_out(self, why: str, *, may_reopen: bool = True) -> LinkError:
        """No reply within the budget: count and log it; after ``reopen_after`` in a row (when ``may_reopen``) the
        transport counts as lost. Returns the error to raise."""
        self.stats["timeouts"] += 1
        self._timeouts_in_row += 1
        self._log.warn("timeout", "%s: %s", self.url, why)
        if may_reopen and self._timeouts_in_row >= self.reopen_after:
            return self._link_down(f"{self._timeouts_in_row} timeouts in a row")
        return LinkError(f"{self.url}: {why}")
