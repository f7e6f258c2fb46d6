"""What every bad-input corpus test shares (tests/*/test_bad_inputs*.py): run ``shm`` in-process, check the one
clear error line a case must end with, fingerprint the files a case must not touch, and drop the logging handlers
``shm hil serve`` leaves on pytest's closed capture stream."""

from __future__ import annotations

import hashlib
import logging
import os
import re
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from shm_cli.main import main


@pytest.fixture(autouse=True)
def no_leftover_log_handlers() -> Iterator[None]:
    """``shm hil serve`` configures logging on the stderr of the moment; in-process that is pytest's capture, closed
    after the case: drop such handlers so a later case's library warning does not hit a closed stream."""
    root = logging.getLogger()
    before = list(root.handlers)
    yield
    for h in list(root.handlers):
        if h not in before:
            root.removeHandler(h)


def run_shm(argv: list[str]) -> int:
    """``shm argv`` in this process; its exit code (argparse's usage errors included)."""
    try:
        return int(main(argv) or 0)
    except SystemExit as exc:  # argparse: usage errors
        return exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 2)


def one_error_line(err: str) -> str:
    """The one ``error:`` line of ``err`` (fails the test when there are none or several)."""
    errors = [ln for ln in re.split(r"[\r\n]+", err) if re.search(r"\berror\b:", ln)]
    assert len(errors) == 1, f"expected one error line, got {len(errors)}: {err[-800:]}"
    return errors[0]


def assert_one_clear_line(case: Any, code: int, cap: Any, forbidden: tuple[str, ...] = ()) -> str:
    """The case ended with its exit code and one error line naming its needles, no traceback, no 'bug' wording."""
    assert "Traceback" not in cap.err + cap.out, cap.err
    assert code == case.code, f"exit {code}, expected {case.code}: {cap.err[-800:]}"
    line = one_error_line(cap.err).lower()
    missing = [n for n in case.needles if n.lower() not in line]
    assert not missing, f"the error line does not name {missing}: {line}"
    for word in ("bug in mfc-shm", *forbidden):
        assert word not in line, line
    return line


def written_corpus(tmp_path_factory: Any, name: str, write: Callable[[Path], None]) -> Path:
    """A fresh directory ``name`` with a corpus's files written by ``write`` (for a module-scoped fixture)."""
    d = tmp_path_factory.mktemp(name)
    write(d)
    return Path(d)


def run_to_one_clear_line(case: Any, corpus: Path, capsys: Any, monkeypatch: Any,
                          forbidden: tuple[str, ...] = ()) -> str:
    """``shm`` on ``case`` over the corpus directory ``corpus`` (``SHM_DEBUG`` unset), in this process: it ended with
    the case's exit code and one clear error line (:func:`assert_one_clear_line`); that line, lower-case."""
    monkeypatch.delenv("SHM_DEBUG", raising=False)
    code = run_shm(case.resolved(corpus))
    return assert_one_clear_line(case, code, capsys.readouterr(), forbidden)


def file_hashes(d: Path) -> dict[str, str]:
    """sha256 of every regular file under ``d`` (symbolic links by their target text)."""
    out = {}
    for p in sorted(d.rglob("*")):
        if p.is_symlink():
            out[str(p)] = "->" + os.readlink(p)
        elif p.is_file():
            out[str(p)] = hashlib.sha256(p.read_bytes()).hexdigest()
    return out
