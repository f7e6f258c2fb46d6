"""Run a command in a subprocess and time its output lines as they arrive: the no-silence harness (issue 27.1)
of tests/shm_cli/test_no_silence.py and the cold-start benchmark (bench/bench_coldstart.py).

:func:`run_timed` starts the command with stdout and stderr on one pipe (what a user watching the terminal, or a
log, sees), reads it as it comes and stamps every line (``\\n`` or ``\\r``: a progress bar's redraws count) with the
seconds since the start. :func:`unexplained_silences` lists every stretch longer than ``limit_s`` with nothing new
on the screen, except after a line that announces work under way: one ending in "…" (a compile announcement, a
stage of a progress report). The start is never explained: the first line must come within ``limit_s``.

:func:`cold_env` points numba's cache (and the generated kernel modules) at an empty directory, so the command meets
a fresh clone's cold start.
"""

from __future__ import annotations

import fcntl
import itertools
import os
import pty
import selectors
import signal
import struct
import subprocess
import termios
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

#: longest stretch (s) a command may show nothing new, unless it announced the work first
LIMIT_S = 2.0
#: how a line announcing work under way ends
WORK_MARK = "…"


@dataclass
class TimedRun:
    """The lines a command printed, each with its arrival time (s after the start), its exit code (None when it was
    stopped by :func:`run_timed`) and its wall time (s)."""

    lines: list[tuple[float, str]] = field(default_factory=list)
    returncode: int | None = None
    wall_s: float = 0.0
    stopped: bool = False
    timed_out: bool = False
    #: when the harness stopped watching (s): the exit, the line ``stop_when`` matched, or the timeout
    until_s: float = 0.0

    def text(self) -> str:
        return "\n".join(f"{t:7.2f}  {line}" for t, line in self.lines)


def cold_env(cache_dir: Path, **extra: str) -> dict[str, str]:
    """The environment of a cold start: numba's cache and the kernel modules in the empty ``cache_dir``."""
    env = dict(os.environ)
    env.pop("MFC_SHM_KERNEL_DIR", None)
    env.update(NUMBA_CACHE_DIR=str(cache_dir), MPLBACKEND="Agg", PYTHONHASHSEED="0", PYTHONUNBUFFERED="1",
               COLUMNS="120")
    env.update(extra)
    return env


def run_timed(argv: Sequence[str], env: dict[str, str], timeout_s: float, *, cwd: Path | None = None,
              stop_when: Callable[[str], bool] | None = None, tty: bool = False) -> TimedRun:
    """Run ``argv`` and stamp each output line on arrival; stop it (SIGINT, then SIGKILL) when ``stop_when(line)``
    holds for a line or after ``timeout_s``. ``tty``: its stdout and stderr are a terminal (a pty of 120 x 40), as
    for a user at a shell, instead of a pipe (a log)."""
    run = TimedRun()
    t0 = time.monotonic()
    if tty:
        master, slave = pty.openpty()
        fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 40, 120, 0, 0))
        proc = subprocess.Popen(list(argv), stdout=slave, stderr=slave, stdin=subprocess.DEVNULL, env=env, cwd=cwd,
                                start_new_session=True)
        os.close(slave)
        fd = master
    else:
        proc = subprocess.Popen(list(argv), stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                stdin=subprocess.DEVNULL, env=env, cwd=cwd, start_new_session=True)
        assert proc.stdout is not None
        fd = proc.stdout.fileno()
    sel = selectors.DefaultSelector()
    sel.register(fd, selectors.EVENT_READ)
    pending = b""
    try:
        while True:
            left = timeout_s - (time.monotonic() - t0)
            if left <= 0:
                run.stopped = run.timed_out = True
                break
            if not sel.select(timeout=min(left, 0.05)):
                if proc.poll() is not None:
                    break
                continue
            try:
                chunk = os.read(fd, 65536)
            except OSError:  # a pty whose last writer closed
                chunk = b""
            now = time.monotonic() - t0
            if not chunk:
                break
            pending += chunk
            *complete, pending = pending.replace(b"\r", b"\n").split(b"\n")
            for raw in complete:
                line = raw.decode("utf-8", "replace").strip()
                if line:
                    run.lines.append((now, line))
                    if stop_when is not None and stop_when(line):
                        run.stopped = True
            if run.stopped:
                break
    finally:
        run.until_s = time.monotonic() - t0
        sel.close()
        if tty:
            os.close(fd)
        if pending.strip():
            run.lines.append((time.monotonic() - t0, pending.decode("utf-8", "replace").strip()))
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGINT)
            try:
                proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()
        run.wall_s = time.monotonic() - t0
        run.returncode = None if run.stopped else proc.returncode
    return run


def unexplained_silences(run: TimedRun, limit_s: float = LIMIT_S) -> list[str]:
    """Every stretch over ``limit_s`` between the start and the last line, or between two lines, that no
    announcement of work explains, in words; empty when the command never went silent unannounced. The tail from
    the last line to the process's exit (the interpreter's teardown: see :func:`exit_tail_s`) is not a silence
    between lines, unless the harness had to stop a command that was still silent at its timeout."""
    events = [(0.0, "<start>"), *run.lines]
    if run.timed_out:
        events.append((run.until_s, "<timeout>"))
    out = []
    for (ta, a), (tb, _b) in itertools.pairwise(events):
        if tb - ta > limit_s and not (a != "<start>" and a.endswith(WORK_MARK)):
            out.append(f"silent {tb - ta:.1f} s (from {ta:.1f} s) after {a!r}")
    return out


def exit_tail_s(run: TimedRun) -> float:
    """Seconds from the last line to the end (the exit): the interpreter's teardown after a command has said all."""
    return run.until_s - (run.lines[-1][0] if run.lines else 0.0)
