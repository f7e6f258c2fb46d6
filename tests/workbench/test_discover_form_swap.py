"""A kept switch tried in its other gate shapes beside the rest of the set (issue 26, ``_form_swap.py``): a tip crack
open for δ3 > 0 whose faces also rub while open (blind set 7, 15 s sweep) was kept in round 1 as a loss growing with
the opening (190 σ), round 2 added the damping switched at δ3 > 0 (73.7 σ) and the verdict fell back to the
parameters. Here the step's rule with the probes and refits faked: what it probes on, what it frees, when it runs,
and that the set changes only when a swap fits clearly better."""

from __future__ import annotations

from types import SimpleNamespace

import pytest
from term_swap_fakes import fake_refits

import workbench.discover._form_swap as fs
from workbench.discover._rounds import SearchProgress

KEYS = ("k3_pos_grow_delta3", "c3_pos_delta3", "k3_pos_delta3")


def _case(held: float, kept: list[int]) -> tuple[SimpleNamespace, SearchProgress]:
    terms = [SimpleNamespace(key=k, placement="damage", unit="1", form=f, shape_range=rng, shape_unit="m")
             for k, f, rng in zip(KEYS, ("on_pos_grow", "on_pos", "on_pos"), (None, (-1e-3, 1e-3), (-1e-3, 1e-3)))]
    setup = SimpleNamespace(terms=terms, names=[("a_00", "g_00"), ("a_01", "g_01"), ("a_02", "g_02")],
                            targets=[], models=[], held_before=441.0, n_held=1875)
    state = SimpleNamespace(values={"a_00": -0.211, "g_00": 0.012, "a_01": 0.38, "g_01": 0.0, "a_02": 0.0,
                                    "g_02": 0.0}, kept=kept)
    progress = SearchProgress(state=state, current_held=held, current_train=held, twins={0: ["x"]},
                              timings={"refit_s": 0.0}, n_sims=0)
    return setup, progress


def _fake(monkeypatch, refit_held: float, seen: dict[str, list]) -> None:
    def best_shapes(setup, progress, settings, cands, coef, base):
        seen["probed"] = [cands, coef, dict(base)]
        return {2: (80.0, (2, -0.12, 1e-6))}

    monkeypatch.setattr(fs, "shape_candidates", lambda terms, term: [0, 2] if term.key == KEYS[0] else [])
    monkeypatch.setattr(fs, "best_shapes", best_shapes)
    fake_refits(monkeypatch, seen, refit_held, {"a_02": -0.12, "g_02": 2e-6, "a_01": 0.36})


@pytest.mark.parametrize(("refit_held", "taken"), [(1.1, True), (72.0, False)])
def test_a_kept_switch_is_swapped_for_another_shape_only_when_it_fits_clearly_better(monkeypatch, refit_held,
                                                                                   taken):
    setup, progress = _case(73.7, [0, 1])
    seen: dict[str, list] = {}
    _fake(monkeypatch, refit_held, seen)
    said: list[str] = []
    assert fs.swap_step(setup, progress, SimpleNamespace(say=said.append, threads=1, max_nfev=12)) is taken
    cands, coef, base = seen["probed"]
    assert cands == [2] and coef == -0.211  # not the kept term itself; probed at its size
    assert base["a_00"] == 0.0 and base["a_01"] == 0.38  # with that term off, the rest of the set on
    assert [sorted(f) for f in seen["free"]] == [["a_01", "a_02", "g_02"]]  # every kept coefficient, its shape
    assert seen["start"][-1]["a_02"] == -0.12 and seen["start"][-1]["g_02"] == 1e-6 and progress.n_sims == 4
    assert progress.rounds[-1]["shape_swap"]["taken"] is taken and ("taken" in said[-1])
    if taken:
        assert progress.state.kept == [2, 1] and progress.current_held == 1.1
        assert progress.state.values["a_00"] == 0.0 and progress.state.values["g_02"] == 2e-6
        assert 0 not in progress.twins
    else:
        assert progress.state.kept == [0, 1] and progress.current_held == 73.7 and progress.twins == {0: ["x"]}


@pytest.mark.parametrize(("held", "kept"), [(73.7, [0]), (2.9, [0, 1])])
def test_no_swap_for_one_term_or_near_the_noise(monkeypatch, held, kept):
    setup, progress = _case(held, kept)
    monkeypatch.setattr(fs, "best_shapes", lambda *a: pytest.fail("probed"))
    fs.swap_step(setup, progress, SimpleNamespace(say=lambda _m: None, threads=1, max_nfev=12))
    assert progress.current_held == held and not progress.rounds


def test_a_switch_given_an_instant_is_swapped_with_its_other_shapes_begun_at_that_instant(monkeypatch):
    """A crack that appeared at 6.75 s and breathes, kept as one opening gradually and placed at 6.69 s: the swap
    runs again for it alone, its other shapes probed and refitted from that instant (none of the others given it)."""
    from workbench.discover._dictionary_code import since_name
    from workbench.discover._gates import SINCE_NEVER_S

    setup, progress = _case(34.0, [0])
    progress.state.values |= {since_name(0): 6.69, since_name(1): SINCE_NEVER_S, since_name(2): SINCE_NEVER_S}
    seen: dict[str, list] = {}
    _fake(monkeypatch, 1.1, seen)
    fs.placed_swap_step(setup, progress, SimpleNamespace(say=lambda _m: None, threads=1, max_nfev=12))
    cands, _, base = seen["probed"]
    assert cands == [2] and base[since_name(2)] == 6.69 and base["a_00"] == 0.0
    start, placed = seen["start"]  # the swap's refit, then the set's refit at the new shape's placed instant
    assert placed[since_name(2)] == 6.001
    assert start[since_name(2)] == 6.69 and start[since_name(1)] == SINCE_NEVER_S
    assert progress.state.kept == [2] and progress.state.values[since_name(2)] == 6.001  # then placed on its own


def test_no_second_swap_for_a_switch_over_the_whole_record(monkeypatch):
    from workbench.discover._dictionary_code import since_name
    from workbench.discover._gates import SINCE_NEVER_S

    setup, progress = _case(34.0, [0])
    progress.state.values[since_name(0)] = SINCE_NEVER_S
    monkeypatch.setattr(fs, "best_shapes", lambda *a: pytest.fail("probed"))
    fs.placed_swap_step(setup, progress, SimpleNamespace(say=lambda _m: None, threads=1, max_nfev=12))
    assert not progress.rounds


def test_after_a_move_the_swap_runs_down_to_the_fix_limit(monkeypatch):
    """A set at 2.71 σ of 441 σ ("explained" by share, above the 1.5 σ a fix must reach): after a kept term moved to
    another place the shapes are tried again down to that limit (``above``), not below it."""
    setup, progress = _case(2.71, [0, 1])
    seen: dict[str, list] = {}
    _fake(monkeypatch, 1.1, seen)
    settings = SimpleNamespace(say=lambda _m: None, threads=1, max_nfev=12)
    assert fs.swap_step(setup, progress, settings) is False and "probed" not in seen
    assert fs.swap_step(setup, progress, settings, above=1.5) is True and progress.current_held == 1.1
    assert fs.swap_step(setup, progress, settings, above=1.5) is False  # at the limit: nothing more is tried
