"""Damage that grows over a finite time and then stays (issue 26 point 3): a kept step or ramp given an end — two
ramps of one parameter, +r from t0 and −r from t1 — and the pair said as one change. The end-to-end case (a root
losing 20 % of k1 linearly over 5 s of a 10 s sweep, then holding, through ``shm diagnose``) is
``test_unseen_damage.py``'s heavy ``ramp_loss_root``; the loss over half a second is ``ramp_loss_root_fast``."""

from __future__ import annotations

import pytest

from workbench.discover._dictionary import Term, build_dictionary
from workbench.discover._finite_change import (
    Window,
    WindowProbe,
    candidate_windows,
    finite_changes,
    ramp_slots,
    window_setting,
    zoom_window,
)
from workbench.discover._results import FoundTerm, in_one_sentence


def _ramp(param: str, index: int, coef: float, t0: float, se: float | None = 0.02) -> FoundTerm:
    term = Term("damage", index, "one", "on_ramp", t0, param, (0.0, 5.0))
    return FoundTerm(term, coef, t0, 1.0, f"a ramp of {param}", [], se)


def test_a_rise_and_its_end_are_said_as_one_loss_that_held():
    found = [_ramp("k", 0, -0.04, 2.5, 0.021), _ramp("k", 0, 0.0398, 7.5, 0.034)]
    rise, end = finite_changes(found)
    assert rise.words.startswith("section 1 lost 20 % of its stiffness between t = 2.50 ± 0.02 s and "
                                 "t = 7.50 ± 0.03 s")
    assert "then held" in rise.words and "grew over 5 s" in rise.words
    # and where half of it was reached, as precisely as the less precise end (a loss over 6–9 s is one around 7.5 s)
    assert "half of it by t = 5.00 s" in rise.words
    assert end.words == "its end at t = 7.50 ± 0.03 s (a ramp of +3.98 %/s from then on cancels the change's rate)"
    assert (rise.coef, end.coef) == (-0.04, 0.0398)  # the numbers stay the fit's
    # the verdict's sentence says the change once: the end is said with its rise (its words stay in the report)
    assert (rise.said_with, end.said_with) == ("", rise.term.key)
    assert in_one_sentence([rise, end]) == rise.words and "its end" not in in_one_sentence([rise, end])


def test_a_pair_found_end_first_is_said_from_its_start_and_a_rate_left_is_said():
    found = [_ramp("c", 2, -0.7, 6.0, None), _ramp("c", 2, 1.0, 4.0, None)]
    end, rise = finite_changes(found)
    assert rise.words.startswith("damping c3 of section 3 rose by 200 % between t = 4 s and t = 6 s")
    assert "then kept rising by 30 %/s" in rise.words and end.words.endswith("leaves it changing by +30 %/s)")


def test_ramps_of_different_parameters_or_of_one_sign_keep_their_own_words():
    found = [_ramp("k", 0, -0.04, 2.5), _ramp("k", 1, 0.04, 7.5), _ramp("m", 0, 0.01, 1.0), _ramp("m", 0, 0.02, 3.0)]
    assert [f.words for f in finite_changes(found)] == [f.words for f in found]


def test_windows_from_a_step_hold_its_instant_and_those_from_a_ramp_end_inside_the_record():
    steps = candidate_windows("on_step", -0.2, 5.0, 10.0)
    assert steps and all(w.total == -0.2 and w.start <= 5.0 <= w.end for w in steps)
    centred = [w for w in steps if abs(w.start + w.end - 10.0) < 1e-9]
    assert len(centred) >= 5 and any(w.end - w.start < 0.1 for w in centred)
    # a slow loss is noticed at its first visible instant: windows that start there, reaching a third of the record
    assert any(w.start == 5.0 and w.end - w.start >= 3.0 for w in steps)
    assert any(w.end == 5.0 and w.end - w.start >= 3.0 for w in steps)
    assert len(set(steps)) == len(steps)
    ramps = candidate_windows("on_ramp", -0.0342, 2.04, 10.0)
    assert all(2.04 <= w.start < w.end < 10.0 and w.rate <= -0.0342 + 1e-12 for w in ramps)
    assert any(abs(w.start - 2.04) < 1e-9 and 7.0 < w.end < 8.0 for w in ramps)  # reaches a loss that ends at 7.5 s
    near_edge = candidate_windows("on_step", 0.3, 0.01, 10.0)
    assert all(w.start >= 0.0 for w in near_edge)


def test_the_window_is_the_two_dictionary_ramps_of_the_kept_parameter():
    terms = build_dictionary({"delta1": 1e-3, "ddelta1": 0.1, "t": 10.0})
    step = next(t for t in terms if t.key == "k1_step_t")
    slots = ramp_slots(terms, step)
    assert len(slots) >= 2 and all(terms[k].key == "k1_ramp_t" for k in slots)
    ramp = terms[slots[1]]
    assert ramp_slots(terms, ramp)[0] == slots[1]  # a kept ramp is the window's rise
    w = Window(2.5, 7.5, -0.2)
    assert window_setting(w, ("a_01", "g_01"), ("a_02", "g_02")) == pytest.approx(
        {"a_01": -0.04, "g_01": 2.5, "a_02": 0.04, "g_02": 7.5})


class _Bowl(WindowProbe):
    """A probe whose whole-record RMS is the distance to a true window (s, and its total in tenths)."""

    def scores(self, windows):
        return [1.0 + abs(w.start - 5.5) + abs(w.end - 6.0) + 10 * abs(w.total + 0.25) for w in windows]


def test_the_zoom_places_a_short_loss_from_the_step_it_replaces_to_the_resolution():
    probe = _Bowl([], [], {}, ("a_1", "g_1"), ("a_2", "g_2"), 10.0, None)
    window, score, n = zoom_window(probe, candidate_windows("on_step", -0.2, 5.62, 10.0))
    assert abs(window.start - 5.5) < 0.01 and abs(window.end - 6.0) < 0.01 and abs(window.total + 0.25) < 0.01
    assert score < 1.1 and n < 300


def test_the_pairs_onsets_are_refitted_near_where_the_whole_record_placed_them():
    from workbench.discover._effect_writer import emit_effect_source, parameter_names_for

    found = finite_changes([_ramp("k", 1, -0.64, 5.553), _ramp("k", 1, 0.64, 5.944)])
    assert [f.term.shape_range for f in found] == [pytest.approx((5.533, 5.573)), pytest.approx((5.924, 5.964))]
    values = {}
    for f, (c, g) in zip(found, parameter_names_for([f.term for f in found])):
        values |= {c: f.coef, g: f.shape}
    src = emit_effect_source([f.term for f in found], values)
    assert "fit=FitRange(5.543, 5.563)" in src and "fit=FitRange(5.934, 5.954)" in src
