"""No orphans (issue 12, point 7): the campaign's pool workers die with the campaign process, SIGKILL included.

A real subprocess builds the campaign's process pool (:func:`studies.campaign.runner._process_executor`, the
one ``shm campaign`` uses), makes every worker busy with a task that never ends, and is killed with SIGKILL; the
workers must be gone within seconds (before the fix they lived for ever)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

TASK = '''
import os, time

def busy_forever(pid_dir):
    open(os.path.join(pid_dir, str(os.getpid())), "w").close()
    while True:
        time.sleep(0.05)
'''

DRIVER = '''
import sys, threading, time
sys.path.insert(0, sys.argv[1])
from studies.campaign.runner import _process_executor
import orphan_task
method = sys.argv[3]
if method == "forkserver":  # a live thread makes the pool use forkserver
    threading.Thread(target=time.sleep, args=(3600,), daemon=True).start()
ex, used = _process_executor(2)
print(used, flush=True)
futs = [ex.submit(orphan_task.busy_forever, sys.argv[2]) for _ in range(2)]
time.sleep(3600)
'''


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_bytes().rsplit(b")", 1)[1].split()[0]
    except (FileNotFoundError, IndexError):
        return False
    return state not in (b"Z", b"X")


def _wait_for(cond, limit_s: float) -> bool:
    end = time.monotonic() + limit_s
    while time.monotonic() < end:
        if cond():
            return True
        time.sleep(0.1)
    return cond()


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="uses /proc to watch the workers")
@pytest.mark.parametrize("method", ["fork", "forkserver"])
def test_pool_workers_die_with_a_sigkilled_campaign(tmp_path: Path, method: str) -> None:
    (tmp_path / "orphan_task.py").write_text(textwrap.dedent(TASK))
    pids = tmp_path / "pids"
    pids.mkdir()
    repo = Path(__file__).resolve().parents[2]
    env = dict(os.environ, PYTHONPATH=str(repo) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    proc = subprocess.Popen([sys.executable, "-c", DRIVER, str(tmp_path), str(pids), method], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert _wait_for(lambda: len(list(pids.iterdir())) == 2, 60), proc.stderr.read() if proc.poll() else ""
        workers = [int(p.name) for p in pids.iterdir()]
        assert all(_alive(w) for w in workers)
        assert proc.stdout.readline().strip() == method
        proc.send_signal(signal.SIGKILL)
        proc.wait(10)
        # generous bound for a loaded 2-core machine; the guards act within about half a second
        assert _wait_for(lambda: not any(_alive(w) for w in workers), 15), \
            f"workers {[w for w in workers if _alive(w)]} outlived the killed campaign"
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(10)
        for p in pids.iterdir():  # never leave a busy worker behind, even when the test fails
            try:
                os.kill(int(p.name), signal.SIGKILL)
            except (ProcessLookupError, ValueError):
                pass
