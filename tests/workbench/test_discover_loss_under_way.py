"""A change under way before the record began (issue 26 point 3, the time gates' family): the dictionary's ramp may
start before t = 0 — c·(t − G) with G < 0 is a share of the loss already there when the record starts and the rest
growing through it (a root loss begun before a 15 s sweep left 16.5 σ: the library's drifts, or a constant loss
and a ramp from inside the record, could not say it). Screened, said and emitted so."""

from __future__ import annotations

import re

import pytest

from board_config.parameter import Parameter
from workbench.discover._dictionary import Term, build_dictionary
from workbench.discover._dictionary_code import dictionary_parameter_names, dictionary_source
from workbench.discover._effect_writer import describe_term, emit_effect_source, parameter_names_for
from workbench.discover._gates import CONTRIBUTIONS, GATED_BY, RAMP_BEFORE_AT, RAMP_BEFORE_REACH, onset_floor

SCALES = {"delta1": 1e-3, "ddelta1": 0.1, "delta2": 1e-3, "ddelta2": 0.1, "delta3": 1e-3, "ddelta3": 0.1,
          "z3": 1e-3, "va": 100.0, "vc": 50.0, "t": 15.0}


def _before(terms: list[Term]) -> list[Term]:
    return [t for t in terms if t.form == "on_ramp" and t.shape < 0.0]


def test_every_time_gated_parameter_and_place_has_one_ramp_begun_before_the_record():
    terms = build_dictionary(SCALES)
    before = _before(terms)
    timed = {(p, i) for p, gates in GATED_BY.items() if "time" in gates
             for i in (range(3) if CONTRIBUTIONS[p].per != "patch" else (-1,))}
    assert {(t.param, t.index) for t in before} == timed and len(before) == len(timed)
    for t in before:
        assert t.shape == RAMP_BEFORE_AT * 15.0 == -7.5
        assert t.shape_range == (-RAMP_BEFORE_REACH * 15.0, 0.0)
    inside = [t for t in terms if t.form == "on_ramp" and t.shape >= 0.0]
    assert all(t.shape_range is not None and t.shape_range[0] >= 0.0 for t in inside)  # the others stay inside
    assert not _before(build_dictionary({k: v for k, v in SCALES.items() if k != "t"}))


def test_the_dictionary_lets_a_ramp_onset_go_below_zero_and_a_step_onset_not():
    terms = build_dictionary(SCALES)
    src = dictionary_source(terms)
    lows = dict(re.findall(r"Parameter\('(g_\d+)', 's', [0-9.e+-]+, ([^,]+),", src))
    for t, (_, g) in zip(terms, dictionary_parameter_names(terms)):
        if t.form in ("on_step", "on_ramp"):
            assert lows[str(g)] == ("-math.inf" if t.form == "on_ramp" else "0.0"), t.key


def test_a_refit_window_stays_in_the_record_for_an_onset_inside_it_and_free_before_it():
    assert onset_floor(0.3, 0.5) == 0.0 and onset_floor(2.0, 0.5) == 1.5
    assert onset_floor(-7.5, 0.5) == -8.0 and onset_floor(-0.2, 0.5) == pytest.approx(-0.7)


def test_a_loss_under_way_is_said_with_its_share_at_the_start_its_rate_and_when_it_began():
    words = describe_term(Term("damage", 0, "one", "on_ramp", -7.5, "k", (-30.0, 0.0)), -0.01, -7.5, 1.0, 0.2)
    assert words.startswith("section 1 had already lost 7.5 % of its stiffness when the record began and went on "
                            "losing 1 %/s through it")
    assert "at that rate it began about 7.5 s before the record" in words
    damping = describe_term(Term("damage", 2, "one", "on_ramp", -2.0, "c", (-30.0, 0.0)), 0.05, -2.0, 1.0)
    assert damping.startswith("damping c3 of section 3 already 10 % higher when the record began and rising by 5 %/s")
    inside = describe_term(Term("damage", 0, "one", "on_ramp", 2.0, "k", (0.0, 7.5)), -0.01, 2.0, 1.0)
    assert "falling by 1 %/s from t = 2 s on" in inside  # a ramp begun inside the record is said as before


