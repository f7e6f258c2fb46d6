"""A damage event inside a record found by shm discover's onset search (issue 26 points 3 and 5): a damping rise of
×3 at an instant (far beyond the ±30 % a step was first probed at); a small stiffness loss, whose step probed a few
milliseconds off the instant rings in the modes and loses to a ramp of the same parameter (the refit list); and
shm diagnose's split-record refit, which tells a damping that doubled mid-record from a wrong constant c2. Truths
written outside the dictionary: ``tests/workbench_damage_effects.py``."""

from __future__ import annotations

import pytest
from discover_damage_support import DAMAGE, discover_one_damage

from workbench.discover._dictionary import Term
from workbench.discover._onset import MAX_LOSS, _next_probes, with_onsets
from workbench.discover._results import ScreenRow


def _row(param: str, index: int, form: str, coef: float, train: float, shape: float = 2.0) -> ScreenRow:
    return ScreenRow(Term("damage", index, "one", form, 1.0, param, (0.0, 4.0)), coef, train, train, shape)


def test_the_refit_gets_the_step_and_the_ramp_of_each_leading_parameter():
    """The probe ranks the ramp of k3 first, then m3, then the step of k3 (a mistimed step rings): the refit list
    holds both forms of the two best parameters, whatever their order in the probe."""
    leads = [_row("k", 2, "on_ramp", -0.05, 40.0), _row("m", 2, "on_step", 0.3, 90.0),
             _row("k", 2, "on_step", -0.12, 95.0), _row("c", 0, "on_step", 0.1, 99.0),
             _row("m", 2, "on_ramp", 0.05, 120.0)]
    other = ScreenRow(Term("force_mass", 0, "zd1", "lin"), 0.1, 9.0, 9.0)
    out = with_onsets([other, _row("k", 2, "on_step", -0.1, 50.0, shape=None)], leads)
    assert out[0] is other
    assert {(r.term.param, r.term.form) for r in out[1:]} == {("k", "on_ramp"), ("k", "on_step"),
                                                              ("m", "on_step"), ("m", "on_ramp")}
    assert all(r.shape == 2.0 for r in out[1:])  # the probed rows, not the screen's fixed-onset ones


def test_a_probe_at_its_edge_is_followed_outwards_and_a_loss_stops_at_its_bound():
    rise = _row("c", 0, "on_step", 0.3, 10.0)
    loss = _row("k", 1, "on_step", -0.3, 10.0)
    inner = _row("m", 1, "on_step", 0.1, 10.0)
    probed = {r.term.key: [-0.3, -0.1, -0.03, 0.03, 0.1, 0.3] for r in (rise, loss, inner)}
    nxt = _next_probes({r.term.key: r for r in (rise, loss, inner)}, probed, set(), dict.fromkeys(probed, 2.0))
    by = {k: sorted(c for r, c, _ in nxt if r.term.key == k) for k in probed}
    assert 3.0 in [round(c, 9) for c in by[rise.term.key]] and max(by[rise.term.key]) == pytest.approx(3.0)
    assert min(by[loss.term.key]) == pytest.approx(MAX_LOSS)  # ×3 = −0.9, ×10 clipped at the bound
    assert max(by[inner.term.key]) == pytest.approx(0.13)  # not at its edge: refined only
    ramp = _row("k", 1, "on_ramp", -0.3 / 2.0, 10.0)  # a total change of −30 % over the 2 s left
    nxt = _next_probes({ramp.term.key: ramp}, {ramp.term.key: [-0.3, -0.1, 0.1, 0.3]}, set(), {ramp.term.key: 2.0})
    assert min(c for _, c, _ in nxt) * 2.0 == pytest.approx(MAX_LOSS)


CASES = {
    "damping rise x3": ("Section2DampingEvent", {"rise": 2.0, "t_event": 2.3}, "c2_step_t", 2.0, 0.3,
                        ("damping c2 of section 2 rose by",)),
}


@pytest.mark.slow
@pytest.mark.parametrize("case", sorted(CASES))
def test_discover_finds_an_event_at_its_instant_on_a_short_sweep(case):
    """A 4 s sweep with the event hidden: discover keeps the step of the right parameter, its size and its instant
    (within 10 ms), at the noise floor."""
    cls, values, key, size, tol, words = CASES[case]
    _, _, found = discover_one_damage(cls, values, key, words, duration_s=4.0, seed=3)
    assert found.coef == pytest.approx(size, abs=tol)
    assert found.shape == pytest.approx(values["t_event"], abs=0.01)


