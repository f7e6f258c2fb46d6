"""A kept switch that began during the record (issue 26, ``_since_onset.py``): blind set 7's tip patch weak for
v_c3 > 0 from 6 s of a 15 s sweep (an electrode finger that cracks mid-test) was kept as patch 3 weak on that side all
along and left 21.9 σ. Here: the dictionary's instant parameter (the term unchanged until it is placed), its code,
words and formula, and the step's rule with the probes and refits faked — what it probes, what it frees, when it runs
and that the instant is taken only when it fits clearly better."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from term_swap_fakes import fake_refits

import workbench.discover._since_onset as so
from workbench.discover import build_dictionary, dictionary_source
from workbench.discover._dictionary import Term
from workbench.discover._dictionary_code import TermSlot, dictionary_since_names, hook_bodies, since_name
from workbench.discover._effect_writer import describe_term, emit_effect_source, formula, parameter_names_for
from workbench.discover._gates import SINCE_NEVER_S, SINCE_PARAMS, TIME_GATES, since_factor
from workbench.discover._rounds import SearchProgress

SCALES = {**{f"{s}{j}": 1e-3 for s in ("z", "zd", "delta", "ddelta") for j in (1, 2, 3)}, "vc": 300.0,
          "va": 400.0, "ic": 1e-3, "one": 1.0, "t": 15.0}
WEAK3 = Term("damage", 2, "vc", "on_pos", 0.0, "d_ep_i", (-240.0, 240.0))


def test_every_switched_damage_term_of_the_damage_parameters_carries_an_instant_that_starts_before_any_record():
    terms = build_dictionary(SCALES)
    since = dictionary_since_names(terms)
    assert since and all(terms[k].placement == "damage" and terms[k].param in SINCE_PARAMS
                         and terms[k].form not in TIME_GATES for k in since)
    assert any(terms[k].param == "k" and terms[k].form == "on_pos" for k in since)  # a crack from an instant
    assert any(terms[k].param == "d_ep_i" and terms[k].signal == "vc" for k in since)  # a polarity from an instant
    assert any(terms[k].form == "on_gap" and terms[k].signal == "vc" for k in since)  # high field, from an instant
    assert not any(t.form in TIME_GATES or t.param == "alpha_h" for k, t in enumerate(terms) if k in since)
    src = dictionary_source(terms)
    assert src.count("Parameter('s_") == len(since) and f"{SINCE_NEVER_S!r}" in src
    # from its default the factor is exactly 1: the dictionary's terms are unchanged until an instant is placed
    assert eval(since_factor(repr(SINCE_NEVER_S)), {"math": math, "t": 0.0}) == 1.0


def test_the_instant_multiplies_the_switched_term_in_the_dictionary_and_as_a_literal_in_the_emitted_file():
    free = hook_bodies([TermSlot(WEAK3, 0, 1, None, None, 2)])["rates"]
    assert any("math.tanh((t - p[po + 2]) / 0.001)" in ln for ln in free)
    placed = Term("damage", 2, "vc", "on_pos", 0.0, "d_ep_i", (-240.0, 240.0), since=6.0125)
    src = emit_effect_source([placed], {"c_d_ep3_pos_vc": -0.3, "g_d_ep3_pos_vc": 0.0})
    assert "math.tanh((t - 6.0125) / 0.001)" in src
    assert "from t = 6.013 s on" in formula(placed, "c", "g")
    whole = emit_effect_source([WEAK3], {"c_d_ep3_pos_vc": -0.3})
    assert "(t - " not in whole  # a change that held all along: its file as before


def test_the_words_say_the_instant_the_switched_change_began():
    placed = Term("damage", 2, "vc", "on_pos", 0.0, "d_ep_i", (-240.0, 240.0), since=6.0125)
    words = describe_term(placed, -0.3, 0.0, 300.0, None, 0.004)
    assert words.startswith(describe_term(WEAK3, -0.3, 0.0, 300.0)) and "from t = 6.013 ± 0.004 s on" in words
    crack = Term("damage", 2, "delta3", "on_pos", 0.0, "k", (-1e-3, 1e-3), since=4.0)
    assert "a crack that appeared during the record" in describe_term(crack, -0.2, 0.0, 1e-3)


def test_the_grid_scales_the_coefficient_by_the_share_of_the_record_it_misses():
    grid = so.probe_grid(-0.1, 20.0)
    assert len(grid) == 2 * len(so.SINCE_AT)
    assert grid[0] == pytest.approx((1.0, -0.1 / 0.95)) and grid[1] == pytest.approx((1.0, -0.1 / math.sqrt(0.95)))
    assert grid[-2] == pytest.approx((19.0, -2.0))  # at 95 % of the record the change is twenty times its mean


def test_the_best_instants_are_apart_by_more_than_a_grid_step_and_skip_failed_probes():
    grid = [(1.0, 1.0), (2.0, 1.0), (3.0, 1.0), (4.0, 1.0)]
    assert so.best_instants(grid, np.array([np.inf, 1.0, 1.1, 2.0]), 1.0) == [(2.0, 1.0), (4.0, 1.0)]
    assert so.best_instants(grid, np.full(4, np.inf), 1.0) == []


def _case(held: float, kept: list[int]) -> tuple[SimpleNamespace, SearchProgress]:
    terms = [WEAK3, Term("measurement", -1, "one", "lin")]
    setup = SimpleNamespace(terms=terms, names=[("a_00", "g_00"), ("a_01", None)], targets=[], models=[],
                            held_before=300.0, n_held=1875, scales={"t": 15.0})
    state = SimpleNamespace(values={"a_00": -0.12, "g_00": 0.0, since_name(0): SINCE_NEVER_S, "a_01": 1e-6},
                            kept=kept)
    progress = SearchProgress(state=state, current_held=held, current_train=held, twins={0: ["x"]},
                              timings={"refit_s": 0.0}, n_sims=0)
    return setup, progress


def _fake(monkeypatch, refit_held: float, seen: dict) -> None:
    def whole_scores(targets, models, values, settings, threads):
        seen["probed"] = list(settings)
        return np.abs(np.array([s[since_name(0)] for s in settings]) - 6.0) + 2.0

    monkeypatch.setattr(so, "whole_scores", whole_scores)
    fake_refits(monkeypatch, seen, refit_held, {"a_00": -0.3, "g_00": 1.0, since_name(0): 6.01, "a_01": 1e-6})


@pytest.mark.parametrize(("refit_held", "taken"), [(1.1, True), (21.0, False)])
def test_a_kept_switch_begins_at_an_instant_only_when_it_fits_clearly_better(monkeypatch, refit_held, taken):
    setup, progress = _case(21.9, [0, 1])
    seen: dict = {}
    _fake(monkeypatch, refit_held, seen)
    said: list[str] = []
    so.since_step(setup, progress, SimpleNamespace(say=said.append, threads=1, max_nfev=12))
    assert len(seen["probed"]) == 2 * len(so.SINCE_AT) and all(set(s) == {"a_00", since_name(0)}
                                                                for s in seen["probed"])
    # the best two, a step apart; once taken, the set refitted at the instant placed on the whole record
    assert [s[since_name(0)] for s in seen["start"]] == pytest.approx([6.0, 4.5] + ([6.001] if taken else []))
    assert seen["start"][0]["a_00"] == pytest.approx(-0.12 / 0.6)  # scaled by the share of the record it misses
    free = seen["free"][0]
    assert set(free) == {"a_00", "g_00", "a_01", since_name(0)}  # every kept coefficient, its shape, its instant
    assert free[since_name(0)] == pytest.approx((5.25, 6.75))
    assert progress.rounds[-1]["since_instant"]["taken"] is taken and "begun at t = 6.01 s" in said[-1]
    if taken:
        assert progress.current_held == 1.1 and progress.state.values[since_name(0)] == 6.001
        assert 0 not in progress.twins
    else:
        assert progress.current_held == 21.9 and progress.state.values[since_name(0)] == SINCE_NEVER_S
        assert progress.twins == {0: ["x"]}


@pytest.mark.parametrize(("held", "kept", "since"), [(2.9, [0], SINCE_NEVER_S), (21.9, [1], SINCE_NEVER_S),
                                                     (21.9, [0], 6.0)])
def test_no_instant_near_the_noise_for_a_term_without_one_or_one_already_placed(monkeypatch, held, kept, since):
    setup, progress = _case(held, kept)
    progress.state.values[since_name(0)] = since
    monkeypatch.setattr(so, "whole_scores", lambda *a: pytest.fail("probed"))
    so.since_step(setup, progress, SimpleNamespace(say=lambda _m: None, threads=1, max_nfev=12))
    assert progress.current_held == held and not progress.rounds


def test_an_emitted_crack_from_an_instant_simulates_the_crack_written_by_hand(tmp_path):
    """The emitted file against the same damage written from the plant's seam: from 0.7 s of a 1.5 s sweep, section 2
    loses 25 % of its stiffness while δ2 > 0 (a crack that appears, then breathes)."""
    from emitted_effect_support import emitted_against_hand

    from board_config.parameter import Parameter
    from plant import PhysicalEffect

    class HandCrackFrom(PhysicalEffect):
        name = "hand_crack_from_instant"
        description = "k2 lower by loss while δ2 > 0, from 0.7 s on"
        parameters = (Parameter("loss", "1", 0.0, 0.0, 0.9, "loss", neutral=0.0),)

        @staticmethod
        def rates(t, x, p, bus, dx, X, P, B):
            step = 0.5 * (1.0 + math.tanh((t - 0.7) / 1e-3))
            opened = 0.5 * (1.0 + math.tanh(x[X.delta2] / 1e-7))
            bus[B.s2] += p[P.loss] * step * opened * p[P.k2] * x[X.delta2]

    term = Term("damage", 1, "delta2", "on_pos", 0.0, "k", (-1e-3, 1e-3), since=0.7)
    (c, g), = parameter_names_for([term])
    moved, apart = emitted_against_hand(tmp_path, term, {c: -0.25, g: 0.0}, HandCrackFrom, {"loss": 0.25})
    assert moved > 1e-7 and apart <= 1e-3 * moved
