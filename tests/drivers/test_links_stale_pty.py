"""Stale pty links of a killed stub are cleaned at the next start (issue 12, point 7): a stub killed with SIGKILL
leaves its ``shm-hil-*`` directory and a symlink to a pty number the kernel will hand to someone else."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from hil_stub.pty_port import OWNER_FILE, PtyPort, clean_stale_links

pytestmark = pytest.mark.integration


def test_a_killed_stubs_pty_link_is_removed_and_a_live_ones_kept(tmp_path: Path):
    env = dict(os.environ, TMPDIR=str(tmp_path))
    code = ("import sys, time; from hil_stub.pty_port import PtyPort; p = PtyPort(); print(p.open(), flush=True); "
            "time.sleep(60)")
    child = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True, env=env,
                             cwd=Path(__file__).resolve().parents[2])
    try:
        link = Path(child.stdout.readline().strip())  # type: ignore[union-attr]
        assert link.is_symlink() and (link.parent / OWNER_FILE).read_text().strip() == str(child.pid)
        assert clean_stale_links(tmp_path) == []  # its stub is alive: left alone
    finally:
        child.send_signal(signal.SIGKILL)
        child.wait(timeout=10)
    assert link.is_symlink(), "SIGKILL leaves the link behind"
    live = PtyPort(tmp_path / "shm-hil-live" / "serial")  # another stub, alive (this process)
    live.open()
    (live.link.parent / OWNER_FILE).write_text(f"{os.getpid()}\n")
    old = tmp_path / "shm-hil-old"  # a stub from before pid files: nothing but a dangling link
    old.mkdir()
    (old / "serial").symlink_to(tmp_path / "no-such-pty")
    foreign = tmp_path / "shm-hil-foreign"  # not ours to judge: a regular file inside
    foreign.mkdir()
    (foreign / "notes.txt").write_text("keep")
    try:
        removed = clean_stale_links(tmp_path)
        assert sorted(removed) == sorted([link.parent, old])
        assert not link.parent.exists() and not old.exists()
        assert live.link.is_symlink() and (foreign / "notes.txt").exists()
    finally:
        live.close()


def test_the_first_pty_of_a_process_cleans_up(tmp_path: Path):
    stale = tmp_path / "shm-hil-dead"
    stale.mkdir()
    (stale / "serial").symlink_to("/dev/pts/999999")
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait(timeout=10)
    time.sleep(0.05)
    (stale / OWNER_FILE).write_text(f"{dead.pid}\n")
    env = dict(os.environ, TMPDIR=str(tmp_path))
    code = "from hil_stub.pty_port import PtyPort; p = PtyPort(); p.open(); p.close()"
    subprocess.run([sys.executable, "-c", code], env=env, check=True, timeout=60,
                   cwd=Path(__file__).resolve().parents[2])
    assert not stale.exists()
