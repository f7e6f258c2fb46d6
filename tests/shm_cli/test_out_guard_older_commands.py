"""The older commands that write an ``--out`` folder (``shm harvest``, ``shm calibrate``, ``shm model frf|step|loop``)
guard it as the workbench commands do (issue 30): a folder holding another command's finished run is refused
without ``--force``, and a folder another running command holds (its ``--out`` lock) is refused always. Either way:
exit 2, one ``error:`` line naming the folder and why, and no file in it changed."""

from __future__ import annotations

import fcntl
import json
import os
from collections.abc import Iterator
from pathlib import Path

import pytest
from bad_inputs_support import file_hashes, one_error_line, run_shm

#: each command with quick settings (were the guard missing, the command would run and write, and the test fail)
COMMANDS: dict[str, list[str]] = {
    "harvest": ["harvest", "--duration-s", "1", "--no-projection"],
    "calibrate": ["calibrate", "--free", "k3"],
    "model-frf": ["model", "frf", "--points", "20"],
    "model-step": ["model", "step", "--duration-s", "0.2"],
    "model-loop": ["model", "loop", "--freq-hz", "1", "--cycles", "0.25"],
}


def _finished_run(d: Path) -> Path:
    """A folder holding a finished ``shm compare`` run (its marker and report)."""
    d.mkdir()
    (d / "compare.json").write_text('{"records": ["a finished comparison"]}\n')
    (d / "report.html").write_text("<html>the earlier, finished report</html>\n")
    return d


@pytest.fixture
def busy(tmp_path: Path) -> Iterator[Path]:
    """A folder whose ``--out`` lock another running command holds."""
    d = tmp_path / "busy"
    d.mkdir()
    (d / "fit.json").write_text("{}\n")
    fd = os.open(d / ".shm-run.lock", os.O_RDWR | os.O_CREAT, 0o644)
    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    os.pwrite(fd, json.dumps({"pid": 1, "command": "shm fit rec.csv --out busy"}).encode() + b"\n", 0)
    yield d
    os.close(fd)


def _refused(argv: list[str], folder: Path, capsys: pytest.CaptureFixture[str]) -> str:
    """Run ``shm argv``: exit 2, no traceback, one error line naming ``folder`` (returned), its files unchanged."""
    before = file_hashes(folder)
    code = run_shm(argv)
    err = capsys.readouterr().err
    line = one_error_line(err)
    assert code == 2, err[-800:]
    assert "Traceback" not in err
    assert str(folder) in line, line
    assert file_hashes(folder) == before
    return line


@pytest.mark.parametrize("command", COMMANDS)
def test_a_foreign_finished_run_is_refused_without_force(command: str, tmp_path: Path, capsys) -> None:
    out = _finished_run(tmp_path / "done")
    line = _refused([*COMMANDS[command], "--out", str(out)], out, capsys)
    assert "finished shm compare run" in line and "--force" in line, line
    assert sorted(p.name for p in out.iterdir()) == ["compare.json", "report.html"]


@pytest.mark.parametrize("command", COMMANDS)
def test_a_folder_in_use_by_another_command_is_refused(command: str, busy: Path, capsys) -> None:
    line = _refused([*COMMANDS[command], "--out", str(busy), "--force"], busy, capsys)  # --force takes no held folder
    assert "in use" in line and "shm fit" in line, line


def test_force_writes_into_a_foreign_run_and_the_lock_is_released(tmp_path: Path, capsys) -> None:
    out = _finished_run(tmp_path / "done")
    assert run_shm([*COMMANDS["model-frf"], "--out", str(out), "--force"]) == 0
    assert (out / "frf_z3_per_va.csv").is_file() and (out / "compare.json").is_file()
    assert (out / ".shm-run.lock").read_text() == ""  # released: a next command on the folder may start
    assert run_shm([*COMMANDS["model-frf"], "--out", str(out), "--force"]) == 0
    capsys.readouterr()
