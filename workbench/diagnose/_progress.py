"""How a diagnosis reports its progress: the stages it goes through and the units of work in each.

:func:`workbench.diagnose.diagnose` is pure logic (no I/O, no clock of its own for output); it calls a
:class:`DiagnoseProgress` at stage boundaries and after each unit of work, and the caller decides what to show (the
CLI: a progress bar on a terminal, one line per stage in a log — :mod:`shm_cli.progress`).
"""

from __future__ import annotations

from typing import Protocol

#: the stages of a diagnosis, in the order they run (names as shown to the user)
STAGES = ("nominal model", "screening effects", "screening parameters", "fitting candidates", "combinations",
          "residual tests", "verdict")


class DiagnoseProgress(Protocol):
    """Receives a diagnosis's progress. ``stage`` starts a stage (one of :data:`STAGES`) with ``total`` units of
    work (None: not counted) and a short ``detail``; ``advance`` says one unit of the current stage is done."""

    def stage(self, name: str, total: int | None = None, detail: str = "") -> None: ...

    def advance(self, label: str = "") -> None: ...


class SilentProgress:
    """A :class:`DiagnoseProgress` that shows nothing (the default: library calls and tests)."""

    def stage(self, name: str, total: int | None = None, detail: str = "") -> None:
        return None

    def advance(self, label: str = "") -> None:
        return None
