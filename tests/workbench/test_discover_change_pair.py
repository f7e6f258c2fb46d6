"""Two losses in two places at two instants (issue 26 point 3, :mod:`workbench.discover._change_pair`): the root
losing 6 % at 3.75 s and the tip 6 % at 9 s of a 15 s sweep (the fifth blind set's ``root_then_tip_loss``) was kept
as a crack in section 3, then as the tip's step at the first instant (46.7 σ): the place moves and the split hold the
instant. The pair probes the kept step in each place with a second step elsewhere at its own instant."""

from __future__ import annotations

import math
from types import SimpleNamespace

import pytest

import workbench.discover._change_pair as pair
from workbench.discover._dictionary import Term
from workbench.discover._rounds import SearchProgress


def _terms() -> list[Term]:
    """Two steps of k per section (slots 0–5: section i at 2i and 2i + 1) and a crack of k3."""
    return [Term("damage", i, "one", "on_step", t0, "k", (t0 - 4.0, t0 + 4.0)) for i in range(3)
            for t0 in (4.0, 11.0)] + [Term("damage", 2, "delta3", "on_neg", 0.0, "k")]


NAMES = [(f"c{k}", f"g{k}") for k in range(6)] + [("c6", None)]


def test_the_kept_step_is_probed_in_each_place_with_a_second_step_elsewhere_at_its_own_instant():
    values = {"c4": -0.057, "g4": 3.74}  # the tip's step (section 3, slot 4) at the first instant
    tries = pair.pair_tries(_terms(), NAMES, values, [4], 4, 15.0)
    pairs = {slots for slots, _ in tries}
    # first piece in sections 1, 2, 3 (slots 0, 2, 4); the second in another section, its first free step
    assert pairs == {(0, 2), (0, 4 + 1), (2, 0), (2, 5), (4, 0), (4, 2)}
    assert len(tries) == len(pairs) * pair.PAIR_INSTANTS * len(pair.PAIR_ADD)
    moved = next(s for slots, s in tries if slots == (0, 5) and s["g5"] > 8.0 and s["c5"] == pytest.approx(-0.057))
    assert moved["c4"] == 0.0 and moved["c0"] == pytest.approx(-0.057) and moved["g0"] == 3.74  # the first moved
    stays = next(s for slots, s in tries if slots == (4, 0))
    assert stays["c4"] == pytest.approx(-0.057) and stays["g4"] == 3.74
    instants = sorted({s["g5"] for slots, s in tries if slots == (0, 5)})
    assert len(instants) == pair.PAIR_INSTANTS and all(0.0 < t < 15.0 for t in instants)


def test_a_place_whose_step_is_kept_already_is_not_a_first_place():
    tries = pair.pair_tries(_terms(), NAMES, {"c4": -0.05, "g4": 3.74}, [0, 4], 4, 15.0)
    assert {slots for slots, _ in tries} == {(2, 1), (2, 5), (4, 1), (4, 2)}


def _progress(held: float, kept_slot: int = 4) -> SearchProgress:
    state = SimpleNamespace(kept=[6, kept_slot], values={"c4": -0.057, "g4": 3.74, "c6": -0.05})
    return SearchProgress(state=state, current_held=held, current_train=held, n_sims=0, rounds=[], stderr={},
                           twins={kept_slot: [{"key": "k3_neg_delta3"}]}, outcome=None, timings={"refit_s": 0.0})


def _setup() -> SimpleNamespace:
    return SimpleNamespace(terms=_terms(), names=NAMES, n_held=1875, scales={"t": 15.0}, targets=[], models=[])


@pytest.mark.parametrize(("current", "after", "kept"), [(46.7, 1.0, True), (46.7, 43.0, False), (2.5, 1.0, None)])
def test_the_pair_replaces_the_kept_step_when_it_removes_the_share(monkeypatch, current, after, kept):
    out = SimpleNamespace(held_rms_sigma=after, train_rms_sigma=after, estimates=[SimpleNamespace(name="g5",
                                                                                                  stderr=0.001)])
    calls = []

    def fake(setup, state, slot, threads, nfev):
        calls.append(slot)
        return pair.PairChange((0, 5), out, {"c0": -0.06, "g0": 3.75, "c5": -0.06, "g5": 9.0}, 12)

    monkeypatch.setattr(pair, "pair_refit", fake)
    progress, said = _progress(current), []
    pair.pair_change(_setup(), progress, SimpleNamespace(threads=1, max_nfev=3, say=said.append), 0.25)
    if kept is None:  # near the noise: the place moves and the split decide
        assert calls == [] and progress.state.kept == [6, 4]
        return
    assert calls == [4] and progress.n_sims == 12
    if kept:
        assert progress.state.kept == [6, 0, 5] and progress.state.values["c4"] == 0.0
        assert progress.current_held == after and 4 not in progress.twins and progress.stderr == {"g5": 0.001}
    else:
        assert progress.state.kept == [6, 4] and progress.state.values["c4"] == -0.057
    assert any("two steps in two places" in s for s in said)


