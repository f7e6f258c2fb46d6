"""A kept term the later ones made redundant is dropped (issue 26: the verdict's first sentence must not lead with a
near-nothing): the set without the least missed term, the others refitted, keeps the held-out error within its
statistical spread (3/√(2n): 0.47 % of it for 2·10⁵ held-out samples) — on MBIT.a a drive saturation of
−0.025 %, kept by round 1, led the sentence before the root loss that carried the record. The fit engine is
replaced by fakes: this is the rule, not the search."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from workbench.discover import _backward
from workbench.discover._dictionary import Term
from workbench.discover._rounds import SearchProgress, SearchSettings
from workbench.discover._search import SearchState

TERMS = [Term("drive", 0, "va", "sat", 160.0), Term("damage", 0, "one", "on_ramp", -7.5, "k", (-30.0, 0.0)),
         Term("force_mass", 2, "z3", "lin")]
NAMES = [("a_00", "g_00"), ("a_01", "g_01"), ("a_02", None)]


def _run(monkeypatch, zeroed: dict[str, float], refit_held: float, kept: list[int], current: float = 1.0,
         held_before: float = 50.0) -> SearchProgress:
    """drop_idle on a set ``kept`` at 1.0 σ held out: ``zeroed`` each coefficient's error when set to 0 alone, the
    refit without the least missed one leaving ``refit_held``."""
    def probe_batch(targets, models, values, settings, threads):
        held = np.array([zeroed[next(iter(s))] for s in settings])
        return held, held, np.ones(len(settings), bool)

    refits: list[dict[str, float]] = []

    def refine(obj, start, max_nfev):
        refits.append(start)
        return SimpleNamespace(ok=True, held_rms_sigma=refit_held, train_rms_sigma=refit_held, estimates=[],
                               values={n: 1.1 * start[n] for n, _ in NAMES if start[n] != 0.0})

    monkeypatch.setattr(_backward, "probe_batch", probe_batch)
    monkeypatch.setattr(_backward, "refine", refine)
    monkeypatch.setattr(_backward, "Objective", lambda *a, **k: SimpleNamespace(n_sims=3))
    monkeypatch.setattr(_backward, "free_for", lambda *a, **k: [])
    values = {"a_00": -2.5e-4, "g_00": 160.0, "a_01": -0.01, "g_01": -7.5, "a_02": 5.0}
    progress = SearchProgress(SearchState(values, list(kept)), current, current, 0, {"refit_s": 0.0},
                              twins={k: [{"term": "x"}] for k in kept})
    setup = SimpleNamespace(targets=[object()], models=[None], terms=TERMS, names=NAMES, n_held=200_000,  # 0.47 %
                            held_before=held_before)
    said: list[str] = []
    _backward.drop_idle(setup, progress, SearchSettings(2, 10, 1, False, said.append))
    progress.said = said  # type: ignore[attr-defined]
    progress.refits_started = refits  # type: ignore[attr-defined]
    return progress


def test_a_term_the_others_made_redundant_is_dropped_and_the_set_refitted_without_it(monkeypatch):
    p = _run(monkeypatch, {"a_00": 1.0001, "a_01": 40.0}, 1.001, [0, 1])
    assert p.state.kept == [1] and p.state.values["a_00"] == 0.0 and p.state.values["a_01"] == pytest.approx(-0.011)
    assert 0 not in p.twins and 1 in p.twins and p.current_held == 1.001
    assert p.rounds[-1]["idle_dropped"]["term"] == "va_sat_va" and "idle term: va_sat_va" in p.said[0]


def test_a_term_the_records_still_need_stays(monkeypatch):
    refit_worse = _run(monkeypatch, {"a_00": 1.1, "a_01": 40.0}, 1.006, [0, 1])  # refitted, 0.6 % above: it matters
    assert refit_worse.state.kept == [0, 1] and refit_worse.state.values["a_00"] == -2.5e-4
    clearly = _run(monkeypatch, {"a_00": 3.0, "a_01": 40.0}, 1.0, [0, 1])  # missed at once: not even refitted
    assert clearly.state.kept == [0, 1] and not clearly.refits_started
    alone = _run(monkeypatch, {"a_01": 1.0}, 1.0, [1])  # the last term is never dropped
    assert alone.state.kept == [1]


def test_idle_terms_go_one_at_a_time_the_least_missed_first(monkeypatch):
    p = _run(monkeypatch, {"a_00": 1.0005, "a_01": 40.0, "a_02": 1.0001}, 1.0005, [0, 1, 2])
    assert p.state.kept == [1]
    assert [r["idle_dropped"]["term"] for r in p.rounds] == ["m3_lin_z3", "va_sat_va"]


def test_nothing_is_dropped_while_the_set_leaves_more_than_the_noise(monkeypatch):
    """Above the noise floor the residual is the model's error: a share of it is no statistical spread (the strong
    tip stop of the not-in-the-library challenge, 219 σ with two terms, lost one and rose to 233 σ)."""
    p = _run(monkeypatch, {"a_00": 219.5, "a_01": 900.0}, 219.9, [0, 1], current=219.0, held_before=959.0)
    assert p.state.kept == [0, 1] and not p.refits_started
