"""A switch with a fitted edge (issue 26 point 3): a kept sign gate that leaves more than the noise is refitted with
its edge width free — a switch off zero over a finite range — said, emitted and kept so."""

from __future__ import annotations

import math
from types import SimpleNamespace

import pytest

from workbench.discover._dictionary import Term
from workbench.discover._effect_writer import describe_term, emit_effect_source, parameter_names_for
from workbench.discover._finite_change import WindowFit
from workbench.discover._smooth_change import Edge, EdgeProbe, zoom_edge
from workbench.discover._switch_edge import (
    EDGE_WIDTHS,
    POINT_FREE,
    candidate_switch_edges,
    switch_bounds,
    switch_free,
)

SCALES = {"delta2": 1e-3, "ddelta2": 0.1, "va": 150.0, "vc": 100.0, "t": 15.0}


def test_edges_are_probed_at_the_kept_point_over_widths_of_the_signals_scale():
    edges = candidate_switch_edges(-0.3, 60.0, 150.0)
    assert {e.centre for e in edges} == {60.0}
    assert sorted({e.width for e in edges}) == pytest.approx([w * 150.0 for w in EDGE_WIDTHS])
    assert sorted({e.total for e in edges}) == pytest.approx([-0.39, -0.3])


def test_a_switching_point_moves_within_its_terms_range_widened_and_may_be_negative():
    term = Term("damage", -1, "va", "on_neg", 0.0, "d_ep", (-120.0, 120.0))
    assert switch_bounds(term, -100.0, 150.0) == pytest.approx((-100.0 - POINT_FREE * 150.0, -55.0))
    assert switch_bounds(term, 118.0, 150.0) == pytest.approx((73.0, 118.0 + POINT_FREE * 150.0))


class _Bowl(EdgeProbe):
    """Whole-record RMS: the distance to a switch at +80 V over a 15 V edge, losing 30 %."""

    def scores(self, edges):
        return [1.0 + abs(e.centre - 80.0) / 10 + abs(math.log(e.width / 15.0)) + 10 * abs(e.total + 0.3)
                for e in edges]


def test_the_zoom_of_a_switch_keeps_its_point_within_bounds_and_its_size_as_the_coefficient():
    probe = _Bowl([], [], {}, ("a_1", "g_1", "h_1"), None, "on_pos", bounds=(40.0, 120.0))
    edge, _, _ = zoom_edge(probe, candidate_switch_edges(-0.28, 70.0, 150.0), 0.0)
    assert 40.0 <= edge.centre <= 120.0 and abs(edge.centre - 80.0) < 6.0
    assert abs(math.log(edge.width / 15.0)) < 0.3 and abs(edge.total + 0.3) < 0.03
    assert probe.setting(Edge(80.0, 15.0, -0.3)) == {"a_1": -0.3, "g_1": 80.0, "h_1": 15.0}  # not a rate
    below = _Bowl([], [], {}, ("a_1", "g_1", "h_1"), None, "on_neg", bounds=(-200.0, -10.0))
    edge, _, _ = zoom_edge(below, [Edge(-20.0, 5.0, -0.3)], 0.0)
    assert edge.centre <= -10.0  # a switching point below zero is no onset: not clipped at 0


def test_the_refit_frees_size_point_and_width_of_the_switch():
    from discover_slots import kept_slot

    s = kept_slot(SCALES, "d_ep_neg_va", -0.3, 60.0, 10.0)
    c, g, h, k = s["c"], s["g"], s["h"], s["k"]
    free = {p.name: p for p in switch_free(s["terms"], s["names"], s["state"], dict(s["state"].values), k,
                                           (20.0, 100.0))}
    assert set(free) == {c, g, h}
    assert (free[g].lower, free[g].upper) == (20.0, 100.0) and free[h].log
    assert free[h].lower == pytest.approx(10.0 / 3) and free[c].lower >= -0.95


def test_a_switch_with_a_fitted_edge_is_said_and_emitted_with_it():
    term = Term("damage", 1, "va", "on_pos", 80.0, "d_ep_i", (-120.0, 120.0), width=15.0)
    words = describe_term(term, -0.3, 80.0, 150.0, 2.0)
    assert "above +80 V" in words and "a gradual switch: 10–90 % of it over 33 V about that point" in words
    (c, g), = parameter_names_for([term])
    src = emit_effect_source([term], {c: -0.3, g: 80.0})
    assert "/ 15.0)" in src and f"[va > {g}]   (its edge ½(1 + tanh((va − {g}) / 15)), SI)" in src
    assert "tanh((t −" not in src  # a switch on the drive, not a step in time


def test_a_kept_switch_that_leaves_more_than_the_noise_is_refitted_with_an_edge_and_kept(monkeypatch):
    import workbench.discover._kept_change as kc

    out = SimpleNamespace(held_rms_sigma=1.1, train_rms_sigma=1.0, estimates=())
    fit = WindowFit(0, 0, 0, out, {"a0": -0.3, "h_00": 15.0}, 9, kind="edge")
    calls = []
    monkeypatch.setattr(kc, "switch_edge_refit", lambda *a: calls.append(a[-3]) or fit)
    placed: list[float] = []
    monkeypatch.setattr(kc, "place_change", lambda setup, progress, settings: placed.append(progress.current_held))
    terms = [Term("damage", 1, "va", "on_pos", 0.0, "d_ep_i", (-120.0, 120.0))]
    setup = SimpleNamespace(terms=terms, names=[("a0", "g0")], targets=[], models=[], scales={"va": 150.0},
                            n_held=5000)
    state = SimpleNamespace(values={"a0": -0.25}, kept=[0])
    progress = SimpleNamespace(ended=None, shaped=[], current_held=2.24, current_train=2.0, state=state, stderr={},
                               twins={}, timings={"refit_s": 0.0}, rounds=[], n_sims=0, outcome=None)
    said: list[str] = []
    kc.refine_kept(setup, progress, SimpleNamespace(say=said.append, threads=1, max_nfev=3), 0.25)
    assert calls == [150.0] and progress.current_held == 1.1 and state.values["h_00"] == 15.0
    assert state.kept == [0] and progress.n_sims == 9 and "kept in its place" in said[-1]
    progress.current_held = 1.0  # at the noise floor: nothing refitted, but a patch's gate is still placed
    kc.refine_kept(setup, progress, SimpleNamespace(say=said.append, threads=1, max_nfev=3), 0.25)
    assert calls == [150.0]
    # placed once after the refit was kept, once at the noise floor (MBIT.a, patch 1 fading with its voltage: kept in
    # patch 2 at 0.983 σ, patches 1 and 3 never said though the record cannot tell them apart)
    assert placed == [1.1, 1.0]
