"""The lock of an output directory in use: one ``shm run`` per ``--out`` at a time.

``with OutputLock(out, command="shm run ...") as lock:`` takes an exclusive ``flock`` on ``<out>/.shm-run.lock``
and writes who holds it (pid, start time, command). A second run on the same directory gets
:class:`OutputInUseError` (an input error, exit 2) naming the running one. The kernel releases the lock when the
holder's process ends, however it ends (SIGKILL included), so a stale lock file never blocks anyone: only a live
holder does.
"""

from __future__ import annotations

import fcntl
import json
import os
import socket
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from board_config.errors import InputError

LOCK_NAME = ".shm-run.lock"


class OutputInUseError(InputError):
    """The output directory is in use by another running ``shm`` process (the message names it)."""


def _holder_text(info: dict[str, Any]) -> str:
    parts = []
    if info.get("pid"):
        parts.append(f"pid {info['pid']}")
    if info.get("host") and info.get("host") != socket.gethostname():
        parts.append(f"host {info['host']}")
    if info.get("started_utc"):
        parts.append(f"started {info['started_utc']}")
    if info.get("command"):
        parts.append(f"'{info['command']}'")
    return ", ".join(parts) or "holder unknown"


class OutputLock:
    """Exclusive, process-lifetime lock of an output directory (see the module docstring)."""

    def __init__(self, directory: str | Path, command: str = "shm run", option: str = "--out") -> None:
        self.directory = Path(directory)
        self.path = self.directory / LOCK_NAME
        self.command = command
        self.option = option
        self._fd: int | None = None

    def read_holder(self) -> dict[str, Any]:
        try:
            return json.loads(self.path.read_text(encoding="utf-8") or "{}")
        except (OSError, ValueError):
            return {}

    def acquire(self) -> OutputLock:
        fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            raise OutputInUseError(
                f"{self.option} {self.directory} is in use by another running {self.command.split(' -')[0]} "
                f"({_holder_text(self.read_holder())}); wait for it to end, stop it, or choose another "
                f"{self.option}") from None
        except OSError:
            os.close(fd)
            raise
        info = {"pid": os.getpid(), "host": socket.gethostname(),
                "started_utc": datetime.now(UTC).isoformat(timespec="seconds"), "command": self.command}
        os.ftruncate(fd, 0)
        os.pwrite(fd, (json.dumps(info) + "\n").encode(), 0)
        self._fd = fd
        return self

    def release(self) -> None:
        if self._fd is not None:
            try:
                os.ftruncate(self._fd, 0)
            except OSError:
                pass
            fcntl.flock(self._fd, fcntl.LOCK_UN)
            os.close(self._fd)
            self._fd = None

    def __enter__(self) -> OutputLock:
        return self.acquire()

    def __exit__(self, *exc: object) -> None:
        self.release()
