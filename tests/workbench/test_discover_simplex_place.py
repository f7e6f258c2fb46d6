"""Instants and sizes of a kept change moved together on the whole record (issue 26 point 3): a simplex search walks
the valleys where a step placed late is sized larger, which zooms of one coordinate at a time stop in."""

from __future__ import annotations

import math
from types import SimpleNamespace

import pytest

import workbench.discover._simplex_place as sp
import workbench.discover._staged_change as staged
from workbench.discover._finite_change import WindowFit


def _trade(setting: dict[str, float]) -> float:
    """A whole-record RMS (σ) whose narrow valley trades each step's onset against its size (a step 0.1 s late is
    1 % larger), least (1 σ) at (4.5 s, −0.25) and (9.75 s, +0.15)."""
    d1 = (setting["g1"] - 4.5, setting["c1"] + 0.25)
    d2 = (setting["g2"] - 9.75, setting["c2"] - 0.15)
    valley = sum((dc + 0.1 * dg) ** 2 for dg, dc in (d1, d2))
    return math.sqrt(1.0 + 4e5 * valley + 50.0 * (d1[0] ** 2 + d2[0] ** 2))


def test_the_simplex_walks_a_valley_that_one_coordinate_at_a_time_cannot():
    start = {"g1": 4.44, "c1": -0.223, "g2": 9.893, "c2": 0.122}
    here, step, n = dict(start), 0.05, 0  # one coordinate at a time, the step halved when no move helps
    while step > 1e-5 and n < 400:
        moves = [here | {k: here[k] + d} for k in here for d in (-step, step)]
        best, n = min(moves, key=_trade), n + len(moves)
        here, step = (best, step) if _trade(best) < _trade(here) else (here, 0.5 * step)
    assert _trade(here) > 2.0  # 400 probes, still far up the valley
    x, score = sp.simplex_search(lambda v: _trade(dict(zip(start, v))), list(start.values()), 400)
    assert score < 1.01 and x[0] == pytest.approx(4.5, abs=0.01) and x[2] == pytest.approx(9.75, abs=0.01)


def test_placed_together_keeps_onsets_in_the_record_and_losses_above_the_limit(monkeypatch):
    calls: list[dict[str, float]] = []

    def scores(targets, models, values, settings, threads):
        calls.extend(settings)
        return [_trade(values | s) for s in settings]

    monkeypatch.setattr(sp, "whole_scores", scores)
    values = {"g1": 4.44, "c1": -0.223, "g2": 9.893, "c2": 0.122, "other": 3.0}
    out, score, n = sp.placed_together([None, None], [], values, ["g1", "g2"], ["c1", "c2"], (0.0, 15.0), None, 400)
    assert out["other"] == 3.0 and score < 1.01 and out["g1"] == pytest.approx(4.5, abs=0.01)
    assert n == 2 * len(calls) and len(calls) <= 400  # the simulations: each probe runs every record
    assert all(0.0 <= c["g1"] <= 15.0 and c["c1"] >= sp.MAX_LOSS for c in calls)
    _, score, _ = sp.placed_together([None], [], values | {"g1": 14.99}, ["g1"], [], (0.0, 4.0), None, 50)
    assert math.isinf(score)  # outside its span from the start: nothing probed


def _two_steps(held: float) -> WindowFit:
    out = SimpleNamespace(held_rms_sigma=held, train_rms_sigma=held, ok=True, values={})
    return WindowFit(0, 1, 0, out, {"c0": -0.22, "g0": 4.44, "c1": 0.12, "g1": 9.89}, 10, kind="stages")


@pytest.mark.parametrize(("held", "moved", "refit", "kept"), [(1.2, 0.5, 0.9, False), (10.7, 12.0, 0.9, False),
                                                              (10.7, 1.0, 1.02, True), (10.7, 1.0, 11.0, False)])
def test_two_steps_still_far_are_moved_together_and_kept_only_when_the_whole_record_prefers(
        monkeypatch, held, moved, refit, kept):
    names = [("c0", "g0"), ("c1", "g1")]
    monkeypatch.setattr(staged, "whole_rms", lambda tg, out: out.held_rms_sigma)
    monkeypatch.setattr(staged, "placed_together", lambda tg, m, values, onsets, sizes, span, th: (
        values | {"g0": 4.5, "g1": 9.75}, moved, 300))
    monkeypatch.setattr(staged, "stage_free", lambda *a: ["free"])
    monkeypatch.setattr(staged, "Objective", lambda tg, m, free, base_values, threads: SimpleNamespace(n_sims=7))
    monkeypatch.setattr(staged, "refine", lambda obj, start, nfev: SimpleNamespace(
        ok=True, held_rms_sigma=refit, train_rms_sigma=refit, values={"c0": -0.25, "c1": 0.15}))
    fit, n = staged._stages_together([None], [], [], names, None, _two_steps(held), 15.0, None, 5)
    assert n == (0 if held <= staged.TOGETHER_ABOVE_SIGMA else 300 if moved >= held else 307)
    assert (fit.values["g0"] == 4.5 and fit.values["c0"] == -0.25) is kept
    # one step split in two at one instant (the move brought them together): not kept
    monkeypatch.setattr(staged, "placed_together", lambda tg, m, values, onsets, sizes, span, th: (
        values | {"g0": 11.0, "g1": 11.002}, moved, 300))
    fit, _ = staged._stages_together([None], [], [], names, None, _two_steps(held), 15.0, None, 5)
    assert fit.values["g0"] == 4.44
