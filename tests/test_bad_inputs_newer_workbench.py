"""The bad-input corpus of the newer workbench commands and effect files (issue 33), run in-process like
``tests/test_bad_inputs.py``: every case ends with exit 2, one ``error:`` line naming the file/option/key and the
reason, no traceback — and no file that was in the corpus folder before the case is changed by it (hashes before and
after). The cases and files are in ``tests/bad_inputs_newer_workbench.py``. Two concurrent ``shm synth`` on one
``--out`` leave one whole, loadable file and the second one says so.
"""

from __future__ import annotations

import fcntl
import hashlib
import os
import re
import threading
from pathlib import Path

import pytest
from bad_inputs_newer_workbench import SLOW_CASES, all_newer_cases, write_newer_files

from shm_cli.main import main

CASES = all_newer_cases()
PARAMS = [pytest.param(c, id=c.id, marks=[pytest.mark.slow] if c in SLOW_CASES else []) for c in CASES]


@pytest.fixture(scope="module")
def corpus(tmp_path_factory):
    d = tmp_path_factory.mktemp("bad_newer")
    write_newer_files(d)
    fd = os.open(d / "busy" / ".shm-run.lock", os.O_RDWR | os.O_CREAT, 0o644)
    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)  # another shm command running on busy/
    os.pwrite(fd, b'{"pid": 1, "command": "shm diagnose rec.csv --out busy"}\n', 0)
    yield d
    os.close(fd)


@pytest.fixture(autouse=True)
def _no_leftover_log_handlers():
    """``shm hil serve`` configures logging on the stderr of the moment (pytest's capture): drop such handlers."""
    import logging

    root = logging.getLogger()
    before = list(root.handlers)
    yield
    for h in list(root.handlers):
        if h not in before:
            root.removeHandler(h)


def file_hashes(d: Path) -> dict[str, str]:
    """sha256 of every regular file under ``d`` (symbolic links by their target text)."""
    out = {}
    for p in sorted(d.rglob("*")):
        if p.is_symlink():
            out[str(p)] = "->" + os.readlink(p)
        elif p.is_file():
            out[str(p)] = hashlib.sha256(p.read_bytes()).hexdigest()
    return out


def run_shm(argv: list[str]) -> int:
    try:
        return int(main(argv) or 0)
    except SystemExit as exc:  # argparse: usage errors
        return exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 2)


def test_the_corpus_is_large_and_covers_the_newer_commands() -> None:
    assert len(CASES) >= 55
    assert {c.argv[0] for c in CASES} >= {"discover", "fit", "synth", "compare", "diagnose", "hil"}
    assert sum("effect" in c.id for c in CASES) >= 30


@pytest.mark.parametrize("case", PARAMS)
def test_bad_input_is_one_clear_line_and_touches_nothing(case, corpus: Path, capsys, monkeypatch) -> None:
    monkeypatch.delenv("SHM_DEBUG", raising=False)
    before = file_hashes(corpus)
    code = run_shm(case.resolved(corpus))
    cap = capsys.readouterr()
    assert "Traceback" not in cap.err + cap.out, cap.err
    assert code == case.code, f"exit {code}, expected {case.code}: {cap.err[-800:]}"
    errors = [ln for ln in re.split(r"[\r\n]+", cap.err) if re.search(r"\berror\b:", ln)]
    assert len(errors) == 1, f"expected one error line, got {len(errors)}: {cap.err[-800:]}"
    line = errors[0].lower()
    missing = [n for n in case.needles if n.lower() not in line]
    assert not missing, f"the error line does not name {missing}: {errors[0]}"
    assert "bug in mfc-shm" not in line
    after = file_hashes(corpus)
    changed = [p for p, h in before.items() if after.get(p) != h]
    assert not changed, f"files there before the case were changed or removed: {changed}"


def test_two_synth_on_one_out_leave_one_whole_file(tmp_path: Path) -> None:
    """Two ``shm synth --out same.csv`` at once: one writes, the other refuses (exit 2); the file loads."""
    from workbench.records import load_record

    out = tmp_path / "same.csv"
    codes: list[int] = []
    barrier = threading.Barrier(2)

    def one(seed: int) -> None:
        barrier.wait()
        codes.append(run_shm(["synth", "--test", "step", "--duration-s", "1", "--seed", str(seed), "--out",
                              str(out)]))

    threads = [threading.Thread(target=one, args=(s,)) for s in (1, 2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert sorted(codes) == [0, 2], codes
    assert load_record(out).n_samples == 1001
    assert [p.name for p in tmp_path.iterdir()] == ["same.csv"]  # no temporary left behind
    assert run_shm(["synth", "--test", "step", "--duration-s", "2", "--out", str(out), "--force"]) == 0
    assert load_record(out).n_samples == 2001
