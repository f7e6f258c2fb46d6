"""Help texts say what is there, and a folder never hides a shipped scenario (issue 27, point 6).

* every ``shm ... --help`` prints ``%`` as ``%`` (argparse formats ``help`` with ``%``, not ``description``: a
  ``%%`` in a description is printed as is — `shm campaign --help` said "95 %%");
* ``shm run --help`` names every shipped scenario (from the registry of ``board_config/scenarios``, not a list in
  the help that falls behind);
* a directory named like a shipped scenario in the working directory (``mkdir aging`` — often a run's ``--out``)
  does not hide it: ``--scenario aging`` means the shipped one; a directory given as a scenario otherwise is a clear
  one-line error, not "Is a directory".
"""

from __future__ import annotations

import argparse
from pathlib import Path

import pytest

from board_config.errors import ConfigError
from board_config.scenario import SCENARIO_DIR, available_scenarios, load_scenario, resolve_scenario_file
from shm_cli.main import build_parser, main


def _all_parsers(parser: argparse.ArgumentParser, words: tuple[str, ...] = ("shm",)):
    yield words, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from _all_parsers(sub, (*words, name))


def test_no_help_text_prints_a_doubled_percent_sign():
    bad = [" ".join(words) for words, p in _all_parsers(build_parser()) if "%%" in p.format_help()]
    assert not bad, f"'%%' printed by: {bad}"


def test_campaign_help_prints_95_percent():
    helps = {" ".join(w): p.format_help() for w, p in _all_parsers(build_parser())}
    assert "95 % Wilson" in " ".join(helps["shm campaign"].split())


def test_run_help_lists_every_shipped_scenario():
    shipped = available_scenarios()
    assert {"default", "maintenance", "degraded", "faults", "patch_leakage", "aging"} <= set(shipped)
    helps = {" ".join(w): p.format_help() for w, p in _all_parsers(build_parser())}
    text = " ".join(helps["shm run"].split())
    missing = [n for n in shipped if n not in text]
    assert not missing, f"shm run --help does not name {missing}"


@pytest.mark.parametrize("typed", ["aging", "aging/"])
def test_a_folder_named_like_a_shipped_scenario_does_not_hide_it(tmp_path, monkeypatch, typed):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "aging").mkdir()
    assert resolve_scenario_file(typed) == SCENARIO_DIR / "aging.toml"
    assert load_scenario(typed).name == "aging"


def test_a_directory_is_never_read_as_a_scenario(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "my_runs").mkdir()
    with pytest.raises(ConfigError, match="is a directory, not a scenario file"):
        load_scenario("my_runs")
    with pytest.raises(ConfigError, match="is a directory"):
        load_scenario(str(tmp_path))


def test_a_file_named_like_a_shipped_scenario_is_still_the_users(tmp_path, monkeypatch):
    """What the user can see wins when it can be a scenario: a file (not a folder) of that name is read."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "faults").write_text((SCENARIO_DIR / "maintenance.toml").read_text())
    assert resolve_scenario_file("faults") == Path("faults")


@pytest.mark.slow
def test_shm_run_with_a_folder_named_like_the_scenario(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "default").mkdir()
    rc = main(["run", "--scenario", "default", "--duration-s", "0.3", "--quiet", "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert rc == 0, err
    assert "Is a directory" not in err and (tmp_path / "out" / "usage.db").exists()
    rc = main(["run", "--scenario", "out", "--duration-s", "0.3", "--quiet", "--out", str(tmp_path / "o2")])
    err = capsys.readouterr().err
    assert rc == 2 and "out: key '-': is a directory, not a scenario file" in err and "Traceback" not in err
