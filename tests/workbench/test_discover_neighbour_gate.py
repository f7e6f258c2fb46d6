"""A crack opened by another section's bending (issue 26 point 3, ``workbench/discover/_neighbour_gate.py`` and the
dictionary's ``other_delta`` / ``kink`` gates): a section's stiffness switched by the sign of a neighbour's deflection
or of the kink across a junction it meets is a member of the dictionary — a step of k·δ, not the bilinear spring of
its own deflection — said in words that name both sections, and refitted beside a best switched by another bending
signal. Measured on the fifth blind set's sweep: the tip crack opened by δ2 > 0 went 26.5 → 1.00 σ, the mid crack
opened by δ2 − δ1 > 0 from 7.3 σ (kept as its own breathing crack) to 1.78 σ."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np

from workbench.discover import build_dictionary
from workbench.discover._dictionary import SIGNALS
from workbench.discover._effect_writer import parameter_names_for
from workbench.discover._gate_words import describe_damage
from workbench.discover._gates import GATES, HINGE_CODE, class_stem, damage_formula, gate_code, is_hinge
from workbench.discover._neighbour_gate import ABOVE_SIGMA, MAX_NEIGHBOURS, neighbour_candidates, neighbour_rows
from workbench.discover._results import ScreenRow

SCALES = {f"{s}{i}": v for s, v in (("z", 1e-3), ("zd", 0.1), ("delta", 1e-3), ("ddelta", 0.1))
          for i in (1, 2, 3)} | {"kink12": 5e-4, "kink23": 5e-4, "vc": 300.0, "va": 300.0, "t": 20.0}


def _key(terms, key: str) -> int:
    return next(k for k, t in enumerate(terms) if t.key == key)


def test_each_section_meets_its_neighbours_and_its_junctions():
    keys = {t.key for t in build_dictionary(SCALES)}
    for k in ("k3_pos_delta2", "k3_neg_delta1", "k1_pos_delta3", "k2_pos_kink12", "k2_neg_kink23", "k1_pos_kink12",
              "k3_neg_kink23"):
        assert k in keys, k
    assert "k1_pos_kink23" not in keys and "k3_pos_kink12" not in keys  # a junction the section does not meet
    assert "c2_pos_delta1" not in keys  # only the stiffness: a crack
    assert not any("kink" in t.key for t in build_dictionary({**SCALES, "kink12": 0.0, "kink23": 0.0}))  # unmoved


def test_a_neighbours_switch_is_a_step_of_the_sections_force_not_a_hinge():
    assert is_hinge("k", "on_pos", "delta2", 1) and not is_hinge("k", "on_pos", "delta2", 2)
    assert gate_code("on_pos", "k", "delta2", 2) == GATES["on_pos"].code
    assert gate_code("on_pos", "k", "delta2", 1) == HINGE_CODE["on_pos"]
    assert damage_formula("k", 2, "on_pos", "delta2", "c", "g") == "S_3 += −c · k3 · δ3   with c = c · [delta2 > g]"
    assert "(delta2 − delta1) > g" in damage_formula("k", 1, "on_pos", "kink12", "c", "g")
    assert class_stem("k", 2, "on_pos", "delta2") == "Section3StiffnessBend2Positive"
    assert class_stem("k", 1, "on_neg", "kink12") == "Section2StiffnessKinkNegative"
    assert class_stem("k", 1, "on_neg", "delta2") == "Section2StiffnessNegative"  # its own: the bilinear spring
    assert SIGNALS["kink12"].code == "(x[X_DELTA + 1] - x[X_DELTA + 0])" and SIGNALS["kink23"].unit == "m"


def test_the_words_name_the_cracked_section_and_what_opens_it():
    words = describe_damage("k", 2, "on_pos", "delta2", -0.1, 0.0)
    assert words.startswith("a crack in section 3 opened by the bending of section 2: stiffness k3 lower by 10 %")
    assert "while δ2 > 0" in words and "bilinear" not in words
    kink = describe_damage("k", 1, "on_pos", "kink12", -0.25, 0.0)
    assert "section 2 opened by the kink across its junction with section 1" in kink and "δ2 − δ1 > 0" in kink
    assert "junction with section 3" in describe_damage("k", 1, "on_neg", "kink23", -0.25, 0.0)
    assert describe_damage("k", 2, "on_pos", "delta2", 0.1, 0.0).startswith("section 3 is stiffer by 10 %")


def _rows(terms, keys):
    return [ScreenRow(terms[_key(terms, k)], -0.2, 10.0 + i, 10.0 + i) for i, k in enumerate(keys)]


def test_the_candidates_are_the_same_section_switched_by_another_bending_signal_in_the_screens_order():
    terms = build_dictionary(SCALES)
    best = _key(terms, "k2_pos_delta2")
    rows = _rows(terms, ["k2_pos_delta2", "k2_neg_kink23", "m2_lin_z2", "k2_pos_kink12"])
    got = [terms[k].key for k in neighbour_candidates(terms, rows, best, set())]
    assert got[:2] == ["k2_neg_kink23", "k2_pos_kink12"]  # screened first, either side
    assert set(got) == {"k2_pos_delta1", "k2_neg_delta1", "k2_pos_delta3", "k2_neg_delta3", "k2_pos_kink12",
                        "k2_neg_kink12", "k2_pos_kink23", "k2_neg_kink23", "k2_pos_z3",
                        "k2_neg_z3"}
    assert "k2_pos_kink12" not in {terms[k].key for k in neighbour_candidates(terms, rows, best, {"k2_pos_kink12"})}
    assert neighbour_candidates(terms, rows, _key(terms, "c2_pos_delta2"), set()) == []  # a damping: no crack
    assert neighbour_candidates(terms, rows, _key(terms, "k2_pos_ddelta2"), set()) == []  # a rate: no bending


def _best(terms, key: str, held: float, coef: float = -0.25):
    names = parameter_names_for(terms)
    k = _key(terms, key)
    outcome = SimpleNamespace(values={names[k][0]: coef}, held_rms_sigma=held)
    return SimpleNamespace(terms=terms, names=names), SimpleNamespace(index=k, held_rms_sigma=held, outcome=outcome)


def test_the_rows_start_at_the_bests_size_switching_at_zero_and_only_above_the_noise():
    terms = build_dictionary(SCALES)
    setup, best = _best(terms, "k2_pos_delta2", 7.3)
    rows = neighbour_rows(setup, best, _rows(terms, ["k2_pos_kink12"]), set())
    assert len(rows) == MAX_NEIGHBOURS and rows[0].term.key == "k2_pos_kink12"
    assert all(r.coef == -0.25 and r.shape == 0.0 and r.placed and math.isinf(r.held_rms_sigma) for r in rows)
    setup, best = _best(terms, "k2_pos_delta2", ABOVE_SIGMA)
    assert neighbour_rows(setup, best, [], set()) == []
    setup, best = _best(terms, "k2_pos_delta2", 7.3, coef=0.0)
    assert neighbour_rows(setup, best, [], set()) == []


def test_the_kink_is_what_the_records_scales_say():
    from board_config import load_parameter_set
    from workbench.discover import signal_scales
    from workbench.fit import model_factory, prepare_targets
    from workbench.simulation import synth_record, synth_test, truth_model

    rec = synth_record(synth_test("mbit-b", duration_s=1.0), truth_model("table2"), noise={"z3": 2e-6}, seed=1)
    targets = prepare_targets([rec], model_factory(load_parameter_set("table2"), []), holdout="blocks", n_blocks=4,
                              max_rate_Hz=250.0)
    scales, sig = signal_scales(targets)
    for a, b, kink in ((1, 2, "kink12"), (2, 3, "kink23")):
        assert np.allclose(sig[kink][0], sig[f"delta{b}"][0] - sig[f"delta{a}"][0])
        assert scales[kink] > 0.0


def test_a_neighbours_switch_leads_only_near_the_noise():
    from workbench.discover._neighbour_gate import LEAD_SIGMA, is_neighbour, neighbour_may_lead

    terms = build_dictionary(SCALES)
    kink, own, tip = (terms[_key(terms, k)] for k in ("k2_pos_kink12", "k2_pos_delta2", "k2_pos_z3"))
    assert is_neighbour(kink) and is_neighbour(terms[_key(terms, "k3_pos_delta2")])
    assert not is_neighbour(own) and not is_neighbour(tip)
    assert neighbour_may_lead(kink, LEAD_SIGMA) and not neighbour_may_lead(kink, 4.7)  # a stand-in for two effects
    assert neighbour_may_lead(own, 4.7) and neighbour_may_lead(tip, 40.0)  # the other families as before
