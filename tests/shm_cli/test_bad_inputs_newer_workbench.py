"""The bad-input corpus of the newer workbench commands and effect files (issue 33), run in-process like
``tests/shm_cli/test_bad_inputs.py``: every case ends with exit 2, one ``error:`` line naming the file/option/key and
the
reason, no traceback — and no file that was in the corpus folder before the case is changed by it (hashes before and
after). The cases and files are in ``tests/bad_inputs_newer_workbench.py``. Two concurrent ``shm synth`` on one
``--out`` leave one whole, loadable file and the second one says so.
"""

from __future__ import annotations

import fcntl
import os
import threading
from pathlib import Path

import pytest
from bad_inputs_newer_workbench import SLOW_CASES, all_newer_cases, write_newer_files
from bad_inputs_support import file_hashes, no_leftover_log_handlers, run_shm, run_to_one_clear_line  # noqa: F401 (autouse fixture)

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


def test_the_corpus_is_large_and_covers_the_newer_commands() -> None:
    assert len(CASES) >= 55
    assert {c.argv[0] for c in CASES} >= {"discover", "fit", "synth", "compare", "diagnose", "hil"}
    assert sum("effect" in c.id for c in CASES) >= 30


@pytest.mark.parametrize("case", PARAMS)
def test_bad_input_is_one_clear_line_and_touches_nothing(case, corpus: Path, capsys, monkeypatch) -> None:
    before = file_hashes(corpus)
    run_to_one_clear_line(case, corpus, capsys, monkeypatch)
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
