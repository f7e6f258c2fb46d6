"""A damage event whose change took time (issue 26 point 3): the dictionary's steps carry a fitted edge width, a
kept step or ramp is also tried as one step with a fitted edge (an S-curve), said and emitted with it."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from board_config.parameter import Parameter
from workbench.discover._dictionary import Term, build_dictionary
from workbench.discover._dictionary_code import dictionary_source, dictionary_width_names
from workbench.discover._effect_writer import describe_term, emit_effect_source, parameter_names_for
from workbench.discover._finite_change import WindowFit, keep_window
from workbench.discover._gates import RAMP_NEVER_S, STEP_WIDTH_S
from workbench.discover._search import SearchState
from workbench.discover._smooth_change import Edge, EdgeProbe, candidate_edges, edge_free, zoom_edge

SCALES = {"delta1": 1e-3, "ddelta1": 0.1, "delta2": 1e-3, "ddelta2": 0.1, "t": 15.0}


def test_every_step_ramp_and_switch_of_the_dictionary_carries_its_width_at_its_sharp_default():
    from workbench.discover._dictionary import SIGNALS
    from workbench.discover._gates import SIGN_WIDTH

    terms = build_dictionary(SCALES)
    widths = dictionary_width_names(terms)
    forms = ("on_step", "on_ramp", "on_pos", "on_neg")
    assert widths and all(terms[k].form in forms for k in widths)
    assert len(widths) == sum(t.form in forms for t in terms)
    src = dictionary_source(terms)
    declared = dict(re.findall(r"Parameter\('(h_\d+)', '[^']+', ([0-9.e+-]+),", src))
    assert set(declared) == set(widths.values())
    for k, h in widths.items():
        form, unit = terms[k].form, SIGNALS[terms[k].signal].unit
        want = {"on_step": STEP_WIDTH_S, "on_ramp": RAMP_NEVER_S}.get(form) or SIGN_WIDTH[unit]
        assert float(declared[h]) == want, terms[k].key
        assert terms[k].width == 0.0
    # the step's edge, the ramp's saturation and a switch's edge are parameters of the kernel, not literals
    assert re.search(r"math\.tanh\(\(t - p\[po \+ \d+\]\) / p\[po \+ \d+\]\)", src)
    assert re.search(r"-p\[po \+ \d+\] \* math\.expm1\(-max\(t - p\[po \+ \d+\], 0\.0\) / p\[po \+ \d+\]\)", src)
    assert re.search(r"math\.tanh\(\(\(x\[X_DELTA \+ 1\]\) - p\[po \+ \d+\]\) / p\[po \+ \d+\]\)", src)


def test_a_ramp_that_never_settles_is_the_plain_ramp_to_a_part_in_a_billion():
    x = np.linspace(0.0, 20.0, 9)
    settling = -RAMP_NEVER_S * np.expm1(-x / RAMP_NEVER_S)
    assert np.allclose(settling, x, rtol=1e-9, atol=0.0)


def test_a_step_with_a_fitted_edge_is_said_as_an_s_curve_around_its_instant():
    term = Term("damage", 0, "one", "on_step", 8.25, "k", width=0.6)
    words = describe_term(term, -0.297, 8.25, 1.0, 0.004)
    assert words.startswith("section 1 lost 29.7 % of its stiffness around t = 8.250 ± 0.004 s, over 1.32 s")
    assert "10–90 %" in words
    sharp = describe_term(Term("damage", 0, "one", "on_step", 8.25, "k"), -0.297, 8.25, 1.0, 0.004)
    assert "at t = 8.250 ± 0.004 s" in sharp and "over" not in sharp


def test_the_emitted_file_writes_the_fitted_edge_and_says_it_in_the_formula():
    term = Term("damage", 1, "one", "on_step", 5.0, "k", (4.0, 6.0), width=0.35)
    (c, g), = parameter_names_for([term])
    src = emit_effect_source([term], {c: -0.2, g: 5.0})
    assert "/ 0.35)" in src and "(1 + tanh((t − g_k2_step_t) / 0.35 s)) / 2" in src


def test_an_emitted_s_curve_simulates_the_loss_written_by_hand(tmp_path):
    """The emitted file against the same loss written from the plant's seam: k2 lower by 20 % along
    ½(1 + tanh((t − 0.8 s)/0.15 s)) on a 1.5 s sweep."""
    from emitted_effect_support import emitted_against_hand

    from plant import PhysicalEffect

    class HandS(PhysicalEffect):
        name = "hand_s_curve"
        description = "k2 lower by loss along an S-curve"
        parameters = (Parameter("loss", "1", 0.0, 0.0, 0.9, "loss", neutral=0.0),)

        @staticmethod
        def rates(t, x, p, bus, dx, X, P, B):
            bus[B.s2] += p[P.loss] * 0.5 * (1.0 + math.tanh((t - 0.8) / 0.15)) * p[P.k2] * x[X.delta2]

    term = Term("damage", 1, "one", "on_step", 0.8, "k", (0.5, 1.1), width=0.15)
    (c, g), = parameter_names_for([term])
    moved, apart = emitted_against_hand(tmp_path, term, {c: -0.2, g: 0.8}, HandS, {"loss": 0.2})
    assert moved > 1e-7 and apart <= 1e-3 * moved


def test_edges_from_a_step_are_centred_on_it_and_those_from_a_ramp_lie_after_its_onset():
    from_step = candidate_edges("on_step", -0.3, 8.0, 15.0)
    assert {e.centre for e in from_step} == {8.0} and all(e.total == -0.3 for e in from_step)
    assert min(e.width for e in from_step) < 0.05 < 1.0 < max(e.width for e in from_step)
    from_ramp = candidate_edges("on_ramp", -0.02, 5.0, 15.0)
    assert all(5.0 < e.centre < 15.0 for e in from_ramp)
    assert {round(e.total, 6) for e in from_ramp} == {-0.2, -0.1}  # the ramp's rate × the time left, and half


def test_a_settling_ramp_is_said_with_its_total_and_time_constant_and_written_so(tmp_path):
    term = Term("damage", 1, "one", "on_ramp", 4.5, "k", (3.0, 6.0), width=1.8)
    words = describe_term(term, 0.35 / 2 / 1.8, 4.5, 1.0, 0.01)
    assert words.startswith("section 2 regained 17.5 % of its stiffness from t = 4.50 ± 0.01 s on, settling "
                            "exponentially with time constant 1.8 s")
    lost = describe_term(term, -0.1, 4.5, 1.0, 0.01)
    assert "lost 18 % of its stiffness" in lost and "grew and arrested" in lost
    (c, g), = parameter_names_for([term])
    src = emit_effect_source([term], {c: 0.1, g: 4.5})
    assert "(-1.8 * math.expm1(-max(t - p[P.g_k2_ramp_t], 0.0) / 1.8))" in src
    assert "1.8 s · (1 − exp(−(t − g_k2_ramp_t)⁺ / 1.8 s))" in src


def test_edges_that_settle_start_at_the_kept_ramp_or_step_and_a_recovery_takes_either_sign():
    settle = candidate_edges("on_ramp", -0.02, 5.0, 15.0, "settle")
    assert {e.centre for e in settle} == {5.0} and all(e.total < 0 for e in settle)
    assert max(e.width for e in settle) > 5.0 > 1.0 > min(e.width for e in settle)
    recover = candidate_edges("on_step", -0.35, 4.5, 15.0, "recover")
    assert {e.centre for e in recover} == {4.5}
    assert any(e.total > 0 for e in recover) and any(e.total < 0 for e in recover)
    probe = EdgeProbe([], [], {}, ("a_1", "g_1", "h_1"), None, "on_ramp")
    assert probe.setting(Edge(4.5, 2.0, 0.2)) == {"a_1": 0.1, "g_1": 4.5, "h_1": 2.0}  # a ramp's rate: total ÷ τ
    # a recovery of +17.5 % from a step refitted alone at −17.9 %: the step grows to end at that level, at the
    # recovery's onset
    probe = EdgeProbe([], [], {}, ("a_1", "g_1", "h_1"), None, "on_ramp", ("a_0", -0.179, "g_0"))
    assert probe.setting(Edge(4.5, 1.8, 0.175)) == pytest.approx(
        {"a_1": 0.175 / 1.8, "g_1": 4.5, "h_1": 1.8, "a_0": -0.354, "g_0": 4.5})


def test_the_onsets_are_placed_together_on_the_whole_record(monkeypatch):
    import workbench.discover._smooth_change as sc

    def scores(targets, models, values, settings, threads):  # the whole record is best 4 ms earlier
        return [1.0 + 100 * abs(s["g_1"] - 4.496) for s in settings]

    monkeypatch.setattr(sc, "whole_scores", scores)
    probe = EdgeProbe([], [], {}, ("a_1", "g_1", "h_1"), None, "on_ramp")
    values, n = sc.placed_onsets(probe, {"g_1": 4.5, "g_0": 4.49, "a_1": 0.1}, ["g_1", "g_0"])
    assert values["g_1"] == values["g_0"] == pytest.approx(4.496) and values["a_1"] == 0.1
    assert n == 1 + 2 * len(sc.POLISH_OFFSETS_S)


def test_a_recovery_is_a_free_ramp_slot_beside_the_kept_step_which_stays():
    from workbench.discover import dictionary_parameter_names
    from workbench.discover._smooth_change import smooth_refit

    terms = build_dictionary(SCALES)
    names = dictionary_parameter_names(terms)
    k = next(i for i, t in enumerate(terms) if t.key == "k2_step_t")
    assert smooth_refit([], [], terms, names, SearchState({}, [k]), k, 15.0, None, 5, "settle") is None  # a step


class _Bowl(EdgeProbe):
    """A probe whose whole-record RMS is the distance to a true S-curve (centre 8.25 s, width 0.6 s, total −0.3)."""

    def scores(self, edges):
        return [1.0 + abs(e.centre - 8.25) + abs(math.log(e.width / 0.6)) + 10 * abs(e.total + 0.3) for e in edges]


def test_the_zoom_moves_centre_width_and_size_toward_the_best_edge():
    probe = _Bowl([], [], {}, ("a_1", "g_1", "h_1"), None)
    edge, score, n = zoom_edge(probe, candidate_edges("on_step", -0.28, 8.1, 15.0), 15.0)
    assert abs(edge.centre - 8.25) < 0.05 and abs(math.log(edge.width / 0.6)) < 0.15
    assert abs(edge.total + 0.3) < 0.02 and score < 1.3 and n < 300


def test_the_edge_refit_frees_size_centre_and_width_within_the_record():
    from discover_slots import kept_slot

    s = kept_slot(SCALES, "k1_step_t", -0.3, 14.9, 0.5)
    c, g, h, k = s["c"], s["g"], s["h"], s["k"]
    free = {p.name: p for p in edge_free(s["terms"], s["names"], s["state"], dict(s["state"].values), k, k, 15.0)}
    assert set(free) == {c, g, h}
    assert free[g].upper == 15.0 and free[g].lower == pytest.approx(14.4)
    assert free[h].lower == pytest.approx(0.5 / 3) and free[h].upper == pytest.approx(1.5) and free[h].log
    assert free[c].lower >= -0.95


def test_a_smooth_change_is_kept_once_in_place_of_the_term_it_replaces():
    state = SearchState({"a_01": -0.3, "a_05": 0.0}, [3, 7])
    fit = WindowFit(5, 5, 7, _Outcome(), {"a_05": -0.29, "h_05": 0.6, "a_07": 0.0}, 10, kind="smooth")
    keep_window(state, {}, {7: [{"key": "x"}]}, fit)
    assert state.kept == [3, 5] and state.values["h_05"] == 0.6


class _Outcome:
    estimates: tuple = ()


def test_an_edge_is_a_plain_value():
    assert Edge(1.0, 0.2, -0.1) == Edge(1.0, 0.2, -0.1)
