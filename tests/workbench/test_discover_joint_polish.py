"""The joint polish after the rounds (issue 26, ``workbench/discover/_joint_polish.py``): each round refits its new
term's shape with the earlier terms' shapes held, so a crack kept first (switching at +20 µm of δ2) stayed there
while round 2 added the damping its rubbing faces add (blind set 6, 15 s sweep: 5.44 σ held out; the emitted file
refitted by ``shm fit --add``, every shape free, 1.13 σ). Here the step's rule with the refit faked: what it frees,
when it runs, and that the set's values change only when the held-out error falls."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

import workbench.discover._joint_polish as jp
from workbench.discover._rounds import SearchProgress


def _case(held: float, kept: list[int]) -> tuple[SimpleNamespace, SearchProgress]:
    terms = [SimpleNamespace(key=k, placement="damage", unit="1", form=f, shape_range=None, shape_unit="m")
             for k, f in (("k2_pos_delta2", "on_pos"), ("c2_pos_soft_delta2", "on_pos_soft"), ("z3m_lin_z3", "lin"))]
    setup = SimpleNamespace(terms=terms, names=[("a_00", "g_00"), ("a_01", "g_01"), ("a_02", None)],
                            targets=[], models=[], held_before=454.0, n_held=1875)
    state = SimpleNamespace(values={"a_00": -0.254, "g_00": 2.02e-5, "a_01": 0.746, "g_01": 2.88e-4, "a_02": 0.0},
                            kept=kept)
    progress = SearchProgress(state=state, current_held=held, current_train=held, stderr={}, outcome=None,
                               rounds=[], timings={"refit_s": 0.0}, n_sims=0)
    return setup, progress


def _fake_refit(monkeypatch, held: float, seen: list[list[str]]) -> None:
    class Obj:
        def __init__(self, targets, models, free, base_values, threads):
            seen.append([fp.name for fp in free])
            self.n_sims = 7

    out = SimpleNamespace(ok=True, held_rms_sigma=held, train_rms_sigma=held, estimates=[],
                          values={"a_00": -0.25, "g_00": 1.0e-6, "a_01": 0.8, "g_01": 1.0e-4})
    monkeypatch.setattr(jp, "Objective", Obj)
    monkeypatch.setattr(jp, "refine", lambda obj, start, nfev: out)


@pytest.mark.parametrize(("polished", "taken"), [(1.13, True), (5.6, False)])
def test_every_kept_shape_is_freed_and_the_values_taken_only_when_the_error_falls(monkeypatch, polished, taken):
    setup, progress = _case(5.44, [0, 1])
    seen: list[list[str]] = []
    _fake_refit(monkeypatch, polished, seen)
    said: list[str] = []
    jp.polish_step(setup, progress, SimpleNamespace(say=said.append, threads=1, max_nfev=12))
    assert sorted(seen[0]) == ["a_00", "a_01", "g_00", "g_01"]  # both coefficients and both shapes
    assert progress.n_sims == 7
    assert (progress.state.values["g_00"] == 1.0e-6) is taken
    assert progress.current_held == (polished if taken else 5.44)
    assert bool(progress.rounds) is taken and bool(said) is taken
    if taken:
        assert progress.rounds[0]["polish"] == {"terms": ["k2_pos_delta2", "c2_pos_soft_delta2"],
                                                "held_rms_sigma": 1.13, "set_held_rms_sigma": 5.44}


@pytest.mark.parametrize(("held", "kept"), [(5.44, [0]), (1.45, [0, 1]), (1.02, [0, 1])])
def test_no_polish_for_one_term_or_near_the_noise(monkeypatch, held, kept):
    setup, progress = _case(held, kept)
    monkeypatch.setattr(jp, "refine", lambda *a: pytest.fail("refitted"))
    jp.polish_step(setup, progress, SimpleNamespace(say=lambda _m: None, threads=1, max_nfev=12))
    assert progress.current_held == held and not progress.rounds
