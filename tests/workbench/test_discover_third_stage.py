"""Damage in three stages (issue 26 point 3, :func:`workbench.discover._staged_change.third_stage`): two steps that
still leave more than the noise are given a third step of their parameter. Found on a blind case (the fifth set's
``tip_loss_in_jumps``: section 3 losing 2 % at 3.75 s, 6.75 s and 9.75 s of a 15 s sweep), said as a loss "between
t = 0.00 s and 10.34 s, faster and faster" (1.55 σ): no shape of one or two pieces follows three jumps."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

import workbench.discover._staged_change as staged
from workbench.discover._dictionary import Term
from workbench.discover._finite_change import WindowFit


def _k3_steps() -> list[Term]:
    return [Term("damage", 2, "one", "on_step", t0, "k", (t0 - 2.0, t0 + 2.0)) for t0 in (2.0, 6.0, 10.0, 14.0)] + [
        Term("damage", 1, "one", "on_step", 6.0, "k", (4.0, 8.0))]


NAMES = [(f"c{k}", f"g{k}") for k in range(5)]


def test_the_third_step_is_probed_over_the_record_as_equal_thirds_and_as_a_share_of_its_nearest_step():
    steps = [(3.7, -0.02, ("a", "ga")), (8.0, -0.04, ("b", "gb"))]
    out = staged.third_settings(steps, ("c", "gc"), 15.0)
    instants = sorted({s["gc"] for s in out})
    assert len(instants) == staged.THIRD_INSTANTS and all(0.0 < t < 15.0 for t in instants)
    assert len(out) == staged.THIRD_INSTANTS * (1 + len(staged.THIRD_SHARES))
    at_1 = [s for s in out if s["gc"] == instants[0]]  # 0.94 s: nearest the step at 3.7 s
    assert at_1[0] == pytest.approx({"a": -0.02, "b": -0.02, "c": -0.02, "gc": instants[0]})  # equal thirds
    assert at_1[1] == pytest.approx({"a": -0.014, "c": -0.006, "gc": instants[0]})  # 30 % split off the nearest
    last = [s for s in out if s["gc"] == instants[-1]]
    assert last[2] == pytest.approx({"b": -0.02, "c": -0.02, "gc": instants[-1]})  # half of the later step


def test_no_third_instant_is_probed_on_a_step():
    steps = [(15.0 / 16.0, -0.02, ("a", "ga")), (8.0, -0.04, ("b", "gb"))]
    instants = {s["gc"] for s in staged.third_settings(steps, ("c", "gc"), 15.0)}
    assert len(instants) == staged.THIRD_INSTANTS - 1 and 15.0 / 16.0 not in instants


def _two_steps(held: float, kind: str = "stages") -> WindowFit:
    out = SimpleNamespace(held_rms_sigma=held, train_rms_sigma=held, ok=True, values={})
    return WindowFit(0, 2, 0, out, {"c0": -0.02, "g0": 3.7, "c2": -0.04, "g2": 8.0}, 7, kind=kind)


def _fakes(monkeypatch, best_at: float) -> list:
    """The fit engine faked: a probe scores lowest at ``best_at`` (equal thirds); the refit reaches 1.0 σ."""
    frees: list = []
    monkeypatch.setattr(staged, "whole_rms", lambda tg, out: out.held_rms_sigma)
    monkeypatch.setattr(staged, "whole_scores", lambda tg, m, values, settings, th: [
        1.0 + abs(s.get("g1", 0.0) - best_at) + (0.0 if len(s) == 4 else 0.5) for s in settings])
    monkeypatch.setattr(staged, "placed_on_whole", lambda tg, m, values, g, score, th: (best_at + 0.05, score, 11))
    monkeypatch.setattr(staged, "Objective", lambda tg, m, free, base_values, threads: SimpleNamespace(
        free=free, n_sims=9))

    def refine(obj, start, nfev):
        frees.append(obj.free)
        return SimpleNamespace(ok=True, held_rms_sigma=1.0, train_rms_sigma=1.0, values={"c1": -0.02})

    monkeypatch.setattr(staged, "refine", refine)
    monkeypatch.setattr(staged, "stages_placed", lambda tg, m, terms, names, state, fit, t_end, th, nfev: fit)
    return frees


def test_two_steps_that_leave_more_than_the_noise_get_a_third_of_their_parameter(monkeypatch):
    frees = _fakes(monkeypatch, best_at=15.0 * 6 / 16)  # between the two steps (3.7 s, 8 s)
    fit = staged.third_stage([], [], _k3_steps(), NAMES, SimpleNamespace(kept=[0]), _two_steps(2.62), 15.0, 1, 3)
    assert fit is not None and fit.kind == "stages3" and fit.slots == (0, 1, 2)  # in time order: 3.7, 5.675, 8 s
    assert fit.values["g1"] == pytest.approx(15.0 * 6 / 16 + 0.05)  # placed on the whole record
    assert fit.values["c1"] == -0.02 and fit.outcome.held_rms_sigma == 1.0
    assert {p.name for p in frees[0]} == {"c0", "g0", "c2", "g2", "c1", "g1"}  # the three sizes and onsets
    assert fit.n_sims == 11 + 9  # no targets: the probes count none


@pytest.mark.parametrize(("held", "kind", "kept"), [(1.2, "stages", [0]), (2.6, "window", [0]),
                                                   (2.6, "stages", [0, 1, 3])])
def test_no_third_step_when_two_explain_the_records_or_none_is_free(monkeypatch, held, kind, kept):
    _fakes(monkeypatch, best_at=10.0)
    fit = _two_steps(held, kind)
    assert staged.third_stage([], [], _k3_steps(), NAMES, SimpleNamespace(kept=kept), fit, 15.0, 1, 3) is None


@pytest.mark.parametrize(("placed_at", "three"), [(8.1, False), (8.0 + 0.02 * 15.0 + 0.01, True)])
def test_a_third_step_that_ends_beside_another_is_one_step_split_in_two(monkeypatch, placed_at, three):
    """MBIT.b's root loss at 0.75 s and tip loss at 1.8 s were kept as section 1 losing 6.01 % at 0.750 s, 2.69 % at
    1.794 s and 2.67 % at 1.811 s: two steps within 2 % of the record of each other are not two stages."""
    _fakes(monkeypatch, best_at=placed_at - 0.05)
    fit = staged.third_stage([], [], _k3_steps(), NAMES, SimpleNamespace(kept=[0]), _two_steps(2.62), 15.0, 1, 3)
    assert (fit is not None) == three


def test_three_steps_are_kept_in_place_of_the_change():
    from workbench.discover._finite_change import keep_window

    out = SimpleNamespace(estimates=[SimpleNamespace(name="g1", stderr=0.001)])
    fit = WindowFit(0, 2, 0, out, {"c1": -0.02, "g1": 9.75}, 1, kind="stages3", extra=(1,))
    state = SimpleNamespace(kept=[4, 0], values={})
    stderr: dict = {}
    keep_window(state, stderr, {}, fit)
    assert state.kept == [4, 0, 2, 1] and state.values == {"c1": -0.02, "g1": 9.75} and stderr == {"g1": 0.001}


def test_the_third_step_is_tried_beside_the_other_shapes_of_the_kept_change(monkeypatch):
    import numpy as np

    monkeypatch.setattr(staged, "window_refit", lambda *a: None)
    monkeypatch.setattr(staged, "smooth_refit", lambda *a: None)
    monkeypatch.setattr(staged, "staged_refit", lambda *a: _two_steps(2.62))
    three = WindowFit(0, 2, 0, SimpleNamespace(held_rms_sigma=1.0, train_rms_sigma=1.0), {}, 4, kind="stages3",
                      extra=(1,))
    monkeypatch.setattr(staged, "third_stage", lambda *a: three)
    terms = _k3_steps()
    setup = SimpleNamespace(terms=terms, names=NAMES, targets=[SimpleNamespace(
        held=np.array([True, False]), train=np.array([False, True]), channels=["z3"])], models=[],
                            scales={"t": 15.0})
    progress = SimpleNamespace(refits=[], state=SimpleNamespace(values={"c0": -0.06, "g0": 3.75}, kept=[0]),
                               n_sims=0)
    said: list[str] = []
    assert staged.change_refit(setup, progress, SimpleNamespace(threads=1, max_nfev=3, say=said.append), 0) is three
    assert progress.n_sims == 7 + 4 and any("as three steps: 1 σ" in s for s in said)
