"""Issue 33 (helper A): ``[life]`` files and ``shm health`` inputs a careless or unlucky user gives.

Each corpus case (``tests/bad_inputs_newer_life_health.py``) runs ``shm`` in-process and must end with exit 2, one
``error:`` line naming the file/key/option and the reason, no traceback, no "internal error", and no pre-existing
file of the corpus changed. Hypothesis mutates a valid ``[life]`` file and health's inputs: never a traceback or an
internal error. Also here: the answer when the board itself said FAULT, the --out lock and foreign folders of
``shm health``, a full disk, and an error raised inside a life's worker.
"""

from __future__ import annotations

import errno
import hashlib
import sqlite3
from pathlib import Path
from types import SimpleNamespace

import pytest
from bad_inputs_newer_life_health import LIFE, all_cases, board_record, write_corpus_files
from bad_inputs_support import one_error_line, run_shm, run_to_one_clear_line, written_corpus
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

CASES = all_cases()


def _snapshot(d: Path) -> dict[str, str]:
    return {str(p.relative_to(d)): hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(d.rglob("*"))
            if p.is_file() and "out" not in p.relative_to(d).parts[:1] and p.name != ".shm-run.lock"}


@pytest.fixture(scope="module")
def corpus(tmp_path_factory) -> Path:
    return written_corpus(tmp_path_factory, "bad_inputs_life_health", write_corpus_files)


def test_the_corpus_is_large_and_covers_lives_and_health() -> None:
    assert len(CASES) >= 55
    assert sum(c.argv[0] == "run" for c in CASES) >= 30 and sum(c.argv[0] == "health" for c in CASES) >= 25


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_bad_input_is_one_clear_line_and_touches_nothing(case, corpus: Path, capsys, monkeypatch) -> None:
    before = _snapshot(corpus)
    run_to_one_clear_line(case, corpus, capsys, monkeypatch, forbidden=("brokenprocesspool",))
    assert _snapshot(corpus) == before, "a pre-existing file changed"


# --- wrong answer: the board said FAULT ---------------------------------------------------------------------
def test_health_says_already_faulty_when_the_board_said_fault_without_a_trend() -> None:
    """Three visits, the board's own verdict FAULT at the third, no significant trend: "already faulty" with the
    hour, not "no significant trend: no date" (issue 33)."""
    from studies.health.assess import levels

    est = {"name": "alpha_h", "relative": 0.01, "stderr": 1e-4, "nominal": 1.0, "verdict": "as nominal",
           "at_bound": False}
    doc = {"visits": [{"visit": i + 1, "operating_hours": 100.0 * i, "board_verdict": v, "estimates": [est],
                       "held_rms_sigma": 1.0} for i, v in enumerate(("PASS", "PASS", "FAULT"))],
           "forecast": {}, "visits_used": 3}
    fc = SimpleNamespace(already_faulty=False, significant=False, trip_operating_hours=None, lower_bound_hours=900.0,
                         last_hours=200.0, rul_hours=None, p_fault_next_visit=None, horizon_hours=2000.0,
                         next_visit_hours=300.0)
    text = levels(doc, {}, fc).how_long  # type: ignore[arg-type]
    assert text.startswith("already faulty") and "visit 3 (200 h)" in text, text
    assert "no significant trend" not in text
    assert doc["forecast"]["already_faulty"] is True  # type: ignore[index]


# --- files: the --out of shm health ----------------------------------------------------------------------------
def test_two_health_on_one_out_the_second_names_the_lock(corpus: Path, tmp_path: Path, capsys) -> None:
    from shm_cli.run_lock import OutputLock

    out = tmp_path / "h"
    out.mkdir()
    with OutputLock(out, command="shm health --out h"):  # a first shm health holding it
        code = run_shm(["health", str(corpus / "life_run"), "--out", str(out)])
    line = one_error_line(capsys.readouterr().err)
    assert code == 2 and "in use" in line and "shm health" in line and str(out) in line


