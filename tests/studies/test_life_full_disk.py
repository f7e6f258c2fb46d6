"""A life run onto a really full disk (issue 33): a 160 kB tmpfs (mounted when the tests run as root, else skipped).

sqlite says "database or disk is full" while the life's log is written: one line naming the folder and the disk,
exit 1, and the earlier life in --out left as it was (the new one was built beside it and never moved in).
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from bad_inputs_newer_life_health import LIFE

ROOT = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.slow


@pytest.fixture
def tiny_disk(tmp_path: Path):
    mnt = tmp_path / "tiny"
    mnt.mkdir()
    if os.geteuid() != 0 or subprocess.run(["mount", "-t", "tmpfs", "-o", "size=160k", "tmpfs", str(mnt)],
                                           capture_output=True).returncode != 0:
        pytest.skip("mounting a tiny tmpfs needs root")
    try:
        yield mnt
    finally:
        subprocess.run(["umount", str(mnt)], check=False)


def test_a_full_disk_during_a_life_is_one_line_and_keeps_the_earlier_life(tiny_disk: Path, tmp_path: Path) -> None:
    toml = tmp_path / "life.toml"
    toml.write_text(LIFE)
    out = tiny_disk / "life"
    out.mkdir()
    (out / "summary.json").write_text('{"earlier": true}')
    env = dict(os.environ, PYTHONPATH=str(ROOT), MPLBACKEND="Agg")
    r = subprocess.run([sys.executable, "-m", "shm_cli.main", "run", "--scenario", str(toml), "--quiet", "--force",
                        "--out", str(out)], capture_output=True, text=True, env=env, timeout=300)
    assert r.returncode == 1, r.stderr
    errors = [ln for ln in r.stderr.splitlines() if "error:" in ln]
    assert len(errors) == 1 and "Traceback" not in r.stderr, r.stderr
    assert "disk is full" in errors[0] and str(out) in errors[0] and "MB free" in errors[0]
    assert (out / "summary.json").read_text() == '{"earlier": true}'
    assert sorted(p.name for p in out.iterdir()) == [".shm-run.lock", "summary.json"]
