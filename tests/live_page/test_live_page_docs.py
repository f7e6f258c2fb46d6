"""docs/live.md's commands, run (issue 32, point 6): every ``shm …`` line of its shell blocks runs (ports made free,
a short duration, no lingering) and prints what the page's text block shows; its ``ssh -L`` line is the one the
command prints for its port."""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
DOC = REPO / "docs" / "live.md"

pytestmark = [pytest.mark.slow, pytest.mark.integration]


def _blocks(kind: str) -> list[str]:
    return re.findall(rf"```{kind}\n(.*?)```", DOC.read_text(), flags=re.S)


def _shm_lines() -> list[str]:
    return [line.split("#", 1)[0].strip() for block in _blocks("sh") for line in block.splitlines()
            if line.startswith("shm ")]


def _shortened(line: str, out: Path) -> list[str]:
    """The doc's command with free ports, a few seconds long, no lingering."""
    argv = shlex.split(line)
    argv[argv.index("--live") + 1] = "0"
    if "--modbus-tcp" in argv:
        argv[argv.index("--modbus-tcp") + 1] = "127.0.0.1:0"
    if "--out" in argv:
        argv[argv.index("--out") + 1] = str(out)
    extra = ["--duration-s", "2", "--quiet"] if argv[1] == "run" else ["--duration", "2"]
    return [sys.executable, "-m", "shm_cli.main", *argv[1:], *extra, "--live-linger", "0"]


def test_the_readmes_live_commands_are_the_docs_ones() -> None:
    """README's ``--live`` examples are docs/live.md's, which the test below runs."""
    readme = (REPO / "README.md").read_text()
    lines = [line.split("#", 1)[0].strip() for block in re.findall(r"```sh\n(.*?)```", readme, flags=re.S)
             for line in block.splitlines() if "--live" in line.split("#", 1)[0]]
    assert lines and set(lines) <= set(_shm_lines()), lines


def test_the_docs_commands_run_and_print_what_the_docs_show(tmp_path: Path) -> None:
    lines = _shm_lines()
    assert [line.split()[:2] for line in lines] == [["shm", "run"], ["shm", "hil"]]
    printed_doc = _blocks("text")[0]
    ssh_doc = next(line for block in _blocks("sh") for line in block.splitlines() if line.startswith("ssh "))
    for line in lines:
        r = subprocess.run(_shortened(line, tmp_path / "out"), capture_output=True, text=True, timeout=180,
                           cwd=REPO, env=dict(os.environ))
        assert r.returncode == 0, r.stderr
        port = re.search(r"live page: http://127\.0\.0\.1:(\d+)/", r.stderr).group(1)
        doc_port = re.search(r"--live (\d+)", line).group(1)
        for expected in printed_doc.strip().splitlines():  # the doc's lines with this run's port
            assert expected.replace("8765", port) in r.stderr, (expected, r.stderr)
        ssh = ssh_doc.split("#", 1)[0].split()  # ssh -L P:127.0.0.1:P HOST
        assert ssh[:2] == ["ssh", "-L"] and ssh[2] == "8765:127.0.0.1:8765"
        assert f"ssh -L {port}:127.0.0.1:{port} " in r.stderr
        assert doc_port in ("8765", "8766")