def test_a_full_disk_leaves_no_half_written_report_and_names_the_path(tmp_path: Path, monkeypatch) -> None:
    from shm_cli.health_cmd import write_staged

    out = tmp_path / "h"
    out.mkdir()
    (out / "report.html").write_text("<html>the earlier, complete report</html>")
    real = Path.write_text

    def full_disk(self: Path, data: str, *a, **k) -> int:
        if self.name == "report.html":
            real(self, data[: len(data) // 2])  # what a full disk leaves: a cut-off file
            raise OSError(errno.ENOSPC, "No space left on device", str(self))
        return real(self, data, *a, **k)

    def write(d: Path) -> dict[str, str]:  # as studies.health.report.write_health_outputs does it
        (d / "health.json").write_text("{}")
        try:
            (d / "report.html").write_text("<html>" + "x" * 1000 + "</html>")
        except OSError as exc:
            return {"report.html": f"{type(exc).__name__}: {exc}"}
        return {}

    monkeypatch.setattr(Path, "write_text", full_disk)
    failed = write_staged(out, write)
    monkeypatch.undo()
    assert (out / "report.html").read_text() == "<html>the earlier, complete report</html>"
    assert (out / "health.json").read_text() == "{}"
    assert "disk is full" in failed["report.html"] and "MB free" in failed["report.html"]
    assert not (out / ".shm-health-new").exists()
    # health.json itself cannot be written: one line naming the path and the disk (OSError: exit 1 in main)
    monkeypatch.setattr(Path, "write_text", lambda self, *a, **k: (_ for _ in ()).throw(
        OSError(errno.ENOSPC, "No space left on device", str(self))))
    with pytest.raises(OSError, match="disk is full") as exc:
        write_staged(out, write)
    assert str(out) in str(exc.value) and "MB free" in str(exc.value)


def test_a_full_disk_during_a_life_is_one_line_and_keeps_the_earlier_life(tmp_path: Path, capsys,
                                                                          monkeypatch) -> None:
    """sqlite's "database or disk is full" while the life's log is written: exit 1, one line naming the folder
    and the disk; the earlier life in --out is left whole (the new one was being built beside it)."""
    import studies.health.life as life_mod
    from studies.health.life import LifeResult, VisitRun

    toml = tmp_path / "life.toml"
    toml.write_text(LIFE)
    out = tmp_path / "life"
    out.mkdir()
    (out / "summary.json").write_text('{"earlier": true}')
    visit = VisitRun(1, 0.0, {"alpha_h": 0.0}, 1, [], 0.1, "PASS")
    monkeypatch.setattr(life_mod, "run_life", lambda *a, **k: LifeResult([visit], 0.1, 2, False, 3))

    def disk_full(*a, **k):
        raise sqlite3.OperationalError("database or disk is full")

    monkeypatch.setattr(life_mod, "write_life_log", disk_full)
    code = run_shm(["run", "--scenario", str(toml), "--quiet", "--force", "--out", str(out)])
    line = one_error_line(capsys.readouterr().err)
    assert code == 1 and "database or disk is full" in line and "disk is full" in line and str(out) in line
    assert "bug in mfc-shm" not in line
    assert (out / "summary.json").read_text() == '{"earlier": true}'
    assert not (out / ".shm-life-new").exists()


# --- an error inside a worker ----------------------------------------------------------------------------
def test_an_input_error_inside_a_worker_is_the_same_clear_line(tmp_path: Path) -> None:
    """Bypassing the parent's checks (a file changed under a running life, a check not yet written): the worker's
    InputError reaches the parent as an InputError with the same message, the pool ends, no worker is left."""
    from board_config.errors import InputError
    from board_config.scenario import load_scenario
    from studies.health.life import run_life

    toml = tmp_path / "life.toml"
    toml.write_text(LIFE.replace('parameter = "alpha_h"', 'parameter = "nosuch"'))
    with pytest.raises(InputError, match=r"rig\.deviations\.nosuch.*no such model parameter") as exc:
        run_life(load_scenario(toml), seed=1, params="table2", workers=2)
    assert "BrokenProcessPool" not in str(exc.value)
    import multiprocessing

    assert not [p for p in multiprocessing.active_children() if p.is_alive()]


# --- hypothesis: mutated [life] files and health inputs never give an internal error ---------------------
_LIFE_TOKENS = ["3", "-3", "0", "1e9", "nan", "inf", "-1e-2", "2.5", '"x"', "[]", "{}", "true", '"h"', '"1/h"',
                '"k3"', '"G_leak"', '"power"', '"step"', '"nosuch"', "=", "[", "]", "\n", "[[life.law]]", "[life]",
                "value", "unit", "rate", "exponent", "at", "visits", "visit_interval", "tick_flights"]


def _mutate(text: str, cuts: list[tuple[int, int, str]]) -> str:
    for pos, length, token in cuts:
        p = pos % (len(text) + 1)
        text = text[:p] + token + text[p + length:]
    return text


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(cuts=st.lists(st.tuples(st.integers(0, 10_000), st.integers(0, 8), st.sampled_from(_LIFE_TOKENS)),
                     min_size=1, max_size=4))
def test_mutated_life_files_never_give_an_internal_error(cuts, tmp_path_factory, monkeypatch, capsys) -> None:
    """A mutation that is still valid is validated in full (the parent's checks, every visit's scenario and
    deviations) and then stopped before the visits' simulation (seconds each): exit 0; any other exit is 2 with
    one named error line."""
    import shm_cli.life_cmd as life_cmd
    from board_config.scenario import load_scenario
    from studies.health.life import plan_life, with_ticked_flights

    d = tmp_path_factory.mktemp("mut")
    toml = d / "life.toml"
    toml.write_text(_mutate(LIFE, cuts))

    def validated_only(args, scenario, *rest):  # what every worker would do before simulating
        for _v, _h, devs in plan_life(scenario):
            sc = load_scenario(scenario.source).with_rig(deviations=dict(devs))
            if sc.life is not None and sc.life.tick_flights > 0:
                with_ticked_flights(sc, sc.life.tick_flights)
        return 0

    monkeypatch.setattr(life_cmd, "_run_life_staged", validated_only)
    code = run_shm(["run", "--scenario", str(toml), "--quiet", "--out", str(d / "out")])
    err = capsys.readouterr().err
    assert "Traceback" not in err and "internal error" not in err, err
    assert code in (0, 2), err
    if code == 2:
        one_error_line(err)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(hours=st.lists(st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.sampled_from([0.0, 100.0, 1e9])),
                      min_size=1, max_size=4),
       uids=st.lists(st.sampled_from(["run-1", "run-2", ""]), min_size=4, max_size=4),
       boards=st.lists(st.sampled_from(["cfg-a", "cfg-b", ""]), min_size=4, max_size=4),
       tests=st.lists(st.sampled_from(["mbit-a", "mbit-b", "step", "nosuch"]), min_size=4, max_size=4),
       params=st.sampled_from(["table2", "nosuch", "", "table2.toml"]), dup=st.booleans())
def test_mutated_health_inputs_never_give_an_internal_error(hours, uids, boards, tests, params, dup,
                                                             tmp_path_factory, monkeypatch, capsys) -> None:
    """Records of mixed hours, runs, boards and tests (the fits are replaced by a stop: what matters is that the
    inputs are judged before them): exit 2 with one named error line, or they reach the assessment."""
    import studies.health.assess as assess_mod

    d = tmp_path_factory.mktemp("hmut")
    files = []
    for i, h in enumerate(hours):
        f = d / f"r{i}.csv"
        f.write_text(board_record(h, i + 1, test=tests[i], run_uid=uids[i], board_id=boards[i]))
        files.append(str(f))
    if dup:
        files.append(files[0])

    class Reached(BaseException):  # past main's own handlers
        pass

    def stop(sources, **k):
        from studies.health.sources import load_visits

        load_visits(sources)
        raise Reached

    monkeypatch.setattr(assess_mod, "assess_health", stop)
    try:
        code = run_shm(["health", *files, "--params", params, "--out", str(d / "out")])
    except Reached:
        return
    err = capsys.readouterr().err
    assert "Traceback" not in err and "internal error" not in err, err
    assert code == 2, err
    one_error_line(err)


def test_every_input_error_crosses_a_process_boundary_whole() -> None:
    """An InputError subclass with its own __init__ (ConfigError, RecordError ...) raised in a worker of any pool
    (the health fits', the campaign's) used to fail to unpickle in the parent and break the pool; now it arrives as
    the same error, message and attributes."""
    import pickle

    from board_config.errors import ConfigError
    from board_config.parameter import ParameterError
    from drivers.link_url import LinkUrlError
    from workbench.records import RecordError

    for err in (ConfigError("p.toml", "parameters.k3.unit", "expected unit 'N/m', got 'N/mm'"),
                RecordError("r.csv", "not finite", line=9, column="z3_mm"), LinkUrlError("sim://?seed=-1", "bad seed"),
                ParameterError("bad", where="w", name="k3", reason="r")):
        back = pickle.loads(pickle.dumps(err))
        assert type(back) is type(err) and str(back) == str(err) and back.__dict__ == err.__dict__
