"""A change that accelerates and arrests (issue 26 point 3, the time gates' family): the dictionary's ramp at a
negative width −T grows as min((t − t0)⁺, T)²/T — zero slope at its onset, steepest at its end, then held — is probed
from a kept step or ramp, said as a loss that grew faster and faster and held, and emitted so."""

from __future__ import annotations

import math

import pytest

from board_config.parameter import Parameter
from workbench.discover._dictionary import Term
from workbench.discover._effect_writer import describe_term, emit_effect_source, parameter_names_for
from workbench.discover._gates import RAMP_NEVER_S, WIDTH_CODE
from workbench.discover._smooth_change import (
    Edge,
    EdgeProbe,
    candidate_edges,
    edge_free,
    simplex_edge,
    zoom_edge,
)

SCALES = {"delta1": 1e-3, "ddelta1": 0.1, "delta2": 1e-3, "ddelta2": 0.1, "t": 15.0}


def _ramp(t: float, g: float, h: float) -> float:
    return float(eval(WIDTH_CODE["on_ramp"].replace("G", repr(g)).replace("H", f"({h!r})"), {"math": math, "t": t}))


def test_a_ramp_of_negative_width_grows_quadratically_from_rest_and_holds_after_its_growth_time():
    g, span = 4.5, 9.0
    assert _ramp(3.0, g, -span) == 0.0 and _ramp(g, g, -span) == 0.0
    assert _ramp(g + 3.0, g, -span) == pytest.approx(9.0 / span)  # (t − t0)² / T
    assert _ramp(g + span, g, -span) == pytest.approx(span) == _ramp(g + span + 5.0, g, -span)  # held at rate·T
    slope_start = (_ramp(g + 0.01, g, -span) - _ramp(g, g, -span)) / 0.01
    slope_end = (_ramp(g + span, g, -span) - _ramp(g + span - 0.01, g, -span)) / 0.01
    assert slope_start < 0.01 and slope_end == pytest.approx(2.0, rel=0.01)
    assert _ramp(g + 2.0, g, 1e12) == pytest.approx(2.0)  # a positive width is the settling ramp as before
    assert _ramp(g + 2.0, g, 1.0) == pytest.approx(1.0 - math.exp(-2.0))


def test_the_dictionary_lets_a_ramp_width_go_negative_and_a_step_width_not():
    import re

    from workbench.discover._dictionary import build_dictionary
    from workbench.discover._dictionary_code import dictionary_source, dictionary_width_names

    terms = build_dictionary(SCALES)
    src = dictionary_source(terms)
    lows = dict(re.findall(r"Parameter\('(h_\d+)', '[^']+', [0-9.e+-]+, ([^,]+),", src))
    for k, h in dictionary_width_names(terms).items():
        assert lows[h] == ("-math.inf" if terms[k].form == "on_ramp" else "1e-12"), terms[k].key
    assert re.search(r"min\(max\(t - p\[po \+ \d+\], 0\.0\), -p\[po \+ \d+\]\) \*\* 2 / -p\[po \+ \d+\]", src)


def test_an_accelerating_loss_is_said_with_its_start_end_and_total():
    term = Term("damage", 1, "one", "on_ramp", 4.5, "k", (3.0, 6.0), width=-9.0)
    words = describe_term(term, -0.02, 4.5, 1.0, 0.01)
    assert words.startswith("section 2 lost 18 % of its stiffness between t = 4.50 ± 0.01 s and t = 13.5 s, faster "
                            "and faster (quadratic in time: a quarter of it by t = 9 s), then held")
    assert "accelerated and arrested" in words
    damping = describe_term(Term("damage", 2, "one", "on_ramp", 2.0, "c", (1.0, 3.0), width=-4.0), 0.5, 2.0, 1.0)
    assert "rose by 200 %" in damping and "accelerated, then held" in damping


