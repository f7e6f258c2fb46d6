"""``shm calibrate --save FILE`` never replaces an existing file without ``--force``, as ``shm fit --save`` does
(issue 30): refused before the calibration runs (exit 2, one ``error:`` line naming the file and ``--force``),
the file and the ``--out`` folder untouched; with ``--force`` the file is replaced by the calibrated set."""

from __future__ import annotations

from pathlib import Path

import pytest
from bad_inputs_support import one_error_line, run_shm

from board_config import load_parameter_set

#: a quick calibration (one free parameter)
QUICK = ["calibrate", "--params", "table2", "--free", "k3"]
MINE = "# my own parameter set, kept by hand\n"


def test_an_existing_save_file_is_refused_without_force(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    save = tmp_path / "mine.toml"
    save.write_text(MINE)
    out = tmp_path / "out"
    code = run_shm([*QUICK, "--save", str(save), "--out", str(out)])
    err = capsys.readouterr().err
    line = one_error_line(err)
    assert code == 2, err[-800:]
    assert "Traceback" not in err
    assert str(save) in line and "--force" in line, line
    assert save.read_text() == MINE
    assert not out.exists()  # refused before anything ran or was written


@pytest.mark.slow  # a calibration: seconds
def test_force_replaces_the_save_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    save = tmp_path / "mine.toml"
    save.write_text(MINE)
    code = run_shm([*QUICK, "--save", str(save), "--out", str(tmp_path / "out"), "--force", "--json"])
    capsys.readouterr()
    assert code == 0
    assert load_parameter_set(save).name == "calibrated"
