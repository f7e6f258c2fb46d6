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
    """The S-curve (a step with a fitted edge), the settling ramp and the recovery are tried beside the window and
    the two steps; an event's window refitted already is not refitted again."""
    tried: list[str] = []

    def smooth(*a):
        tried.append(a[-1])
        return _fit({"smooth": 1.01, "settle": 3.0, "recover": 2.0}[a[-1]],
                    {"smooth": 20, "settle": 30, "recover": 40}[a[-1]], a[-1])

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
    assert fit.rise == 20 and tried == ["smooth", "settle", "recover"]
    assert any("S-curve" in s and "1.01 σ" in s for s in said)
    ended = _fit(0.9, 50)  # the event's own window, refitted when it was judged: used, not refitted
    progress.n_sims = 0
    fit = staged.change_refit(setup, progress, SimpleNamespace(threads=1, max_nfev=3, say=said.append), 3, ended)
    assert fit is ended and progress.n_sims == 5 * 4


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
