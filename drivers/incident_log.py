"""Incident logging for links that fail every tick: the first few of a kind are logged, then only the 10th, 100th,
1000th ... (with the count), so a link that stays down for minutes does not flood the log. Counts are kept by the
caller (``link.stats``); this only decides what reaches the logger."""

from __future__ import annotations

import logging
from collections import Counter


class IncidentLog:
    """``warn(kind, msg, *args)``: log occurrence n of ``kind`` when n <= ``first`` or n is a power of ten."""

    def __init__(self, logger: logging.Logger, first: int = 3) -> None:
        self.logger = logger
        self.first = first
        self.seen: Counter[str] = Counter()

    def warn(self, kind: str, msg: str, *args: object) -> None:
        self.seen[kind] += 1
        n = self.seen[kind]
        if n <= self.first or _power_of_ten(n):
            suffix = f" [{kind} #{n}]" if n > 1 else ""
            self.logger.warning(msg + suffix, *args)


def _power_of_ten(n: int) -> bool:
    while n >= 10 and n % 10 == 0:
        n //= 10
    return n == 1


class SilentLog(IncidentLog):
    """An :class:`IncidentLog` that logs nothing (a link's start-up checks: their failure is raised as one error)."""

    def __init__(self) -> None:
        super().__init__(logging.getLogger("drivers.silent"))

    def warn(self, kind: str, msg: str, *args: object) -> None:
        self.seen[kind] += 1