def test_only_a_kept_step_far_from_the_noise_is_probed_as_a_pair(monkeypatch):
    monkeypatch.setattr(pair, "pair_refit", lambda *a: pytest.fail("probed"))
    progress = _progress(46.7, kept_slot=6)  # a crack, constant in time
    pair.pair_change(_setup(), progress, SimpleNamespace(threads=1, max_nfev=3, say=print), 0.25)
    assert progress.state.kept == [6, 6]


def test_the_best_probes_are_taken_once_per_pair_of_places_in_either_order():
    tries = [((0, 5), {"a": 1.0}), ((5, 0), {"a": 2.0}), ((0, 5), {"a": 3.0}), ((2, 5), {"a": 4.0}),
             ((4, 0), {"a": 5.0})]
    scores = [3.0, 1.0, 2.0, math.inf, 4.0]
    found = pair.best_distinct(tries, scores, 3)
    # (5, 0) and (0, 5) are one pair of places: its lowest kept; an infinite score ends the list
    assert [(t[0], e) for t, e in found] == [((5, 0), 1.0), ((4, 0), 4.0)]
    assert pair.best_distinct(tries, scores, 1) == [(tries[1], 1.0)]


def test_swapping_the_places_moves_each_instant_with_its_size():
    values = {"c4": -0.068, "g4": 3.742, "c1": -0.034, "g1": 9.005}
    slots, change = pair.swapped(NAMES, (4, 1), values)
    assert slots == (1, 4)  # the first instant's slot first
    assert change == {"c4": -0.034, "g4": 9.005, "c1": -0.068, "g1": 3.742}


def test_the_refits_are_the_three_lowest_and_the_best_one_swapped():
    # two pairs found and placed (indices 0, 1), then the same two swapped (2, 3)
    placed = [((4, 1), {"v": 0.0}, 31.8), ((4, 3), {"v": 1.0}, 33.8), ((1, 4), {"v": 2.0}, 141.9),
              ((3, 4), {"v": 3.0}, 53.9)]
    assert [s for s, _ in pair.refit_order(placed, 2)] == [(4, 1), (4, 3), (3, 4), (1, 4)]
    placed[2] = ((1, 4), {"v": 2.0}, 40.0)  # the best's swap among the three lowest: no fourth
    assert [s for s, _ in pair.refit_order(placed, 2)] == [(4, 1), (4, 3), (1, 4)]


def test_the_pair_kept_is_the_refit_the_held_out_blocks_prefer_not_the_probe_lowest_before_it(monkeypatch):
    tries = [((4, 1), {"c1": -0.03}), ((4, 3), {"c3": -0.03})]
    monkeypatch.setattr(pair, "whole_scores", lambda *a: [31.8, 33.8])
    placed = [((4, 1), {"v": 0.0}, 31.8), ((4, 3), {"v": 1.0}, 33.8), ((1, 4), {"v": 2.0}, 141.9),
              ((3, 4), {"v": 3.0}, 53.9)]
    monkeypatch.setattr(pair, "pair_tries", lambda *a: tries)
    monkeypatch.setattr(pair, "_placed", lambda *a: (placed, 7))
    held = {(4, 1): 3.81, (4, 3): 20.0, (3, 4): 5.0, (1, 4): 0.976}  # the best's swap refits lowest

    def refit(setup, state, slot, slots, start, threads, nfev):
        out = SimpleNamespace(ok=True, held_rms_sigma=held[slots])
        return pair.PairChange(slots, out, dict(start), 10)

    monkeypatch.setattr(pair, "_pair_refit_one", refit)
    setup = SimpleNamespace(terms=_terms(), names=NAMES, scales={"t": 15.0}, targets=[object()], models=[object()])
    got = pair.pair_refit(setup, SimpleNamespace(values={}, kept=[4]), 4, 1, 3)
    assert got is not None and got.slots == (1, 4) and got.outcome.held_rms_sigma == 0.976
    assert got.n_sims == 2 * 1 + 7 + 4 * 10  # the probes, the placing, four refits
