"""Damage forms in shm discover's dictionary (issue 26 point 3): a core parameter's own term switched by a gate —
the sign of a section's deflection or rate, a gap, the sign of the drive or the charge, a step or a ramp at an
instant t0 inside the record — named in an engineer's words, with t0 fitted and reported. The truths are written
outside the dictionary (tests/workbench_damage_effects.py: hard switches, their own parameters)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from discover_damage_support import discover_one_damage

from workbench.discover import build_dictionary, dictionary_source
from workbench.discover._dictionary import GATE_FORMS, Term
from workbench.discover._effect_writer import describe_term, emit_effect_source, parameter_names_for
from workbench.discover._gate_words import describe_damage
from workbench.discover._gates import class_stem, damage_formula, gate_values, gate_width, onsets


def test_gate_code_agrees_with_its_numpy_values():
    s = np.linspace(-2e-3, 2e-3, 9)
    t = np.linspace(0.0, 3.0, 9)
    for name, form in GATE_FORMS.items():
        code = form.code.replace("math.tanh", "np.tanh").replace("abs(", "np.abs(").replace("max(", "np.maximum(")
        code = code.replace("min(", "np.minimum(")
        h = gate_width(name, "m")
        g = 5e-4 if name in ("on_gap", "on_excess") or name.endswith(("_grow", "_grow2", "_sat")) else 1.4
        got = eval(code, {"np": np, "S": s, "G": g, "H": h, "t": t})
        want = gate_values(name, s, g, t, "m")
        assert np.allclose(got, want), name
    # the gap gate times a stiffness is the dead zone k (δ − clip(δ, ±g)): continuous, free play within ±g
    assert np.allclose(s * gate_values("on_gap", s, 5e-4, t, "m"), s - np.clip(s, -5e-4, 5e-4))
    # the excess gate: nothing within ±g, then rising linearly with the magnitude past it, either sign (1 at 2g)
    v = np.array([-400.0, -300.0, -150.0, 0.0, 100.0, 150.0, 225.0, 300.0])
    assert np.allclose(gate_values("on_excess", v, 150.0, v * 0.0, "V"), [5 / 3, 1.0, 0, 0, 0, 0, 0.5, 1.0])


def test_onsets_span_the_record():
    got = onsets(30.0, (0.125, 0.375, 0.625, 0.875))
    assert [t0 for t0, _ in got] == [3.75, 11.25, 18.75, 26.25]
    assert got[0][1][0] == 0.0 and got[-1][1][1] == 30.0
    assert all(a[1][1] == b[1][0] for a, b in itertools.pairwise(got))  # contiguous refit ranges


def test_words_name_the_damage_as_an_engineer_would():
    crack = describe_damage("k", 1, "on_pos", "delta2", -0.25, 0.0)
    assert crack.startswith("a breathing crack in section 2 that opens for δ2 > 0: stiffness k2 lower by 25 %")
    event = describe_damage("k", 1, "on_step", "one", -0.25, 20.04, 0.08)
    assert event.startswith("section 2 lost 25 % of its stiffness at t = 20.04 ± 0.08 s")
    patch = describe_damage("d_ep", -1, "on_neg", "va", -0.3, 0.0)
    assert patch.startswith("all three patches' authority d_ep is 30 % lower for negative drive")
    play = describe_damage("k", 0, "on_gap", "delta1", 0.4, 2e-5)
    assert "section 1 is stiffer by 40 % beyond ±20 µm of δ1" in play and "free play" in play
    ramp = describe_damage("c", 2, "on_ramp", "one", 0.01, 5.0, 0.5)
    assert "damping c3 of section 3 rising by 1 %/s from t = 5.0 ± 0.5 s" in ramp
    mass = describe_damage("m", 2, "on_step", "one", -0.1, 3.0)
    assert mass.startswith("mass m3 fell by 10 % at t = 3 s")
    rate = describe_damage("k", 1, "on_pos", "ddelta2", -0.25, 0.0)
    assert rate.startswith("stiffness k2 of section 2 25 % lower for δ̇2 > 0") and "direction of motion" in rate
    edge = describe_damage("k", 1, "on_pos_soft", "ddelta2", -0.25, 1e-3)
    assert "for δ̇2 > 0 (switching over about ±1 mm/s of δ̇2" in edge and "direction of motion" in edge
    assert "contact damping" in describe_damage("c", 1, "on_gap", "delta2", 2.0, 3e-4)
    charging = describe_damage("d_ep_i", 0, "on_pos", "ic", -0.4, 0.0)  # one sense of the charging, not of the volts
    assert charging.startswith("patch 1 (on section 1) whose authority d_ep is 40 % lower while its charging current "
                               "is positive (the charge rising, i_c > 0)")
    assert "±0.2 mA" in describe_damage("d_ep_i", 0, "on_pos_soft", "ic", -0.4, 2e-4)
    assert class_stem("d_ep_i", 0, "on_pos", "ic") == "Patch1CouplingChargingPositive"
    saturating = describe_damage("d_ep_i", 0, "on_pos_sat", "ic", -0.4, 2e-4)  # more of it the faster it charges
    assert saturating.startswith("patch 1 (on section 1) whose authority d_ep is 40 % lower while it charges, the "
                                 "more the stronger the current (63 % of it at +0.2 mA") and "discharges" in saturating
    assert class_stem("d_ep_i", 0, "on_pos_sat", "ic") == "Patch1CouplingChargingSaturatingPositive"
    assert damage_formula("d_ep_i", 0, "on_pos_sat", "ic", "a", "g").endswith("with c = a · tanh(ic⁺ / g)")
    fading = describe_damage("d_ep_i", 1, "on_neg_sat", "vc", -0.35, 80.0)  # on one polarity, saturating
    assert fading.startswith("patch 2 (on section 2) whose authority d_ep is 35 % lower for negative voltage, the "
                             "more the stronger the voltage (63 % of it at −80 V")
    assert class_stem("k", 1, "on_pos", "ddelta2") != class_stem("k", 1, "on_pos", "delta2")
    high_field = describe_damage("d_ep_i", 1, "on_gap", "vc", -0.3, 150.0)  # either polarity, past a magnitude
    assert high_field.startswith("patch 2 (on section 2) whose authority d_ep is 30 % lower above ±150 V of v_c2, "
                                 "in either polarity") and "back-switch" in high_field
    assert class_stem("d_ep_i", 1, "on_gap", "vc") == "Patch2CouplingAboveMagnitude"
    rising = describe_damage("d_ep_i", 1, "on_excess", "vc", -0.5, 150.0)  # growing linearly past a magnitude
    assert rising.startswith("patch 2 (on section 2) whose authority d_ep is lower above ±150 V of v_c2, in either "
                             "polarity, by 33.3 % per 100 V past that magnitude") and "back-switch" in rising
    assert class_stem("d_ep_i", 1, "on_excess", "vc") == "Patch2CouplingGrowingAboveMagnitude"
    square = describe_damage("k", 1, "on_neg_grow2", "delta2", -0.3, 4e-4)  # the share with the opening squared
    assert square.startswith("a breathing crack in section 2 that opens for δ2 < 0, its lost stiffness growing with "
                             "the square of the opening: k2 lower by 30 % once δ2 reaches −400 µm")
    assert class_stem("k", 1, "on_neg_grow2", "delta2") == "Section2StiffnessGrowingSquareNegative"
    d = np.array([-8e-4, -4e-4, -2e-4, 0.0, 2e-4])
    assert np.allclose(gate_values("on_neg_grow2", d, 4e-4, d * 0.0, "m"), [1.0, 1.0, 0.25, 0.0, 0.0])
    assert damage_formula("d_ep_i", 1, "on_excess", "vc", "a", "g").endswith("with c = a · (|vc| − g)⁺ / g")
    term = Term("damage", 1, "one", "on_step", 20.0, "k", (15.0, 22.5))
    assert describe_term(term, -0.25, 20.04, 1.0, 0.08) == event
    assert term.key == "k2_step_t" and term.unit == "1"
    assert Term("damage", 1, "one", "on_ramp", 20.0, "k").unit == "1/s"


def test_dictionary_without_a_duration_has_no_time_gates_and_compiles():
    scales = {f"{s}{i}": v for s, v in (("z", 1e-3), ("zd", 0.1), ("delta", 1e-3), ("ddelta", 0.1))
              for i in (1, 2, 3)} | {"vc": 50.0, "va": 100.0}
    terms = build_dictionary(scales)
    assert not any(t.form in ("on_step", "on_ramp") for t in terms)
    with_t = build_dictionary(scales | {"t": 12.0})
    assert {t.key for t in with_t} > {t.key for t in terms}
    assert not any(t.signal == "va" for t in build_dictionary(scales | {"t": 12.0}, driven=False)
                   if t.placement == "damage")
    compile(dictionary_source(with_t), "<dictionary>", "exec")


def test_emitted_damage_file_reads_the_core_parameters_by_name(tmp_path):
    from plant import resolve_effect

    terms = [Term("damage", 1, "one", "on_step", 20.0, "k", (15.0, 22.5)),
             Term("damage", -1, "va", "on_neg", 0.0, "d_ep"), Term("damage", 2, "one", "on_ramp", 3.0, "m", (0, 6)),
             Term("damage", -1, "vc", "on_pos", 0.0, "beta_h"), Term("damage", -1, "one", "on_step", 4.0, "C_ep")]
    names = parameter_names_for(terms)
    values = {c: -0.2 for c, _ in names} | {g: t.shape for t, (_, g) in zip(terms, names) if g}
    src = emit_effect_source(terms, values)
    for seam in ("p[P.k2]", "x[X.delta2]", "p[P.d_ep]", "bus[B.qh1 + i]", "bus[B.va_demand]", "bus[B.z0dd]",
                 "dx[X.ddelta3]", "p[P.beta_h]", "x[X.hq1 + i]", "p[P.C_ep]"):
        assert seam in src, seam
    assert "P_K" not in src and "po +" not in src
    f = tmp_path / "damage.py"
    f.write_text(src)
    cls = resolve_effect(str(f))
    assert cls.__name__ == "DiscoveredSection2StiffnessEventPlus"
    assert cls.fit_range("g_k2_step_t").lower < 20.0 < cls.fit_range("g_k2_step_t").upper
    assert "lost 20 % of its stiffness at t = 20 s" in describe_term(terms[0], -0.2, 20.0, 1.0)


CASES = {
    "event": ("Section2StiffnessEvent", {"loss_k2": 0.25, "t_event": 4.0}, "k2_step_t",
              ("section 2 lost", "of its stiffness at t = ")),
    "crack": ("Section2BreathingCrack", {"open_loss": 0.25}, "k2_pos_delta2",
              ("a breathing crack in section 2 that opens for δ2 > 0",)),
    "polarity": ("PatchWeakNegative", {"neg_loss": 0.3}, "d_ep_neg_va",
                 ("all three patches' authority d_ep is", "lower for negative drive")),
}


@pytest.mark.slow
@pytest.mark.parametrize("case", sorted(CASES))
def test_discover_names_damage_written_outside_it_and_its_file_refits(case, tmp_path):
    """A 6 s sweep whose truth is damage written outside the dictionary (hard switches): discover names the damage
    form, the relative change within 3 points and the instant within 20 ms, and the emitted file refits with
    `shm fit --add` to the noise floor."""
    import json

    from shm_cli.main import main
    from workbench.records import write_record

    cls, values, key, words = CASES[case]
    rec, d, found = discover_one_damage(cls, values, key, words, duration_s=6.0, seed=11)
    truth = -next(v for k, v in values.items() if k != "t_event")
    assert found.coef == pytest.approx(truth, abs=0.03)
    if "t_event" in values:
        assert found.shape == pytest.approx(values["t_event"], abs=0.02)
    path, emitted = tmp_path / "rec.csv", tmp_path / "damage_found.py"
    write_record(rec, path)
    emitted.write_text(d.effect_source(effect_name="damage_found") or "")
    assert main(["fit", str(path), "--params", "table2", "--add", str(emitted), "--save", str(tmp_path / "r.toml"),
                 "--out", str(tmp_path / "fit"), "--json"]) == 0
    fit = json.loads((tmp_path / "fit" / "fit.json").read_text())
    assert fit["held_rms_sigma"]["after"] <= 1.5