@pytest.mark.slow
def test_diagnose_does_not_call_a_damping_that_doubled_mid_record_a_wrong_parameter(tmp_path):
    """c2 doubles at 2 s of a 4 s sweep: re-estimating c2 over the whole record comes close to the noise floor, but
    its split-record refit differs between the parts, so diagnose runs the discovery step and its first sentence
    names the event at its instant."""
    from workbench.challenges.discovery import first_sentence, times_quoted_s
    from workbench.diagnose import diagnose
    from workbench.simulation import synth_record, synth_test, truth_model

    truth = truth_model("table2", [f"{DAMAGE}:Section2DampingEvent"], {"rise": 1.0, "t_event": 2.0})
    rec = synth_record(synth_test("sweep", duration_s=4.0), truth, noise={"z3": 2e-6}, seed=5)
    d = diagnose([rec], "table2", emit_dir=tmp_path)
    assert d.time_change is not None and [p.name for p in d.time_change.changed] == ["c2"], d.message
    head = first_sentence(d.message)
    assert head.startswith("Found beyond the library: damping c2 of section 2 rose by"), d.message
    assert any(abs(t - 2.0) < 0.02 for t in times_quoted_s(head)), head


def test_split_estimates_differ_only_beyond_their_errors_and_materially():
    from workbench.diagnose._time_change import PartEstimates, TimeChange, differs

    doubled = PartEstimates("c1", "N*s/m", 0.1, 0.002, 0.2, 0.003)
    constant = PartEstimates("k1", "N/m", 1000.0, 5.0, 1010.0, 5.0)  # 1.4 standard errors apart
    tiny = PartEstimates("m3", "kg", 1.0, 1e-6, 1.01, 1e-6)  # far apart in errors, but 1 %
    unknown = PartEstimates("d_ep", "m/V", 1.0, float("inf"), 2.0, 0.1)
    assert differs(doubled) and not differs(constant) and not differs(tiny) and not differs(unknown)
    tc = TimeChange(3.0, [doubled, constant])
    assert [p.name for p in tc.changed] == ["c1"]
    assert "c1 0.1 ± 0.002 N*s/m before t ≈ 3 s, 0.2 ± 0.003 N*s/m after (+100 %" in tc.sentence()
    assert TimeChange(3.0, [constant]).sentence() == ""


def test_a_time_change_leads_the_verdict_only_when_the_discovery_keeps_a_time_term(monkeypatch):
    """A cure presented by the library ("c1 is wrong"), refitted on two parts that differ: the discovery's result
    replaces it only when it keeps a term gated in time; a constant term (on a sweep, time is also frequency: a
    mimic's parts may differ) leaves the library's verdict first."""
    from types import SimpleNamespace

    import workbench.diagnose._discovery as dd
    from workbench.diagnose._time_change import PartEstimates, TimeChange

    monkeypatch.setattr(dd, "term_formulas", lambda disc: ["…"])
    tc = TimeChange(3.0, [PartEstimates("c1", "N*s/m", 0.1, 0.002, 0.2, 0.003)])

    def run(form: str, words: str) -> SimpleNamespace:
        d = SimpleNamespace(message="c1 is wrong: 0.196 N*s/m instead of 0.098 N*s/m (+100 %) — re-estimate it.",
                            verdict="wrong_parameter", winner=SimpleNamespace(held_rms_sigma=1.2),
                            baseline_held_rms_sigma=28.8, fit_command="", next_command="", time_change=tc)
        term = Term("damage", 0, "one", form, 3.0, "c") if form else Term("force_mass", 0, "zd1", "lin")
        disc = SimpleNamespace(terms=[SimpleNamespace(description=words, term=term, said_with="")], held_before=28.8,
                               held_after=0.97, message="Found: …", verdict="found")
        dd.final_verdict(d, disc, {"emitted": None, "fit_command": ""})
        return d

    d = run("on_step", "damping c1 of section 1 rose by 100 % at t = 3.000 s")
    assert d.message.startswith("Found beyond the library: damping c1 of section 1 rose by 100 % at t = 3.000 s")
    assert "What the library names is not constant over the record: c1 0.1 ± 0.002 N*s/m before t ≈ 3 s" in d.message
    d = run("", "a viscous force on mass 1")
    assert d.message.startswith("c1 is wrong") and "not constant" not in d.message
