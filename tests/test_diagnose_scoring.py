"""The diagnosis' scoring and verdict rules without a fit (docs/workbench.md): the ranking puts accepted candidates
first, best held-out ΔBIC first, unstable or unfitted last; the winner is the best accepted candidate, except that
a re-estimation explaining the held-out data within ``PREFER_PARAMETER_WITHIN`` of the best effect wins (no new
physics needed); ``found`` lists the blamed names in the order forward selection found them."""

from __future__ import annotations

from dataclasses import dataclass

import pytest

from workbench.candidate_fit import PREFER_PARAMETER_WITHIN
from workbench.diagnose import Diagnosis, _rank_key, choose_winner


@dataclass
class Cand:
    """What the scoring reads of a fitted candidate (stands in for ``CandidateResult``)."""

    effect: str
    kind: str = "effect"
    accepted: bool = True
    stable: bool = True
    delta_bic_held: float = 0.0
    held_rss: float = 1.0
    outcome: object | None = True
    members: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        self.members = self.members or (self.effect,)


def rank(cands):
    return [c.effect for c in sorted(cands, key=_rank_key)]


def test_ranking_accepted_first_then_best_held_out_bic():
    cands = [Cand("rejected_big", accepted=False, delta_bic_held=100.0), Cand("small", delta_bic_held=5.0),
             Cand("big", delta_bic_held=50.0), Cand("unstable", stable=False, delta_bic_held=80.0),
             Cand("unfitted", outcome=None, delta_bic_held=90.0)]
    assert rank(cands) == ["big", "small", "unstable", "unfitted", "rejected_big"]
    assert rank([Cand("r2", accepted=False, delta_bic_held=1.0), Cand("r1", accepted=False, delta_bic_held=9.0)]) == \
        ["r1", "r2"]


def test_no_accepted_candidate_no_winner():
    assert choose_winner([]) is None
    assert choose_winner([Cand("a", accepted=False), Cand("p", kind="parameter", accepted=False)]) is None


def test_the_best_accepted_candidate_wins():
    best = Cand("drag", held_rss=1.0)
    assert choose_winner([Cand("x", accepted=False), best, Cand("y")]) is best
    par = Cand("k3", kind="parameter", held_rss=0.5)
    assert choose_winner([par, best]) is par  # a re-estimation ranked first simply wins


@pytest.mark.parametrize(("ratio", "param_wins"), [(1.0, True), (PREFER_PARAMETER_WITHIN, True),
                                                   (PREFER_PARAMETER_WITHIN * 1.001, False), (3.0, False)])
def test_a_reestimation_close_to_the_best_effect_wins(ratio, param_wins):
    assert PREFER_PARAMETER_WITHIN == pytest.approx(1.10)
    best = Cand("drag", held_rss=2.0)
    par = Cand("k3", kind="parameter", held_rss=2.0 * ratio)
    later = Cand("d_ep", kind="parameter", held_rss=0.1)
    got = choose_winner([best, Cand("other", held_rss=2.5), par, later])
    assert got is (par if param_wins else best)
    # a rejected re-estimation never wins; a combination is not a re-estimation
    assert choose_winner([best, Cand("k3", kind="parameter", accepted=False, held_rss=1.0)]) is best
    assert choose_winner([best, Cand("a + b", kind="combination", held_rss=1.0)]) is best


def _diagnosis(winner, steps=(), ranking=()):
    return Diagnosis(verdict="missing", message="", winner=winner, ranking=list(ranking),
                     baseline_train_rms_sigma=1.0, baseline_held_rms_sigma=1.0, baseline_channels=[],
                     where_it_fails=[], tests_before=[], tests_after=[], targets=[], baseline_sim=None,
                     params_name="table2", timings={}, steps=list(steps))


def test_found_lists_the_blamed_names_in_forward_selection_order():
    win = Cand("drag + creep", kind="combination", members=("drag", "creep"))
    steps = [Cand("creep"), Cand("creep + k3", kind="combination", members=("creep", "k3"))]
    d = _diagnosis(win, steps, ranking=[win, *steps])
    assert d.found == ("creep", "drag")  # k3 was tried but is not in the winner
    assert d.ranked_names == ["drag + creep", "creep", "creep + k3"]
    assert _diagnosis(None, steps).found == ()
    assert _diagnosis(Cand("drag")).found == ("drag",)
