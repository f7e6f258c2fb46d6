"""End-to-end: the ``shm`` command line for the plant model (real subprocesses for --help and exit codes)."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from shm_cli.main import main


def _shm(*args: str) -> subprocess.CompletedProcess:
    env = dict(os.environ)
    return subprocess.run([sys.executable, "-m", "shm_cli.main", *args], capture_output=True, text=True, env=env,
                          timeout=300)


def test_help_lists_commands():
    r = _shm("--help")
    assert r.returncode == 0 and "model" in r.stdout
    r = _shm("model", "--help")
    assert r.returncode == 0 and all(c in r.stdout for c in ("info", "frf", "step", "loop"))


def test_model_info_json_reports_modes():
    r = _shm("model", "info", "--params", "table2", "--json")
    assert r.returncode == 0, r.stderr
    info = json.loads(r.stdout)
    freqs = [m["frequency_Hz"] for m in info["modes"]]
    assert freqs == pytest.approx([17.07, 35.65, 102.19], rel=2e-3)
    assert info["rc_pole_closed_form_Hz"] == pytest.approx(10.01, rel=1e-3)
    assert info["static_tip_gain_m_per_V"] == pytest.approx(info["static_tip_gain_closed_form_m_per_V"], rel=1e-6)


def test_unknown_parameter_set_is_exit_2_with_message():
    r = _shm("model", "info", "--params", "nonexistent")
    assert r.returncode == 2
    assert "unknown parameter set" in r.stderr and "table2" in r.stderr


def test_frf_step_loop_write_plots_and_csv(tmp_path, capsys):
    assert main(["model", "frf", "--out", str(tmp_path / "frf"), "--points", "200"]) == 0
    assert main(["model", "step", "--out", str(tmp_path / "step"), "--duration-s", "0.5"]) == 0
    assert main(["model", "loop", "--out", str(tmp_path / "loop"), "--freq-hz", "0.5", "--cycles", "1"]) == 0
    for rel in ("frf/frf_z3_per_va.png", "frf/frf_z3_per_va.csv", "frf/frf_vstored_per_accel.png",
                "step/step.png", "step/step.csv", "loop/loop.png", "loop/loop.csv"):
        assert (tmp_path / rel).stat().st_size > 0, rel
    header = (tmp_path / "step" / "step.csv").read_text().splitlines()[0]
    assert header == "time_s,va_V,z3_m"


def test_bad_numbers_are_exit_2(tmp_path, capsys):
    assert main(["model", "frf", "--out", str(tmp_path), "--f-min-hz", "-1"]) == 2
    assert "--f-min-hz" in capsys.readouterr().err
