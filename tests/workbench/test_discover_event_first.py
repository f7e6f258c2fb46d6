"""Issue 26 point 7 (speed): when the current model matches a record to the noise until an instant and misses it
after (a damage event), ``shm discover`` probes the time-gated terms at that onset and refits them first; only when
none reaches the noise floor are the other rows probed on the full model and refitted
(:func:`workbench.discover._rounds.event_first`)."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import pytest

import workbench.discover._rounds as rounds
from workbench.discover._dictionary import Term
from workbench.discover._results import ScreenRow

FOREIGN = Path(__file__).parents[1] / "workbench_foreign_damage.py"


def _row(key: str, form: str, param: str = "k", index: int = 1) -> ScreenRow:
    term = Term("damage", index, "one", form, 1.0, param, (0.0, 4.0)) if form in ("on_step", "on_ramp") else \
        Term("force_mass", index, key, form)
    return ScreenRow(term, 0.1, 50.0, 50.0, 2.0 if form in ("on_step", "on_ramp") else None)


def _flow(monkeypatch: pytest.MonkeyPatch, timed_held: float, ramp_held: float = 60.0) -> tuple[list[str], object]:
    """event_first with its probes and refits replaced by fakes: what it called, in order, and its best refit."""
    calls: list[str] = []
    timed = [_row("k1_step", "on_step"), _row("k1_ramp", "on_ramp")]
    constant = [_row("zd1", "lin"), _row("zd2", "lin", index=2)]

    def onset_screen(setup, progress, settings, rows, batch):
        calls.append("onset probe")
        return timed

    def nonlinear_screen(setup, progress, settings, rows):
        calls.append("nonlinear probes")
        return constant

    def refit_best(setup, progress, settings, todo, tried):
        calls.append("refit " + ",".join(r.term.form for r in todo))
        held = timed_held if todo[0].term.form == "on_step" else 30.0
        if todo[0].term.form == "on_step":
            tried += [{"term": todo[0].term.key, "held_rms_sigma": held},
                      {"term": todo[1].term.key, "held_rms_sigma": ramp_held}]
        return rounds.BestRefit(held, 0, SimpleNamespace(held_rms_sigma=held))

    monkeypatch.setattr(rounds, "onset_screen", onset_screen)
    monkeypatch.setattr(rounds, "nonlinear_screen", nonlinear_screen)
    monkeypatch.setattr(rounds, "refit_best", refit_best)
    setup = SimpleNamespace(n_held=10_000, terms=[timed[0].term])
    settings = SimpleNamespace(n_refit=4)
    _, best = rounds.event_first(setup, None, settings, constant, None, [])
    return calls, best


def test_a_time_gated_term_at_the_noise_floor_ends_the_round_before_any_other_probe(monkeypatch):
    calls, best = _flow(monkeypatch, timed_held=1.0)
    assert calls == ["onset probe", "refit on_step,on_ramp"]
    assert best.held_rms_sigma == 1.0


def test_without_a_time_gated_term_at_the_noise_floor_the_other_rows_are_probed_and_refitted(monkeypatch):
    calls, best = _flow(monkeypatch, timed_held=80.0)
    assert calls == ["onset probe", "refit on_step,on_ramp", "nonlinear probes", "refit lin,lin"]
    assert best.held_rms_sigma == 30.0  # the best over both refit lists


def test_a_refitted_twin_within_the_tolerance_gets_the_rows_probed_for_the_order_twins_are_named_in(monkeypatch):
    calls, best = _flow(monkeypatch, timed_held=1.0, ramp_held=1.01)
    assert calls == ["onset probe", "refit on_step,on_ramp", "nonlinear probes"]
    assert best.held_rms_sigma == 1.0


@pytest.mark.slow
def test_a_stiffness_drop_mid_sweep_is_refitted_first_and_found_without_the_other_refits():
    """A 6 s sweep whose section 2 loses 25 % of its stiffness at 3.3 s (written outside the dictionary): the
    round refits the time-gated terms and, once k2's step is best, only the members of k2 constant in time (a
    time event leads only when no such member explains the records alike:
    :func:`workbench.discover._rounds.plausible_best`); it keeps k2's step at its instant, at the noise floor."""
    from workbench.discover import discover
    from workbench.simulation import synth_record, synth_test, truth_model

    truth = truth_model("table2", [f"{FOREIGN}:StiffnessDropEvent"], {"f_drop": 0.25, "t_event": 3.3})
    rec = synth_record(synth_test("sweep", duration_s=6.0), truth, noise={"z3": 2e-6}, seed=7)
    said: list[str] = []
    d = discover([rec], "table2", max_terms=1, on_progress=said.append)
    assert d.verdict == "found", d.message
    assert d.terms[0].term.key == "k2_step_t"
    assert d.terms[0].shape == pytest.approx(3.3, abs=0.01)
    refitted = [t["term"] for t in d.rounds[0]["refitted"]]
    timed = [k for k in refitted if "_step_" in k or "_ramp_" in k]
    assert timed and refitted[:len(timed)] == timed, refitted
    # then only k2's own members constant in time (its sign gates, smooth edges, gap — whatever the family holds)
    assert all(k.startswith("k2_") and k not in timed for k in refitted[len(timed):]), refitted
    assert any("an event inside the record" in m for m in said), said
