"""Find what changes, then trend it (issue 28, point 1): when the default re-estimation leaves more than the noise
or runs to a bound, diagnose names the cause on that visit and health re-estimates and trends that set — an
effect's own parameter (G_leak) as much as a core parameter."""

from __future__ import annotations

import numpy as np
import pytest

from studies.health.cause import VisitDiagnosis, excess_trigger, reestimation_set
from studies.health.estimate import DEFAULT_FREE, VisitEstimates, VisitParameter
from studies.health.follow import Followed, find_and_follow, follow_set, series, trends_upto, why_sentence


def _est(held: float, bound: tuple[str, ...] = (), **rel: float) -> VisitEstimates:
    nominal = {"k3": 100.0, "alpha_h": 0.5, "beta_h": 2.0}
    return VisitEstimates(tuple(
        VisitParameter(n, nominal[n] * (1 + rel.get(n, 0.0)), 1e-4 * nominal[n], nominal[n], "1", n in bound)
        for n in DEFAULT_FREE), held, held, 0.0)


def test_excess_is_the_latest_visit_beyond_the_noise_or_at_a_bound():
    assert excess_trigger([_est(1.0), _est(1.1), _est(1.4)]) is None
    i, why = excess_trigger([_est(1.0), _est(2.0), _est(1.2)])
    assert i == 1 and "held-out" in why
    # a board visit leaves 1.8 sigma at entry: 1.5 x that is the bar, not 1.5 sigma
    assert excess_trigger([_est(1.8), _est(2.6)]) is None
    i, why = excess_trigger([_est(1.0), _est(1.0, bound=("k3",))])
    assert i == 1 and "k3" in why and "bound" in why


def test_an_effect_is_followed_by_its_own_parameter():
    assert reestimation_set(["dielectric_leakage"]) == (("dielectric_leakage",), ("G_leak",))
    assert follow_set(["dielectric_leakage"]) == (("dielectric_leakage",), ("G_leak",))
    # a section the default set does not free replaces k3 (which stands for any section); hysteresis stays
    assert follow_set(["k2"]) == ((), ("k2", "alpha_h", "beta_h"))
    # what the default set covers keeps the default set
    assert follow_set(["alpha_h", "k3"]) is None and follow_set([]) is None


def test_find_and_follow_diagnoses_once_and_reestimates_the_named_set(monkeypatch):
    calls = []

    def fake_diagnose(records, params, base, candidates=()):
        calls.append((records, base))
        return VisitDiagnosis(("dielectric_leakage",), "missing", "Missing effect", 0.1)

    monkeypatch.setattr("studies.health.follow.diagnose_visit", fake_diagnose)
    ests = [_est(1.0, k3=0.01), _est(1.1), _est(9.0, k3=0.3)]
    got = []

    def reestimate(effects, free, base):
        got.append((effects, free, base))
        return [VisitEstimates((VisitParameter("G_leak", 1e-4 * i, 1e-8, 0.0, "S"),), 1.0, 1.0, 0.0)
                for i in range(3)]

    f = find_and_follow(ests, lambda i: [f"record {i}"], "table2", reestimate)
    assert f.switched and f.free == ("G_leak",) and f.diagnosed_visit == 2
    assert calls == [(["record 2"], {"k3": 101.0, "alpha_h": 0.5, "beta_h": 2.0})]  # the first visit's fitted set
    assert got[0][:2] == (("dielectric_leakage",), ("G_leak",))
    text = why_sentence(f, [0.0, 100.0, 200.0])
    assert "at 200 h" in text and "G_leak" in text and "dielectric_leakage" in text
    assert f.estimates is not None
    y, s = series(f.estimates, f.free)
    assert np.allclose(y["G_leak"], [0.0, 1e-4, 2e-4])  # in its own unit, not relative to a nominal of 0
    t = trends_upto([0.0, 100.0, 200.0], y, s, 3)["G_leak"]
    assert t.significant and t.rate_per_100h(200.0) == pytest.approx(1e-4, rel=1e-3)


def test_without_excess_nothing_is_diagnosed(monkeypatch):
    def boom(*a, **k):
        raise AssertionError("diagnose must not run")

    monkeypatch.setattr("studies.health.follow.diagnose_visit", boom)
    f = find_and_follow([_est(1.0), _est(1.2)], lambda i: [], "table2", boom)
    assert f == Followed() and "default fit explained each visit" in why_sentence(f, [0.0, 100.0])


