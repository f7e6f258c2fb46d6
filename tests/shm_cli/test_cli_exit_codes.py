"""Exit codes that tell the truth (issue 15, point 2): 2 only for input the user can fix, an unexpected error is
exit 1 with one line calling it a bug in mfc-shm (command, exception, how to get the traceback), and a failing
figure never loses a command's numeric results."""

from __future__ import annotations

import json

import pytest

from board_config.errors import ConfigError, InputError
from shm_cli import main as shm_main
from shm_cli.main import CliError, main


def _raiser(exc: BaseException):
    def handler(args):
        raise exc
    return handler


@pytest.fixture
def info_raises(monkeypatch):
    """``shm model info`` raising a given exception."""
    from shm_cli import model_cmd

    def install(exc: BaseException) -> None:
        monkeypatch.setattr(model_cmd, "cmd_info", _raiser(exc))
    return install


def test_internal_value_error_is_a_bug_exit_1_with_one_line(info_raises, capsys, monkeypatch):
    monkeypatch.delenv("SHM_DEBUG", raising=False)
    info_raises(ValueError("'yerr' must not contain\nnegative values"))
    assert main(["model", "info"]) == 1
    cap = capsys.readouterr()
    assert cap.out == ""
    lines = cap.err.strip().splitlines()
    assert len(lines) == 1, cap.err
    line = lines[0]
    for needle in ("bug in mfc-shm", "'shm model info'", "ValueError", "'yerr' must not contain negative values",
                   "--debug", "SHM_DEBUG=1"):
        assert needle in line, line
    assert "Traceback" not in cap.err


@pytest.mark.parametrize("how", ["flag-first", "flag-after-command", "env"])
def test_debug_prints_the_traceback(info_raises, capsys, monkeypatch, how):
    monkeypatch.delenv("SHM_DEBUG", raising=False)
    info_raises(ZeroDivisionError("inside"))
    if how == "env":
        monkeypatch.setenv("SHM_DEBUG", "1")
        argv = ["model", "info"]
    else:
        argv = ["--debug", "model", "info"] if how == "flag-first" else ["model", "info", "--debug"]
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert "Traceback (most recent call last)" in err and "ZeroDivisionError: inside" in err
    assert "bug in mfc-shm" in err


@pytest.mark.parametrize("exc", [CliError("--n must be positive"), InputError("--x: bad value"),
                                 ConfigError("p.toml", "parameters.k3.value", "must be positive")])
