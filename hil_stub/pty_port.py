"""Pseudo-terminals for the HIL stub, without socat.

:class:`PtyPort` — one pty: the stub reads and writes the master side; the board opens the slave side by a
stable symlink (like ``/dev/serial/by-id/...``), so when the stub closes the pty ("the port vanishes") and
later opens a new one, the board's reconnect finds it again under the same name.

A server that insists on opening its port by URL (pymodbus' RTU server) serves the master through
:mod:`hil_stub.protocol_ptymaster` — no second pty and relay between it and the board.

A stub killed with SIGKILL cannot remove its links: each stub directory holds ``owner.pid``, and
:func:`clean_stale_links` (run when the first pty of a process is created) removes the directories of stubs that
are no longer running — their links would otherwise point at pty numbers the kernel hands to someone else.
"""

from __future__ import annotations

import contextlib
import errno
import os
import select
import tempfile
import tty
from pathlib import Path

PREFIX = "shm-hil-"
OWNER_FILE = "owner.pid"
_cleaned = False


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # someone else's live process
        return True
    return True


def clean_stale_links(tmpdir: str | Path | None = None) -> list[Path]:
    """Remove ``shm-hil-*`` directories left by stubs that are no longer running; returns what was removed.

    A directory is stale when its ``owner.pid`` names a dead process, or (older stubs, no pid file) when it holds
    nothing but symlinks whose pty is gone. Anything else is left alone."""
    base = Path(tmpdir) if tmpdir is not None else Path(tempfile.gettempdir())
    removed: list[Path] = []
    for d in base.glob(PREFIX + "*"):
        try:
            if not d.is_dir() or d.is_symlink():
                continue
            entries = list(d.iterdir())
            owner = d / OWNER_FILE
            if owner.exists():
                try:
                    pid = int(owner.read_text().strip() or "0")
                except ValueError:
                    continue
                if pid <= 0 or _alive(pid):
                    continue
            elif not all(e.is_symlink() and not e.exists() for e in entries):
                continue
            for e in entries:
                if e.is_symlink() or e.name == OWNER_FILE or e.name.endswith(".tmp"):
                    e.unlink()
            d.rmdir()
            removed.append(d)
        except OSError:  # raced with another process, or not ours to remove
            continue
    return removed


def _claim(directory: Path) -> None:
    """Mark ``directory`` as this process's (for :func:`clean_stale_links` in a later stub)."""
    with contextlib.suppress(OSError):
        (directory / OWNER_FILE).write_text(f"{os.getpid()}\n")


def _clean_once() -> None:
    global _cleaned
    if not _cleaned:
        _cleaned = True
        removed = clean_stale_links()
        if removed:
            import logging

            logging.getLogger("hil_stub.pty").warning(
                "removed %d stale pty link director%s of stubs no longer running: %s", len(removed),
                "y" if len(removed) == 1 else "ies", ", ".join(map(str, removed)))


def _make_link(target: str, link: Path) -> None:
    tmp = link.with_name(f".{link.name}.{os.getpid()}.tmp")
    with contextlib.suppress(FileNotFoundError):
        tmp.unlink()
    os.symlink(target, tmp)
    os.replace(tmp, link)  # atomic: the board never sees a missing link during a swap


class PtyPort:
    """One pty with a stable symlink to its slave side."""

    def __init__(self, link: str | Path | None = None, name: str = "serial") -> None:
        """``link``: the symlink's path; default ``name`` in a new ``shm-hil-*`` directory of the temp dir."""
        self._own_dir = link is None
        if link is None:
            _clean_once()
            link = Path(tempfile.mkdtemp(prefix=PREFIX)) / name
        self.link = Path(link)
        self.master: int | None = None
        self._slave: int | None = None
        self.slave_name = ""
        self.dropped_bytes = 0

    def open(self) -> str:
        """Create the pty (raw mode both sides) and point the symlink at it. Returns the symlink path."""
        self.link.parent.mkdir(parents=True, exist_ok=True)
        if self._own_dir:
            _claim(self.link.parent)
        master, slave = os.openpty()
        tty.setraw(master)
        tty.setraw(slave)
        os.set_blocking(master, False)
        self.master, self._slave = master, slave  # keeping the slave open: the board may come and go
        self.slave_name = os.ttyname(slave)
        _make_link(self.slave_name, self.link)
        return str(self.link)

    def close(self) -> None:
        """Close both sides and remove the symlink: the port vanishes (the board's reads fail with EIO)."""
        with contextlib.suppress(FileNotFoundError):
            self.link.unlink()
        if self._own_dir:
            with contextlib.suppress(OSError):
                (self.link.parent / OWNER_FILE).unlink()
                self.link.parent.rmdir()  # only if empty; open() recreates it
        for fd in (self.master, self._slave):
            if fd is not None:
                with contextlib.suppress(OSError):
                    os.close(fd)
        self.master = self._slave = None

    @property
    def is_open(self) -> bool:
        return self.master is not None

    def read(self, timeout: float) -> bytes:
        """Bytes from the board (b"" on timeout)."""
        if self.master is None:
            raise OSError(errno.EBADF, "pty closed")
        ready, _, _ = select.select([self.master], [], [], timeout)
        if not ready:
            return b""
        try:
            return os.read(self.master, 4096)
        except BlockingIOError:
            return b""

    def write(self, data: bytes) -> None:
        """Send to the board; if nobody reads and the pty buffer is full, the bytes are dropped (counted)."""
        if self.master is None:
            raise OSError(errno.EBADF, "pty closed")
        try:
            n = os.write(self.master, data)
        except BlockingIOError:
            n = 0
        self.dropped_bytes += len(data) - n
