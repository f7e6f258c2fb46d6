"""A bad option or argument is one line, ``shm <cmd>: error: <what>; see 'shm <cmd> --help'``, exit 2 — not
argparse's usage block (several lines of every option) printed before the error (shm_cli.main.ShmArgumentParser).
``--help`` still prints the usage and exits 0."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from shm_cli.main import main

BIN = Path(sys.executable).parent

CASES = [
    (["diagnose"], "shm diagnose", "the following arguments are required: RECORD, --out"),
    (["diagnose", "r.csv", "--out", "o", "--bogus"], "shm diagnose", "unrecognized arguments: --bogus"),
    (["run", "--seed", "x"], "shm run", "argument --seed: invalid int value: 'x'"),
    (["model"], "shm model", "the following arguments are required: SUBCOMMAND"),
    (["model", "info", "--bogus"], "shm model info", "unrecognized arguments: --bogus"),
    (["log", "show", "--db"], "shm log show", "argument --db: expected one argument"),
    (["health", "--f", "x"], "shm health", "ambiguous option: --f could match"),
    (["nosuch"], "shm", "argument COMMAND: invalid choice: 'nosuch'"),
    ([], "shm", "the following arguments are required: COMMAND"),
    (["--debug", "fit", "--bogus"], "shm fit", "the following arguments are required"),
]


def _run(argv: list[str]) -> int:
    try:
        return int(main(argv) or 0)
    except SystemExit as exc:
        return exc.code if isinstance(exc.code, int) else 2


@pytest.mark.parametrize(("argv", "prog", "what"), CASES, ids=[" ".join(c[0]) or "nothing" for c in CASES])
def test_a_usage_error_is_one_line_naming_the_command_and_the_help(argv, prog, what, capsys):
    assert _run(argv) == 2
    cap = capsys.readouterr()
    assert cap.out == ""
    assert "usage:" not in cap.err and "Traceback" not in cap.err, cap.err
    lines = cap.err.splitlines()
    assert len(lines) == 1, cap.err
    assert lines[0].startswith(f"{prog}: error: {what}"), lines[0]
    assert lines[0].endswith(f"; see '{prog} --help'"), lines[0]


def test_help_still_shows_the_usage_and_exits_0(capsys):
    assert _run(["diagnose", "--help"]) == 0
    assert capsys.readouterr().out.startswith("usage: shm diagnose ")


def test_the_installed_command_says_one_line_too():
    r = subprocess.run([str(BIN / "shm"), "run", "--seed", "x"], capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and r.stdout == ""
    assert r.stderr == "shm run: error: argument --seed: invalid int value: 'x'; see 'shm run --help'\n", r.stderr