def test_the_emitted_accelerating_loss_simulates_the_loss_written_by_hand(tmp_path):
    """The emitted file against the same loss written from the plant's seam: k2 lower by 20 % growing as
    ((t − 0.3 s)/0.8 s)² on a 1.5 s sweep, held from 1.1 s."""
    from emitted_effect_support import emitted_against_hand

    from plant import PhysicalEffect

    class HandAccel(PhysicalEffect):
        name = "hand_accelerating_loss"
        description = "k2 lower by loss·min(1, ((t − 0.3)/0.8)²)"
        parameters = (Parameter("loss", "1", 0.0, 0.0, 0.9, "loss", neutral=0.0),)

        @staticmethod
        def rates(t, x, p, bus, dx, X, P, B):
            s = min(1.0, max(0.0, (t - 0.3) / 0.8))
            bus[B.s2] += p[P.loss] * s * s * p[P.k2] * x[X.delta2]

    term = Term("damage", 1, "one", "on_ramp", 0.3, "k", (0.1, 0.5), width=-0.8)
    (c, g), = parameter_names_for([term])
    assert "min((t − g_k2_ramp_t)⁺, 0.8 s)² / 0.8 s" in emit_effect_source([term], {c: -0.25, g: 0.3})
    moved, apart = emitted_against_hand(tmp_path, term, {c: -0.2 / 0.8, g: 0.3}, HandAccel, {"loss": 0.2})
    assert moved > 1e-7 and apart <= 1e-3 * moved


def test_accelerating_edges_start_before_a_kept_step_or_at_and_before_a_kept_ramp_and_end_in_the_record():
    from_step = candidate_edges("on_step", -0.18, 10.0, 15.0, "accelerate")
    assert from_step and all(e.width < 0.0 and e.centre < 10.0 for e in from_step)
    assert all(e.centre - e.width > 10.0 for e in from_step)  # the step lies inside the growth
    assert {round(e.total, 4) for e in from_step} == {-0.144, -0.18, -0.225}
    from_ramp = candidate_edges("on_ramp", -0.025, 6.5, 15.0, "accelerate")
    assert max(e.centre for e in from_ramp) == 6.5 and min(e.centre for e in from_ramp) < 4.5
    assert all(e.width < 0.0 and e.centre - e.width <= 15.0 + 1e-9 for e in from_ramp)
    # the ramp's change to the end, and half
    assert sorted({round(e.total, 5) for e in from_ramp}) == [-0.2125, -0.10625]
    probe = EdgeProbe([], [], {}, ("a_1", "g_1", "h_1"), None, "on_ramp")
    assert probe.setting(Edge(4.5, -9.0, -0.18)) == {"a_1": -0.02, "g_1": 4.5, "h_1": -9.0}  # rate: total ÷ T


class _Bowl(EdgeProbe):
    """Whole-record RMS as the distance to a true accelerating loss (start 4.5 s, growth 9 s, total −0.18)."""

    def scores(self, edges):
        return [1.0 + abs(e.centre - 4.5) + abs(math.log(e.width / -9.0)) + 10 * abs(e.total + 0.18) for e in edges]


def test_the_simplex_search_walks_start_end_and_total_to_a_narrow_minimum():
    probe = _Bowl([], [], {}, ("a_1", "g_1", "h_1"), None, "on_ramp")
    first = candidate_edges("on_ramp", -0.029, 7.7, 15.0, "accelerate")
    assert min(probe.scores(first)) > 2.0
    edge, score, n = simplex_edge(probe, first, 15.0)
    assert edge.width < 0.0 and abs(edge.centre - 4.5) < 0.05 and abs(edge.width + 9.0) < 0.1
    assert abs(edge.total + 0.18) < 0.002 and score < 1.1 and n <= len(first) + 4 * 250
    far = _Bowl([], [], {}, ("a_1", "g_1", "h_1"), None, "on_ramp")
    assert zoom_edge(far, first, 15.0)[1] > score  # the S-curve's zoom stops short of it


