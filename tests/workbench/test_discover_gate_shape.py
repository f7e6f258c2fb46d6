"""The same damage with another gate shape (issue 26 point 3, ``workbench/discover/_gate_shape.py``): a change kept
with the wrong shape of its gate — a crack held shut until δ2 < −0.4 mm said as one whose loss grows with the
opening (26.4 σ, blind set 4, sweep), a patch fading with its voltage said as a smooth switch of the drive (7.0 σ,
MBIT.a) — is probed with each other shape of the same parameter, place and side over a grid, and comes back as a
row placed at its best probe. The measured cases are the fourth blind set's heavy ones."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

import workbench.discover._gate_shape as gs
import workbench.discover._onset as scoring
from workbench.discover import build_dictionary
from workbench.discover._effect_writer import parameter_names_for

SCALES = {f"{s}{i}": v for s, v in (("z", 1e-3), ("zd", 0.1), ("delta", 1e-3), ("ddelta", 0.1))
          for i in (1, 2, 3)} | {"vc": 300.0, "va": 300.0, "t": 20.0}


def _key(terms, key: str) -> int:
    return next(k for k, t in enumerate(terms) if t.key == key)


def test_sides_kinds_and_grids():
    assert gs.gate_side("on_neg_grow") == "neg" and gs.gate_side("on_pos") == "pos"
    assert gs.gate_side("on_gap") == "" and gs.gate_side("on_step") == ""
    assert gs.same_kind("va", "vc") and gs.same_kind("delta2", "delta2") and gs.same_kind("z3", "delta3")
    assert not gs.same_kind("delta2", "ddelta2") and not gs.same_kind("zd3", "z3") and not gs.same_kind("va", "z3")
    terms = build_dictionary(SCALES)
    hinge = terms[_key(terms, "k2_neg_delta2")]
    points = gs.shape_grid(hinge, 1e-3)
    assert min(points) == pytest.approx(-0.75e-3) and max(points) == pytest.approx(0.75e-3) and 0.0 in points
    assert gs.shape_grid(terms[_key(terms, "k2_neg_grow_delta2")], 1e-3) == pytest.approx([2.5e-4, 5e-4, 1e-3, 2e-3])


def test_the_candidates_are_the_same_change_with_another_shape():
    terms = build_dictionary(SCALES)
    grow = terms[_key(terms, "k2_neg_grow_delta2")]
    keys = {terms[k].key for k in gs.shape_candidates(terms, grow)}
    # section 2's stiffness, its side, a position: its own deflection or the tip's swing; its share with the square of
    # the opening
    assert keys == {"k2_neg_delta2", "k2_neg_soft_delta2", "k2_neg_z3", "k2_neg_soft_z3", "k2_neg_grow2_delta2"}
    drive = terms[_key(terms, "d_ep2_pos_soft_va")]
    keys = {terms[k].key for k in gs.shape_candidates(terms, drive)}
    assert keys == {"d_ep2_pos_va", "d_ep2_pos_vc", "d_ep2_pos_grow_vc", "d_ep2_pos_sat_vc",
                    "d_ep2_pos_soft_va"}  # either voltage; a linear rise or a smooth saturation
    assert gs.shape_candidates(terms, terms[_key(terms, "k2_gap_delta2")]) == []
    hinge = terms[_key(terms, "k1_pos_delta1")]  # a sharp switch is probed over the grid itself too
    keys = {terms[k].key for k in gs.shape_candidates(terms, hinge)}
    assert keys == {"k1_pos_delta1", "k1_pos_soft_delta1", "k1_pos_grow_delta1", "k1_pos_grow2_delta1",
                    "k1_pos_z3", "k1_pos_soft_z3"}
    rate = _key(terms, "k3_neg_soft_ddelta3")  # a smooth switch too: its edge over the grid, once per shape
    cands = gs.shape_candidates(terms, terms[rate])
    assert sorted(terms[k].key for k in cands) == ["k3_neg_ddelta3", "k3_neg_soft_ddelta3"] and rate in cands


def test_a_rate_switch_edge_is_probed_from_near_the_sharp_switch():
    # a tip crack switched by δ̇3 < 0 over 0.2 mm/s on a sweep whose δ̇3 reaches 0.88 m/s: the grid, with its zoom
    # (three rounds, × / ÷ 1.5, 1.25, 1.125), reaches it
    terms = build_dictionary(SCALES)
    grid = gs.shape_grid(terms[_key(terms, "k3_neg_soft_ddelta3")], 0.88)
    reach = (1 + gs.SHAPE_STEP) * (1 + gs.SHAPE_STEP / 2) * (1 + gs.SHAPE_STEP / 4)
    assert min(grid) / reach < 2e-4 < max(grid) and max(grid) == pytest.approx(0.088)
    assert gs.shape_grid(terms[_key(terms, "k3_neg_soft_delta3")], 1e-3) == pytest.approx([3e-5, 1e-4, 3e-4, 1e-3])


def _run(monkeypatch, best_key: str, truth_key: str, truth_shape: float, held: float = 26.0):
    """shape_rows on a dictionary whose probes leave 1 σ at ``truth_key`` × ``truth_shape`` (the best refit's size),
    growing with the distance in shape (relative to the grid's span) and size, elsewhere ``held``."""
    terms = build_dictionary(SCALES)
    names = parameter_names_for(terms)
    k_best, k_truth = _key(terms, best_key), _key(terms, truth_key)
    cname, gname = names[k_truth]

    def probe(targets, models, values, settings, threads):
        out = []
        for s in settings:
            if cname in s:
                out.append(1.0 + 40.0 * abs(s[str(gname)] - truth_shape) / 1e-3 + 40.0 * abs(s[cname] + 0.3))
            else:
                out.append(held)
        a = np.array(out)
        return a, a, np.ones(len(a), bool)

    monkeypatch.setattr(scoring, "probe_batch", probe)
    monkeypatch.setattr(scoring, "whole_record_rms", lambda targets, h, t: np.asarray(h))
    monkeypatch.setattr(gs, "whole_rms", lambda targets, out: out.held_rms_sigma)
    setup = SimpleNamespace(terms=terms, names=names, scales=SCALES, targets=[object()], models=[])
    progress = SimpleNamespace(state=SimpleNamespace(values={}), n_sims=0)
    said: list[str] = []
    settings = SimpleNamespace(threads=1, say=said.append)
    outcome = SimpleNamespace(values={names[k_best][0]: -0.3}, held_rms_sigma=held, train_rms_sigma=held)
    best = SimpleNamespace(index=k_best, held_rms_sigma=held, outcome=outcome)
    return gs.shape_rows(setup, progress, settings, best), said, progress


def test_a_hinge_off_zero_comes_back_placed_at_its_point(monkeypatch):
    # the corner at −0.4 mm lies between the grid's points (−0.3, −0.45 mm on a 1 mm scale): the zoom places it
    rows, said, progress = _run(monkeypatch, "k2_neg_grow_delta2", "k2_neg_delta2", -4.0e-4)
    assert rows and rows[0].term.key == "k2_neg_delta2" and rows[0].placed
    assert rows[0].shape == pytest.approx(-4.0e-4, abs=1.3e-5) and rows[0].coef == pytest.approx(-0.3, rel=0.2)
    assert progress.n_sims > 0 and "another gate shape" in said[0]


def test_a_rate_switch_kept_with_the_screen_edge_comes_back_at_its_own(monkeypatch):
    # the screen's edge (0.5 mm/s on a 0.1 m/s scale) refitted stays a factor of four from 0.2 mm/s; the grid, zoomed,
    # places the smooth switch at its edge
    rows, _, _ = _run(monkeypatch, "k3_neg_soft_ddelta3", "k3_neg_soft_ddelta3", 2.0e-4)
    assert rows and rows[0].term.key == "k3_neg_soft_ddelta3"
    assert rows[0].shape == pytest.approx(2.0e-4, rel=0.15)


def test_nothing_comes_back_at_the_noise_or_when_no_shape_is_near(monkeypatch):
    rows, _, _ = _run(monkeypatch, "k2_neg_grow_delta2", "k2_neg_delta2", -4.5e-4, held=1.2)
    assert rows == []
    rows, _, _ = _run(monkeypatch, "k2_neg_grow_delta2", "k2_neg_delta2", 5.0, held=26.0)  # every probe far
    assert rows == []