@pytest.mark.slow
def test_docs_leakage_recipe_is_followed_to_the_leak(tmp_path):
    """docs/health.md's recipe ("following the cause"): five synthetic visits of a leaking patch; shm health names
    the leakage, trends G_leak and forecasts the trip the truth reaches at 1850 h (0.74 mS at 0.4 µS/h)."""
    import json
    import os
    import re
    import subprocess
    import sys
    from pathlib import Path

    doc = Path(__file__).resolve().parents[2] / "docs" / "health.md"
    text = doc.read_text()
    section = text[text.index("### What changes: following the cause"):]
    recipe = re.search(r"```sh\n(.*?)```", section, re.S)
    assert recipe is not None
    env = dict(os.environ, PATH=str(Path(sys.executable).parent) + os.pathsep + os.environ.get("PATH", ""))
    (tmp_path / "records").mkdir()
    res = subprocess.run(["bash", "-e", "-c", recipe.group(1)], cwd=tmp_path, env=env, capture_output=True,
                         text=True, timeout=900)
    assert res.returncode == 0, res.stderr[-2000:]
    h = json.loads((tmp_path / "out" / "health.json").read_text())
    assert h["followed"]["switched"] and h["followed"]["named"] == ["dielectric_leakage"]
    assert h["followed"]["free"] == ["G_leak"] and h["trend"]["G_leak"]["significant"]
    lo, hi = h["forecast"]["trip_interval_90"]
    assert lo <= 1850.0 <= hi
    assert "FOLLOWED" in res.stdout and "dielectric_leakage" in res.stdout


def test_an_effect_parameter_trips_at_its_own_limit():
    """G_leak rising 0.4 µS/h, five precise visits: the forecast trips where the trend reaches the monitor's limit
    for G_leak (0.74 mS: 1850 h), not on the α_h boundary (no α_h trend at all)."""
    from studies.health.forecast import forecast_trip
    from studies.health.trend import fit_trend
    from studies.health.trip import TripBoundary

    boundary = TripBoundary(np.array([-0.6, 0.3]), np.array([-0.6, 0.6]), np.full((2, 2), -0.093),
                            np.full((2, 2), 0.148), "synthetic")
    h = np.arange(5) * 200.0
    g = 4e-7 * h + np.random.default_rng(1).normal(0.0, 1e-8, 5)
    t = fit_trend("G_leak", h, g, np.full(5, 1e-8), floor=1e-7)
    fc = forecast_trip({"G_leak": t}, boundary, 800.0, 200.0, effect_limits={"G_leak": 7.4e-4})
    assert fc.significant and fc.trip_interval_90 is not None
    lo, hi = fc.trip_interval_90
    assert lo <= 1850.0 <= hi and abs(fc.trip_operating_hours - 1850.0) < 60.0
    no_limit = forecast_trip({"G_leak": t}, boundary, 800.0, 200.0)
    assert no_limit.trip_operating_hours is None  # without its limit the effect never trips the α_h boundary


def test_the_followed_section_and_the_localisation_are_compared():
    """A k2 loss followed by its own stiffness: the page says whether the localisation's possible sections hold
    it (sections 1 and 2 cannot be told apart with the MBITs) or not."""
    from studies.health.four_levels import _cause_place, _section_agreement

    fol = {"free": ["k2", "alpha_h", "beta_h"], "effects": [], "switched": True}
    assert "section 2" in _cause_place(fol)
    assert "they agree" in _section_agreement(fol, {"possible_sections": [1, 2], "section": None})
    assert "disagree" in _section_agreement(fol, {"possible_sections": [3], "section": 3})
    assert _section_agreement({"free": ["G_leak"]}, {"possible_sections": [3]}) == ""


def test_a_second_diagnosis_when_the_set_in_use_leaves_growing_residual():
    """The challenge's sequential prognosis diagnoses at the first excess and again (at most three times) when the
    set in use leaves 1.5 × the residual it left at the visit last diagnosed: a k2 loss growing beside an α_h drift
    was named "alpha_h" at 300 h and would have been trended as k3 for good."""
    from studies.health.challenge import needs_diagnosis

    ests = [_est(h) for h in (1.0, 2.0, 2.5, 3.5)]
    assert needs_diagnosis(Followed(), ests, 1, 0)
    kept = Followed(diagnosed_visit=1, named=["alpha_h"])
    assert not needs_diagnosis(kept, ests, 2, 1)  # 2.5 < 1.5 x 2.0
    assert needs_diagnosis(kept, ests, 3, 1)  # 3.5 > 3.0
    assert not needs_diagnosis(kept, ests, 3, 3)  # the cap
    switched = Followed(diagnosed_visit=1, named=["dielectric_leakage"], free=("G_leak",),
                        estimates=[_est(1.0) for _ in range(4)])
    assert not needs_diagnosis(switched, ests, 3, 1)  # the followed set explains the visits