def test_the_refit_frees_a_negative_growth_time_linearly_and_its_start_by_a_quarter_of_it():
    from discover_slots import kept_slot

    s = kept_slot(SCALES, "k2_ramp_t", -0.02, 4.5, -9.0)
    c, g, h, k = s["c"], s["g"], s["h"], s["k"]
    free = {p.name: p for p in edge_free(s["terms"], s["names"], s["state"], dict(s["state"].values), k, k, 15.0)}
    assert set(free) == {c, g, h}
    assert free[h].lower == -27.0 and free[h].upper == pytest.approx(-3.0) and not free[h].log
    assert free[g].lower == pytest.approx(2.25) and free[g].upper == pytest.approx(6.75)


def test_a_change_of_another_parameter_starts_from_the_static_twin_in_that_parameters_ramp(monkeypatch):
    """A patch's authority rising faster and faster (not how damage moves it) is also tried as the stiffness of
    its section lost faster and faster: the accelerating change in a ramp slot of k, from −c/(1 + c)."""
    from discover_slots import kept_slot

    import workbench.discover._smooth_change as sc

    s = kept_slot(SCALES, "d_ep2_ramp_t", 0.03, 6.0, RAMP_NEVER_S)
    terms, names, kept = s["terms"], s["names"], s["k"]
    like = next(i for i, t in enumerate(terms) if t.key == "k2_step_t")
    seen = {}

    def simplex(probe, first, t_end):
        seen.update(names=probe.names, first=first)

    monkeypatch.setattr(sc, "simplex_edge", simplex)
    assert sc.smooth_refit([], [], terms, names, s["state"], kept, 15.0, None, 5, "accelerate", like) is None
    ramp = next(i for i, t in enumerate(terms) if t.key == "k2_ramp_t")
    assert seen["names"][:2] == (names[ramp][0], names[ramp][1])
    assert all(e.total < 0.0 for e in seen["first"])  # a stiffness lost where the authority rose
    assert sc.smooth_refit([], [], terms, names, s["state"], kept, 15.0, None, 5, "recover", like) is None


def test_an_accelerating_change_grows_over_at_least_a_hundredth_of_the_record():
    """Quicker, it is a step: a 15 % loss of k2 at 11.0 s of MBIT.a was said as accelerating "between t = 11 s and
    t = 11 s"."""
    from discover_slots import kept_slot

    from workbench.discover._smooth_change import ACCEL_MIN_SHARE

    late = candidate_edges("on_ramp", -0.02, 14.95, 15.0, "accelerate")
    assert late and all(e.width <= -ACCEL_MIN_SHARE * 15.0 for e in late)
    tried: list[Edge] = []

    class _Step(EdgeProbe):  # best as a step at 11 s: the shorter the growth, the better
        def scores(self, edges):
            tried.extend(edges)
            return [1.0 + abs(e.centre - 11.0) + 5 * abs(e.total + 0.15) + 0.1 * abs(e.width) for e in edges]

    probe = _Step([], [], {}, ("a_1", "g_1", "h_1"), None, "on_ramp")
    edge, _, _ = simplex_edge(probe, candidate_edges("on_step", -0.15, 11.0, 15.0, "accelerate"), 15.0)
    assert min(-e.width for e in tried) >= ACCEL_MIN_SHARE * 15.0 and -edge.width >= ACCEL_MIN_SHARE * 15.0
    assert -edge.width < 0.5  # pressed against the bound
    s = kept_slot(SCALES, "k2_ramp_t", -1.0, 11.0, -0.05)  # a growth time below the least: the refit still bounds it
    free = {p.name: p for p in edge_free(s["terms"], s["names"], s["state"], dict(s["state"].values), s["k"], s["k"],
                                         15.0)}
    assert free[s["h"]].lower < free[s["h"]].upper == -ACCEL_MIN_SHARE * 15.0
