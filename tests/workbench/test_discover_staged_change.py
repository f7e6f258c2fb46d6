"""Damage in stages (issue 26 point 3, :mod:`workbench.discover._staged_change`): a kept step or ramp that leaves
more than the noise is also tried as two steps of its parameter. Found on a blind case (``two_stage_s2`` of
``tests/workbench_blind_damage.py``): section 2 losing 10 % at 4.5 s and 10 % more at 12 s of a 15 s sweep was kept
as a ramp from 2.78 s, 67 σ held out, and said as "stiffness k2 falling by 1.1 %/s from t = 2.8 s"."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

import workbench.discover._staged_change as staged
from workbench.discover._dictionary import Term
from workbench.discover._finite_change import Window, WindowFit, finite_changes
from workbench.discover._results import FoundTerm


def _k2_steps() -> list[Term]:
    return [Term("damage", 1, "one", "on_step", t0, "k", (t0 - 1.0, t0 + 1.0)) for t0 in (2.0, 6.0, 10.0)] + [
        Term("damage", 1, "one", "on_ramp", 4.0, "k", (0.0, 8.0)), Term("damage", 0, "one", "on_step", 6.0, "k"),
        Term("damage", 1, "delta2", "on_pos", 0.0, "k")]


def test_the_steps_of_a_parameter_are_its_own_step_slots_the_kept_one_first():
    terms = _k2_steps()
    assert staged.step_slots(terms, terms[1]) == [1, 0, 2]
    assert staged.step_slots(terms, terms[3]) == [0, 1, 2]  # from a ramp of k2: k2's steps, not k1's
    assert staged.step_slots(terms, terms[4]) == [4]


def test_each_first_instant_is_paired_with_second_instants_after_it_only():
    windows = staged.candidate_stages([2.0, 14.0, 16.0], -0.2, 15.0)
    assert len(windows) == 2 * staged.STAGE_SECONDS  # the first at 16 s is past the record
    assert all(w.start < w.end < 15.0 and w.total == -0.2 for w in windows)
    assert {w.start for w in windows} == {2.0, 14.0}


def test_the_kept_instant_is_also_paired_with_first_instants_before_it():
    """The kept step may sit at the later, larger change: first instants evenly before it end there."""
    windows = staged.candidate_stages([8.0], -0.2, 15.0, kept_at=8.0)
    before = [w for w in windows if w.end == 8.0]
    assert len(before) == staged.STAGE_SECONDS and all(0.0 < w.start < 8.0 for w in before)
    assert len(windows) == 2 * staged.STAGE_SECONDS


def test_a_share_above_one_gives_part_of_the_change_back_at_the_second_step():
    """A partial recovery: 25 % lost, 15 % of it back — the kept total −10 % split at a share of 2.5."""
    assert max(staged.STAGE_SHARES) >= 2.5
    s = staged.stage_setting(Window(6.0, 13.0, -0.1), 2.5, ("a", "ga"), ("b", "gb"))
    assert s == pytest.approx({"a": -0.25, "ga": 6.0, "b": 0.15, "gb": 13.0})


def test_two_steps_share_the_total_change():
    s = staged.stage_setting(Window(4.5, 12.0, -0.2), 0.3, ("a", "ga"), ("b", "gb"))
    assert s == pytest.approx({"a": -0.06, "ga": 4.5, "b": -0.14, "gb": 12.0})


def _fit(held: float, rise: int, kind: str = "window") -> WindowFit:
    out = SimpleNamespace(held_rms_sigma=held, train_rms_sigma=held)
    return WindowFit(rise=rise, end=rise + 1, replaced=3, outcome=out, values={}, n_sims=5, kind=kind)


@pytest.mark.parametrize(("window_held", "stages_held", "chosen"), [(67.9, 1.47, 0), (1.01, 20.0, 10),
                                                                     (None, 3.0, 0), (None, None, None)])
def test_the_change_kept_is_the_refit_that_leaves_the_whole_record_lowest(monkeypatch, window_held, stages_held,
                                                                           chosen):
    monkeypatch.setattr(staged, "window_refit", lambda *a: None if window_held is None else _fit(window_held, 10))
    monkeypatch.setattr(staged, "staged_refit", lambda *a: None if stages_held is None else _fit(stages_held, 0))
    monkeypatch.setattr(staged, "smooth_refit", lambda *a: None)
    terms = _k2_steps()
    setup = SimpleNamespace(terms=terms, names=[("c", "g")] * len(terms), targets=[SimpleNamespace(
        held=np.array([True, False]), train=np.array([False, True]), channels=["z3"])],
                            models=[], scales={"t": 15.0})
    progress = SimpleNamespace(refits=[], state=SimpleNamespace(values={"c": -0.1}, kept=[3]), n_sims=0)
    fit = staged.change_refit(setup, progress, SimpleNamespace(threads=1, max_nfev=3, say=lambda s: None), 3)
    assert (None if fit is None else fit.rise) == chosen
    assert progress.n_sims == 5 * ((window_held is not None) + (stages_held is not None))


def test_a_change_with_a_fitted_time_scale_is_kept_when_it_leaves_the_record_lowest(monkeypatch):
    """The S-curve (a step with a fitted edge), the settling ramp, the recovery and the accelerating change are
    tried beside the window and the two steps; an event's window refitted already is not refitted again."""
    tried: list[str] = []

    def smooth(*a):
        variant = a[-2]  # (…, variant, like)
        tried.append(variant)
        return _fit({"smooth": 1.01, "settle": 3.0, "recover": 2.0, "accelerate": 2.5}[variant],
                    {"smooth": 20, "settle": 30, "recover": 40, "accelerate": 45}[variant], variant)

    monkeypatch.setattr(staged, "window_refit", lambda *a: _fit(4.54, 10))
    monkeypatch.setattr(staged, "staged_refit", lambda *a: _fit(9.0, 0))
    monkeypatch.setattr(staged, "smooth_refit", smooth)
    terms = _k2_steps()
    setup = SimpleNamespace(terms=terms, names=[("c", "g")] * len(terms), targets=[SimpleNamespace(
        held=np.array([True, False]), train=np.array([False, True]), channels=["z3"])],
                            models=[], scales={"t": 15.0})
    progress = SimpleNamespace(refits=[], state=SimpleNamespace(values={"c": -0.1}, kept=[3]), n_sims=0)
    said: list[str] = []
    fit = staged.change_refit(setup, progress, SimpleNamespace(threads=1, max_nfev=3, say=said.append), 3)
    assert fit.rise == 20 and tried == ["smooth", "settle", "recover", "accelerate"]
    assert any("S-curve" in s and "1.01 σ" in s for s in said)
    ended = _fit(0.9, 50)  # the event's own window, refitted when it was judged: used, not refitted
    progress.n_sims = 0
    fit = staged.change_refit(setup, progress, SimpleNamespace(threads=1, max_nfev=3, say=said.append), 3, [ended])
    assert fit is ended and progress.n_sims == 5 * 5
    tried.clear()
    ended = _fit(0.9, 60, "smooth")  # an S-curve the judgement refitted: the window is refitted, the S-curve not
    fit = staged.change_refit(setup, progress, SimpleNamespace(threads=1, max_nfev=3, say=said.append), 3, [ended])
    assert fit is ended and tried == ["settle", "recover", "accelerate"]


