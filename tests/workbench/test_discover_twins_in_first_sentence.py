"""A finding whose place the records leave open says so in the sentence that states it (issue 26 point 1): on a
quasi-static MBIT.a a root crack open for δ1 > 0 was named "a breathing crack in section 2 …" and only the next
sentence said the records could not tell it from section 1's — the verdict's first sentence put the damage in the
wrong section with no doubt attached."""

from __future__ import annotations

import workbench_unseen_damage as unseen

from workbench.challenges.discovery import KINDS, case_record, first_sentence
from workbench.discover import discover
from workbench.discover._dictionary import Term
from workbench.discover._results import FoundTerm, ScreenRow
from workbench.discover._twins import MAX_TWINS, alike, place_first, switch_family
from workbench.simulation import synth_test


def _crack(index: int) -> Term:
    return Term("damage", index, f"delta{index + 1}", "on_pos", 0.0, "k")


def test_the_twins_of_a_finding_are_in_its_first_sentence():
    twin = {"key": "k1_pos_delta1", "placement": "damage", "index": 0, "signal": "delta1", "form": "on_pos",
            "held_rms_sigma": 0.99, "judged_by": "refitted",
            "words": "a breathing crack in section 1 that opens for δ1 > 0: stiffness k1 lower by 25.1 % on that side"}
    found = FoundTerm(_crack(1), -0.2, 0.0, 1e-3,
                      "a breathing crack in section 2 that opens for δ2 > 0: stiffness k2 lower by 20 % on that side",
                      twins=[twin])
    first = first_sentence("Found beyond the library: " + found.description + ". Held-out error 114 σ → 0.98 σ.")
    assert "section 2" in first and "section 1" in first and "cannot tell it from" in first


def _twin(key: str, index: int, held: float) -> dict:
    return {"key": key, "placement": "damage", "index": index, "held_rms_sigma": held}


def test_a_twin_in_another_place_is_named_before_the_twins_of_the_same_place():
    chosen = _crack(0)  # a crack in section 1, named on one mode (MBIT.a)
    same = [_twin("d_ep1_pos_delta1", 0, 1.0), _twin("k1_pos_delta1", 0, 1.01), _twin("k1_neg_z3", 0, 1.01)]
    elsewhere = _twin("k2_pos_z3", 1, 1.02)
    picked = place_first(chosen, [*same, elsewhere])
    assert len(picked) == MAX_TWINS and picked[-1] is elsewhere and picked[0] is same[0]
    # already among the first: the order stays; none elsewhere, or a finding without a place: the first n
    assert place_first(chosen, [same[0], elsewhere, *same[1:]]) == [same[0], elsewhere]
    assert place_first(chosen, same) == same[:MAX_TWINS]
    assert place_first(Term("damage", -1, "va", "on_pos", 0.0, "alpha_h"), [*same, elsewhere]) == same[:MAX_TWINS]
    # a global twin (no place) is not "elsewhere"
    assert place_first(chosen, [*same, _twin("alpha_h_pos_vc", -1, 1.0)]) == same[:MAX_TWINS]


def test_a_finding_without_twins_reads_as_before():
    found = FoundTerm(_crack(1), -0.2, 0.0, 1e-3, "a breathing crack in section 2 that opens for δ2 > 0")
    assert found.description == "a breathing crack in section 2 that opens for δ2 > 0"


# --- the switching family: readings of one signal that a one-way record cannot tell apart -------------------------

def _row(term: Term, held: float) -> ScreenRow:
    return ScreenRow(term, 1.0, held, held)


def test_the_switching_family_is_the_other_switching_terms_of_the_chosen_terms_signal_one_row_per_key():
    chosen = Term("force_section", 0, "delta1", "clip", 1e-3)
    rows = [_row(Term("damage", 0, "delta1", "on_gap", 3e-4, "k"), 27.0),
            _row(Term("force_section", 0, "delta1", "dead", 4e-4), 28.0),
            _row(Term("force_section", 0, "delta1", "dead", 1e-4), 29.0),  # another shape of the same key
            _row(Term("force_section", 0, "delta1", "lin"), 29.5),  # does not switch
            _row(Term("force_section", 1, "delta2", "clip", 1e-3), 29.6),  # another signal
            _row(Term("damage", 0, "delta1", "on_pos", 0.0, "k"), 30.0),
            _row(Term("damage", 0, "delta1", "on_pos_soft", 2e-4, "k"), 30.1)]
    keys = [r.term.key for r in switch_family(chosen, rows, done={"k1_gap_delta1"})]
    assert keys == ["s1_dead_delta1", "k1_pos_delta1", "k1_pos_soft_delta1"]
    # a term that does not switch (or switches in time) has no such family
    assert switch_family(Term("force_section", 0, "delta1", "lin"), rows, set()) == []
    assert switch_family(Term("damage", 0, "one", "on_step", 1.0, "k"), rows, set()) == []


def test_a_crack_on_a_step_that_bends_the_section_one_way_is_named_in_the_first_sentence(tmp_path):
    """An MBIT.b step bends the root one way: a root crack open for δ1 > 0 and a clearance within ±g of δ1 explain
    it alike. The screen ranked the crack fourth of its family and it was never refitted, so the first sentence named
    only the clearance; the family's refit puts the crack in the sentence (as the finding or as its twin)."""
    cls = unseen.UNSEEN["crack_root_positive"][0]
    spec = synth_test("mbit-b", **KINDS.get("mbit-b", {}))
    rec, _ = case_record(spec, cls, unseen.truth_values("crack_root_positive", spec.duration_s), 2e-6, 1)
    d = discover([rec], "table2", max_terms=1)
    first = first_sentence(d.message)
    assert "breathing crack in section 1" in first, first
    assert d.held_after <= 1.5, d.held_after


def test_signals_alike_are_the_same_kind_at_the_same_place():
    assert alike("z2", "delta2") and alike("zd2", "ddelta2") and alike("va", "vc") and alike("delta1", "delta1")
    assert not alike("z2", "delta3") and not alike("z2", "zd2") and not alike("delta1", "va")
    assert not alike("one", "delta1")


def test_a_force_switched_by_a_mass_displacement_has_the_sections_switches_of_that_place_in_its_family():
    chosen = Term("force_mass", 1, "z2", "pos", 9e-4)
    rows = [_row(Term("force_mass", 2, "z3", "pos", 1e-3), 12.0),
            _row(Term("damage", 1, "delta2", "on_pos", 0.0, "k"), 40.0),
            _row(Term("damage", 2, "delta3", "on_pos", 0.0, "k"), 41.0)]
    assert [r.term.key for r in switch_family(chosen, rows, set())] == ["k2_pos_delta2"]


def test_the_twin_in_another_place_is_the_same_damage_there_when_the_records_allow_it():
    """Sections 1 and 2 each losing 7 % at once on MBIT.a (one mode) were said "section 1 lost 13.1 % … — these
    records cannot tell it from authority d_ep of patch 2 rose …; or from authority d_ep of patch 1 rose …": the
    twin elsewhere was another parameter's while section 2's own loss was a twin too."""
    chosen = Term("damage", 0, "one", "on_step", 9.0, "k")
    patch2 = _twin("d_ep2_step_t", 1, 0.98) | {"param": "d_ep_i"}
    patch1 = _twin("d_ep1_step_t", 0, 0.98) | {"param": "d_ep_i"}
    section2 = _twin("k2_step_t", 1, 0.99) | {"param": "k"}
    assert place_first(chosen, [patch2, patch1, section2]) == [patch2, section2]
    assert place_first(chosen, [patch2, patch1]) == [patch2, patch1]  # none of its own parameter: as before
