"""An event that acts on one side of the motion or the drive (issue 26, ``_event_side.py``): blind set 7's tip patch
weak for v_c3 > 0 from 6 s of a 15 s sweep was kept as "authority d_ep of patch 3 dropped by 26.1 % at t = 6.13 s"
(15 σ held out). Here the step's rule with the probes and refits faked: its candidates, what they are probed and
refitted with, when it runs, and that the step gives way only to a switch that fits clearly better."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from term_swap_fakes import fake_refits

import workbench.discover._event_side as es
from workbench.discover._dictionary import Term
from workbench.discover._dictionary_code import since_name
from workbench.discover._gates import SINCE_NEVER_S
from workbench.discover._rounds import SearchProgress

TERMS = [Term("damage", 2, "one", "on_step", 5.6, "d_ep_i", (3.75, 7.5)),
         Term("damage", 2, "vc", "on_pos", 0.0, "d_ep_i", (-240.0, 240.0)),
         Term("damage", 2, "vc", "on_neg", 0.0, "d_ep_i", (-240.0, 240.0)),
         Term("damage", 1, "vc", "on_pos", 0.0, "d_ep_i", (-240.0, 240.0)),  # another patch
         Term("damage", 2, "vc", "on_pos", 0.0, "alpha_h", (-240.0, 240.0))]  # another parameter


def _case(held: float, kept: list[int]) -> tuple[SimpleNamespace, SearchProgress]:
    names = [("a_00", "g_00"), ("a_01", "g_01"), ("a_02", "g_02"), ("a_03", "g_03"), ("a_04", "g_04")]
    setup = SimpleNamespace(terms=TERMS, names=names, targets=[], models=[], held_before=64.0, n_held=1875,
                            scales={"t": 15.0, "vc": 300.0})
    values = {"a_00": -0.26, "g_00": 6.13, "a_01": 0.0, "g_01": 0.0, "a_02": 0.0, "g_02": 0.0, "a_03": 0.04,
              "g_03": 0.0}
    values |= {since_name(k): SINCE_NEVER_S for k in (1, 2, 3)}
    progress = SearchProgress(state=SimpleNamespace(values=values, kept=kept), current_held=held,
                              current_train=held, twins={0: ["x"]}, timings={"refit_s": 0.0}, n_sims=0)
    return setup, progress


def test_the_candidates_are_the_switched_terms_of_the_steps_parameter_and_place():
    assert es.side_candidates(TERMS, TERMS[0]) == [1, 2]


def _fake(monkeypatch, refit_held: float, seen: dict) -> None:
    def whole_scores(targets, models, values, settings, threads):
        seen["first"] = (list(settings), dict(values))
        # patch 3 weak on the positive side, from 0.1 s before the step's instant
        return [9.0 - (abs(s.get(since_name(1), 0.0) - 6.03) < 1e-9) if "a_01" in s else 30.0 for s in settings]

    def best_shapes(setup, progress, settings, cands, coef, base):
        seen.setdefault("shapes", []).append((list(cands), coef, base[since_name(cands[0])]))
        j = cands[0]
        return {j: (8.0 if j == 1 else 12.0, (j, -0.5, 2.0))}

    monkeypatch.setattr(es, "whole_scores", whole_scores)
    monkeypatch.setattr(es, "best_shapes", best_shapes)
    fake_refits(monkeypatch, seen, refit_held, {"a_01": -0.3, "g_01": 1.5, since_name(1): 6.01})


@pytest.mark.parametrize(("refit_held", "taken"), [(1.2, True), (14.5, False)])
def test_a_kept_step_becomes_a_switch_begun_at_its_instant_only_when_it_fits_clearly_better(monkeypatch,
                                                                                         refit_held, taken):
    setup, progress = _case(15.0, [0, 3])  # a term kept beside the step, making up for what it missed
    seen: dict = {}
    _fake(monkeypatch, refit_held, seen)
    said: list[str] = []
    es.side_step(setup, progress, SimpleNamespace(say=said.append, threads=1, max_nfev=12))
    probes, base = seen["first"]
    assert base["a_00"] == 0.0 and base["a_03"] == 0.0  # probed alone: the step off, and what made up for it
    assert len(probes) == 2 * len(es.SIDE_SIZES) * len(es.SIDE_BEFORE_S)
    assert {round(p[since_name(1)], 6) for p in probes if since_name(1) in p} == {6.13, 6.03, 5.93, 5.83}
    assert {round(p["a_01"], 6) for p in probes if "a_01" in p} == {-0.26, -0.364, -0.52}
    # each switch over its shapes from its best probe's instant, the better first
    assert seen["shapes"] == [([1], pytest.approx(-0.39), pytest.approx(6.03)),
                              ([2], pytest.approx(-0.39), pytest.approx(6.13))]
    assert len(seen["start"]) == (3 if taken else 2)  # once taken, the set refitted at the placed instant
    assert set(seen["free"][0]) == {"a_01", "g_01", since_name(1), "a_03"}
    assert seen["free"][0][since_name(1)] == pytest.approx((5.88, 6.18))
    start = seen["start"][0]
    assert start["a_00"] == 0.0 and start["a_01"] == -0.5 and start["g_01"] == 2.0 and start["a_03"] == 0.04
    assert start[since_name(1)] == pytest.approx(6.03) and start[since_name(2)] == SINCE_NEVER_S
    assert progress.rounds[-1]["event_side"]["taken"] is taken and "on one side from its instant" in said[-1]
    if taken:
        assert progress.state.kept == [1, 3] and progress.current_held == 1.2
        assert progress.state.values[since_name(1)] == 6.001 and 0 not in progress.twins
    else:
        assert progress.state.kept == [0, 3] and progress.current_held == 15.0 and progress.twins == {0: ["x"]}


@pytest.mark.parametrize(("held", "kept"), [(2.5, [0]), (15.0, [1])])
def test_no_side_near_the_noise_or_for_a_kept_switch(monkeypatch, held, kept):
    setup, progress = _case(held, kept)
    progress.state.values["a_01"] = -0.3
    monkeypatch.setattr(es, "whole_scores", lambda *a: pytest.fail("probed"))
    es.side_step(setup, progress, SimpleNamespace(say=lambda _m: None, threads=1, max_nfev=12))
    assert not progress.rounds


def test_the_best_candidates_skip_those_that_never_integrate_and_keep_their_best_instant():
    probes = [{since_name(j): t} for j in (4, 7, 9) for t in (5.0, 6.0)]
    scores = np.array([3.0, 5.0, np.inf, np.inf, 9.0, 1.0])
    assert es.best_candidates([4, 7, 9], probes, scores, 2) == [(9, 6.0), (4, 5.0)]
