"""No command stays silent for more than 2 s, even on a fresh clone's cold numba cache (issue 27.1).

Each test runs a command in a subprocess with ``NUMBA_CACHE_DIR`` pointed at an empty directory (every kernel it
needs compiles, tens of seconds each) and stamps its output lines as they arrive (:mod:`bench.output_timing`). The
first line must come within 2 s, and no later stretch without output may exceed 2 s unless the line before it announced
the work under way (ends in "…"): the plant's "compiling the model for effects … (first use, ~N s) …", a progress
stage of ``shm diagnose``. Each test also checks that the cold start really compiled (the announcement is there) and
that a warm start announces nothing. Slow: cold compiles take tens of seconds to minutes.
"""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from bench.output_timing import LIMIT_S, cold_env, exit_tail_s, run_timed, unexplained_silences

SHM = [sys.executable, "-m", "shm_cli.main"]

pytestmark = pytest.mark.slow


def _check(run, what: str) -> None:
    silences = unexplained_silences(run)
    assert not silences, f"{what} went silent:\n" + "\n".join(silences) + "\n--- output ---\n" + run.text()
    # and the shell gets its prompt back soon after the last line (the interpreter's teardown after a compile)
    assert exit_tail_s(run) <= LIMIT_S, f"{what}: {exit_tail_s(run):.1f} s from its last line to its exit"


def _compiles(run) -> list[str]:
    return [line for _t, line in run.lines if line.startswith("compiling ")]


def test_model_info_announces_its_cold_compile_and_is_never_silent(tmp_path):
    env = cold_env(tmp_path / "numba")
    cold = run_timed([*SHM, "model", "info"], env, timeout_s=600, cwd=tmp_path)
    assert cold.returncode == 0, cold.text()
    assert any("compiling the nominal model (amplifier terminal) (first use, ~" in c for c in _compiles(cold))
    _check(cold, "shm model info (cold)")
    warm = run_timed([*SHM, "model", "info"], env, timeout_s=300, cwd=tmp_path)
    assert warm.returncode == 0 and not _compiles(warm), warm.text()  # a warm start says nothing about compiling
    assert warm.wall_s < cold.wall_s / 3


@pytest.fixture(scope="module")
def short_record(tmp_path_factory) -> Path:
    from workbench.records import write_record
    from workbench.simulation import synth_record, synth_test, truth_model

    rec = synth_record(synth_test("mbit-b", duration_s=2.0),
                       truth_model("table2", ["geometric_stiffening"], {"kappa_nl": 2e4}), noise={"z3": 2e-6}, seed=0)
    return write_record(rec, tmp_path_factory.mktemp("rec") / "stiff.csv")


def test_diagnose_reports_its_stages_and_compiles_on_a_short_record(tmp_path, short_record):
    env = cold_env(tmp_path / "numba")
    # one effect (a composition to compile cold) and one re-estimation: every stage, a counted one of two
    argv = [*SHM, "diagnose", str(short_record), "--candidates", "geometric_stiffening,k3", "--out",
            str(tmp_path / "diag")]
    run = run_timed(argv, env, timeout_s=900, cwd=tmp_path)
    assert run.returncode == 0, run.text()
    text = run.text()
    assert _compiles(run), text  # cold: the compositions compiled, announced
    # a log (stderr is a pipe): one line per stage, each announcing the work it starts
    for stage in ("diagnose: loading", "diagnose: nominal model", "diagnose: screening parameters",
                  "diagnose: fitting candidates", "diagnose: residual tests", "diagnose: verdict",
                  "diagnose: writing the report"):
        assert stage in text
    _check(run, "shm diagnose (cold)")
    # on a terminal (warm now): a live bar per stage, redrawn every second — no stretch over 2 s at all, since
    # a bar's line does not end in "…"; counted stages show n/total and the candidate just done
    tty = run_timed(argv, env, timeout_s=600, cwd=tmp_path, tty=True)
    assert tty.returncode == 0 and not _compiles(tty), tty.text()
    assert any(line.startswith("diagnose: fitting candidates:") and "/2" in line for _t, line in tty.lines)
    _check(tty, "shm diagnose (warm, on a terminal)")


def test_hil_serve_says_what_it_builds_before_its_port_opens(tmp_path):
    env = cold_env(tmp_path / "numba")
    argv = [*SHM, "hil", "serve", "--modbus-tcp", "127.0.0.1:0", "--duration", "60", "--status-every", "0"]
    run = run_timed(argv, env, timeout_s=600, cwd=tmp_path, stop_when=lambda line: "board: --link" in line)
    assert run.stopped and any("board: --link" in line for _t, line in run.lines), run.text()
    assert _compiles(run), run.text()
    _check(run, "shm hil serve (cold)")