def test_user_input_errors_exit_2_naming_the_item(info_raises, capsys, exc):
    info_raises(exc)
    assert main(["model", "info"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("shm: error: ") and str(exc).split(":")[0] in err and "bug" not in err


def test_typed_input_errors_of_every_layer_are_input_errors():
    """The error classes that name a user's file, option or value all derive from InputError (exit 2)."""
    from firmware_sim.mbit import MbitClampError
    from plant.effect import EffectError
    from studies.campaign.runner import CampaignError
    from studies.campaign.store import CampaignStoreError
    from workbench.fit import FitError
    from workbench.records import RecordError
    from workbench.simulation._replay import ReplayError

    for cls in (ConfigError, CliError, CampaignError, CampaignStoreError, MbitClampError, EffectError, FitError,
                RecordError, ReplayError):
        assert issubclass(cls, InputError), cls
        assert issubclass(cls, ValueError), cls  # callers catching ValueError keep working


def test_os_error_is_a_failed_job_not_a_bug(info_raises, capsys):
    info_raises(PermissionError(13, "Permission denied", "/root/out"))
    assert main(["model", "info"]) == 1
    err = capsys.readouterr().err
    assert "Permission denied" in err and "/root/out" in err and "bug" not in err


def test_interrupt_exits_130(info_raises, capsys):
    info_raises(KeyboardInterrupt())
    assert main(["model", "info"]) == 130


def test_user_input_deep_in_the_layers_is_exit_2(tmp_path, capsys):
    """Validation raised below the CLI (campaign spec, harvest setup, synth test, link URL) is the user's to fix."""
    cases = [
        (["campaign", "--ranges", "0:50:7", "--out", str(tmp_path / "c")], "--ranges"),
        (["harvest", "--freq-hz", "0", "--out", str(tmp_path / "h")], "excitation frequency"),
        (["synth", "--test", "sweep", "--f0-hz", "50", "--f1-hz", "10", "--out", str(tmp_path / "s.csv")],
         "f1_hz"),
        (["run", "--quiet", "--link", "modbus-tcp://host:port", "--out", str(tmp_path / "r")], "port"),
    ]
    for argv, needle in cases:
        assert main(argv) == 2, argv
        err = capsys.readouterr().err
        assert needle in err and "bug" not in err, err


def test_a_failing_figure_keeps_the_campaign_results(tmp_path, capsys, monkeypatch):
    """Point 3: the numbers (tables, runs, traces, campaign.json) are written before the figures; a figure that
    fails is named, campaign.json says so, and the exit code is 1."""
    from studies.campaign import figures as campaign_figures

    def broken(result, path):
        raise ValueError("'yerr' must not contain negative values")

    monkeypatch.setattr(campaign_figures, "fig11", broken)
    out = tmp_path / "c"
    rc = main(["campaign", "--mbit", "a", "--ranges", "0:10:10", "--n", "2", "--workers", "1", "--no-progress",
               "--json", "--out", str(out)])
    cap = capsys.readouterr()
    assert rc == 1
    summary = json.loads(cap.out)
    assert "fig11.png" in summary["figures"]["failed"]
    assert "could not write fig11.png" in cap.err and "ValueError" in cap.err
    stored = json.loads((out / "campaign.json").read_text())
    assert stored["figures"] == summary["figures"] and stored["complete"] is True
    for name in ("fig11_table.csv", "runs.csv", "traces.npz", "roc.csv", "error_traces.png", "roc.png"):
        assert (out / name).stat().st_size > 0, name
    assert not (out / "fig11.png").exists()


def test_a_failed_campaign_leaves_no_finished_looking_campaign_json(tmp_path, capsys, monkeypatch):
    """A rerun into a directory that held a finished campaign removes the old campaign.json before running: if the
    rerun fails, nothing says 'complete'."""
    import shm_cli.campaign_cmd as cc

    out = tmp_path / "c"
    argv = ["campaign", "--mbit", "a", "--ranges", "0:10:10", "--n", "1", "--workers", "1", "--no-progress",
            "--no-figures", "--out", str(out)]
    assert main(argv) == 0
    assert (out / "campaign.json").exists()
    import studies.campaign as fc

    def exploding(*a, **k):
        raise RuntimeError("worker pool vanished")

    monkeypatch.setattr(fc, "run_campaign", exploding)
    assert main([*argv, "--seed", "2"]) == 1
    assert "bug in mfc-shm" in capsys.readouterr().err
    assert not (out / "campaign.json").exists()
    assert cc  # the module under test


def test_main_docstring_states_the_policy():
    doc = shm_main.__doc__ or ""
    for needle in ("**0**", "**2**", "**1**", "InputError", "SHM_DEBUG", "--debug"):
        assert needle in doc


def test_a_failed_rerun_leaves_no_earlier_summary(tmp_path, capsys, monkeypatch):
    """harvest_summary.json (like campaign.json, diagnosis.json, fit.json, calibration.json) is written at the end
    of a run: a rerun into the same --out that fails must not leave the earlier one looking like its result."""
    import studies.harvest

    out = tmp_path / "h"
    out.mkdir()
    (out / "harvest_summary.json").write_text('{"verdict": "from an earlier run"}')

    def exploding(*a, **k):
        raise RuntimeError("integrator state corrupted")

    monkeypatch.setattr(studies.harvest, "run_harvest", exploding)
    assert main(["harvest", "--duration-s", "0.5", "--out", str(out)]) == 1
    assert "bug in mfc-shm" in capsys.readouterr().err
    assert not (out / "harvest_summary.json").exists()