def test_two_steps_have_their_onsets_placed_on_the_whole_record_and_refitted_with_them_held(monkeypatch):
    """The refit on the training blocks is blind to an onset inside a held-out block: each onset is placed on the
    whole record, then the sizes are refitted with the onsets held (the better refit of the two is kept)."""
    placed = {"g0": 6.0, "g1": 13.0}
    monkeypatch.setattr(staged, "placed_on_whole", lambda tg, m, values, g, score, th: (placed[g], score * 0.5, 22))
    refits: list[list] = []

    def refine(obj, start, nfev):
        refits.append(obj.free)
        return SimpleNamespace(ok=True, held_rms_sigma=1.0, train_rms_sigma=1.0, values={"c0": -0.25, "c1": 0.15})

    monkeypatch.setattr(staged, "refine", refine)
    monkeypatch.setattr(staged, "Objective", lambda tg, m, free, base_values, threads: SimpleNamespace(
        free=free, n_sims=9))
    monkeypatch.setattr(staged, "whole_rms", lambda tg, out: out.held_rms_sigma)
    terms = _k2_steps()
    names = [("c0", "g0"), ("c1", "g1"), ("c2", "g2"), ("c3", "g3"), ("c4", "g4"), ("c5", None)]
    out = SimpleNamespace(held_rms_sigma=12.6, train_rms_sigma=1.2, values={})
    fit = WindowFit(0, 1, 3, out, {"c0": -0.25, "g0": 6.0, "c1": 0.14, "g1": 12.94}, 5, kind="stages")
    state = SimpleNamespace(values={}, kept=[3])
    again = staged.stages_placed([], [], terms, names, state, fit, 20.0, 1, 3)
    # placed, refitted, placed again where it was: done (two placements of 2 × 22 probes, one refit)
    assert again.values["g1"] == 13.0 and again.outcome.held_rms_sigma == 1.0 and again.n_sims == 5 + 2 * 44 + 9
    onsets = {p.name: (p.lower, p.upper) for p in refits[0] if p.name in ("g0", "g1")}
    assert onsets["g1"] == pytest.approx((13.0 - 1e-3, 13.0 + 1e-3))


def test_the_onsets_of_two_steps_of_one_parameter_are_placed_as_a_pair_in_the_emitted_file():
    terms = _k2_steps()
    found = [FoundTerm(terms[0], -0.1, 4.5, 1.0, "section 2 lost 10 % at t = 4.5 s", []),
             FoundTerm(terms[2], -0.1, 12.0, 1.0, "section 2 lost 10 % at t = 12 s", []),
             FoundTerm(terms[4], -0.1, 6.0, 1.0, "section 1 lost 10 % at t = 6 s", [])]
    out = finite_changes(found)
    assert out[0].term.shape_range == pytest.approx((4.48, 4.52))
    assert out[1].term.shape_range == pytest.approx((11.98, 12.02))
    assert out[2].term.shape_range is None  # a single step of another parameter keeps its range
    assert [f.words for f in out] == [f.words for f in found]


def test_a_later_step_that_gives_part_of_the_loss_back_is_said_as_a_recovery():
    """The root losing 25 % at 6 s and 15 % of it back at 13 s (a blind case): the later step's words say how much
    came back and what stays lost, not "stiffness k1 rose by 15 %"."""
    terms = _k2_steps()
    found = [FoundTerm(terms[0], -0.25, 6.0, 1.0, "section 2 lost 25 % of its stiffness at t = 6 s", [], 0.001),
             FoundTerm(terms[2], 0.15, 13.0, 1.0, "stiffness k2 of section 2 rose by 15 % at t = 13 s", [], 0.001)]
    out = finite_changes(found)
    assert out[0].words == found[0].words
    assert out[1].words.startswith("then section 2 regained 15 % of its stiffness at t = 13.000 ± 0.001 s")
    assert "60 % of the change undone, 10 % stays" in out[1].words and "partial recovery" in out[1].words
    same_way = finite_changes([found[0], FoundTerm(terms[2], -0.1, 13.0, 1.0, "section 2 lost 10 %", [], 0.001)])
    assert same_way[1].words == "section 2 lost 10 %"  # a second loss keeps its own words