def test_the_emitted_loss_under_way_loads_and_simulates_the_loss_written_by_hand(tmp_path):
    """The emitted file against the same drift written from the plant's seam: k1 lower by 30 % × (t + 0.75 s)/3 s on
    a 1.5 s sweep — 7.5 % at its start, 22.5 % at its end."""
    from emitted_effect_support import emitted_against_hand

    from plant import PhysicalEffect, resolve_effect

    class HandDrift(PhysicalEffect):
        name = "hand_drift_begun_before"
        description = "k1 lower by loss·(t + 0.75 s)/3 s"
        parameters = (Parameter("loss", "1", 0.0, 0.0, 0.9, "loss", neutral=0.0),)

        @staticmethod
        def rates(t, x, p, bus, dx, X, P, B):
            bus[B.s1] += p[P.loss] * max(0.0, (t + 0.75) / 3.0) * p[P.k1] * x[X.delta1]

    term = Term("damage", 0, "one", "on_ramp", -0.75, "k", (-3.0, 0.0))
    (c, g), = parameter_names_for([term])
    f = tmp_path / "drift.py"
    f.write_text(emit_effect_source([term], {c: -0.1, g: -0.75}))
    cls = resolve_effect(str(f))
    rng = cls.fit_range(str(g))
    assert rng.lower < -0.75 < rng.upper  # the file loads with its onset before the record, and a refit may move it
    moved, apart = emitted_against_hand(tmp_path, term, {c: -0.1, g: -0.75}, HandDrift, {"loss": 0.3})
    assert moved > 1e-7 and apart <= 1e-3 * moved


def test_the_ramp_begun_before_the_record_is_probed_at_its_own_onset_and_the_others_at_the_residuals(monkeypatch):
    """The onset probe: steps and the ramp inside the record at the instant the residual changes (t0 = 6 s of a
    15 s record), the ramp begun before it at its own onset (−7.5 s) — at the same total changes over the time
    left from there (22.5 s) — each under its own key, the best of each returned with the onset it was probed at."""
    import numpy as np

    from workbench.discover import _onset
    from workbench.discover._results import ScreenRow

    ramp_in = Term("damage", 0, "one", "on_ramp", 3.75, "k", (0.0, 7.5))
    ramp_before = Term("damage", 0, "one", "on_ramp", -7.5, "k", (-30.0, 0.0))
    step = Term("damage", 0, "one", "on_step", 1.875, "k", (0.0, 3.75))
    names = {ramp_in: ("a_0", "g_0"), ramp_before: ("a_1", "g_1"), step: ("a_2", "g_2")}
    seen: list[dict[str, float]] = []

    def fake_batch(targets, models, values, settings, threads):
        seen.extend(settings)  # the error is least for the ramp begun before, at −15 % over its 22.5 s
        err = [abs(s.get("a_1", 1.0) * 22.5 + 0.15) + 1.0 if "a_1" in s else 50.0 for s in settings]
        return np.array(err), np.array(err), np.ones(len(settings), bool)

    monkeypatch.setattr(_onset, "probe_batch", fake_batch)
    rows = [ScreenRow(t, 0.0, 9.0, 9.0) for t in (ramp_in, ramp_before, step)]
    out, n = _onset.onset_probe(rows, names, [], [], {}, 6.0, 15.0, 1)
    before = [s for s in seen if "a_1" in s]
    assert before and all(s["g_1"] == -7.5 for s in before)
    assert {round(s["a_1"] * 22.5, 6) for s in before} >= {-0.3, -0.1, 0.1, 0.3}
    assert all(s["g_0"] == 6.0 for s in seen if "a_0" in s) and any("a_0" in s for s in seen)
    assert out[0].term is ramp_before and out[0].shape == -7.5 and out[0].coef * 22.5 == pytest.approx(-0.15, rel=0.2)
    assert {_onset.probe_key(r.term) for r in out} == {"k1_ramp_t", "k1_ramp_t before", "k1_step_t"}
    assert n == len(seen)


def test_an_emitted_onset_inside_the_record_stays_at_or_after_its_start_and_one_before_it_may_move_back(tmp_path):
    from plant import resolve_effect

    terms = [Term("damage", 1, "one", "on_step", 4.0, "k", (2.0, 6.0)),
             Term("damage", 0, "one", "on_ramp", -3.0, "k", (-20.0, 0.0))]
    names = parameter_names_for(terms)
    f = tmp_path / "two.py"
    f.write_text(emit_effect_source(terms, {names[0][0]: -0.2, str(names[0][1]): 4.0,
                                            names[1][0]: -0.01, str(names[1][1]): -3.0}))
    lows = {p.name: p.lower for p in resolve_effect(str(f)).own_parameters()}
    assert lows[str(names[0][1])] == 0.0 and lows[str(names[1][1])] < -20.0
    assert all(t.before_record == (t.shape < 0) for t in terms)
