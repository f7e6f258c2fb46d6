"""Trends from few visits and intervals that carry the law's uncertainty (issue 28, points 2 and 3).

A trend is evidence when the visits' own precision supports it (three or four precise estimates on a line are a
trend); laws are chosen with a criterion that works at n = 4 (AIC on the visits' own errors, laws admitted by n);
the forecast's interval mixes the laws by their Akaike weights, so it holds each plausible law's own prediction.
"""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from studies.health.forecast import forecast_trip
from studies.health.trend import MIN_VISITS_FOR, fit_trend, paths_of
from studies.health.trip import TripBoundary


def _alpha_only_boundary(lo: float = -0.093, hi: float = 0.148) -> TripBoundary:
    """The monitor's trip limits on α_h, flat in k3 and β_h (as table2's nearly are)."""
    return TripBoundary(np.array([-0.6, 0.3]), np.array([-0.6, 0.6]), np.full((2, 2), lo), np.full((2, 2), hi),
                        "synthetic")


@settings(max_examples=60, deadline=None)
@given(n=st.integers(3, 4), slope=st.floats(1e-5, 3e-4), sign=st.sampled_from([-1.0, 1.0]),
       a=st.floats(-0.02, 0.02), err=st.floats(1e-6, 1e-4), seed=st.integers(0, 10**6))
def test_three_or_four_precise_visits_on_a_line_are_a_trend(n, slope, sign, a, err, seed):
    """Before: the F-test estimated the scale from n − 2 residuals (one or two degrees of freedom) and declared no
    trend from three precise visits whatever their precision."""
    h = np.arange(n) * 400.0
    y = a + sign * slope * h + np.random.default_rng(seed).normal(0.0, err, n)
    t = fit_trend("alpha_h", h, y, np.full(n, err))
    assert t.significant, (t.p_value, t.best.name)
    assert np.sign(t.rate_per_100h(h[-1])) == sign


def test_four_precise_visits_of_an_accelerating_law_give_a_date():
    """The issue's few-visit life: visits every 400 h, α_h accelerating (power 1.6), four estimates to ±0.01 %:
    before, "no significant trend" and a lower bound after the true trip; now a date whose interval holds it."""
    h = np.array([0.0, 400.0, 800.0, 1200.0])
    y = 0.15 * (h / 1900.0) ** 1.6 + np.random.default_rng(3).normal(0.0, 1e-4, 4)
    t = fit_trend("alpha_h", h, y, np.full(4, 1e-4))
    assert t.significant and t.best.name in ("power", "exponential")
    fc = forecast_trip({"alpha_h": t}, _alpha_only_boundary(), 1200.0, 400.0)
    true_trip = 1900.0 * (0.148 / 0.15) ** (1 / 1.6)
    assert fc.significant and fc.trip_interval_90 is not None
    lo, hi = fc.trip_interval_90
    assert lo <= true_trip <= (hi if hi is not None else np.inf)


def test_laws_are_admitted_by_the_number_of_visits():
    h = np.arange(4) * 100.0
    t = fit_trend("k3", h, -1e-4 * h, np.full(4, 1e-3))
    assert {"none", "linear", "exponential", "power"} <= set(t.fits)
    assert "change_point" not in t.fits and MIN_VISITS_FOR["change_point"] == 5
    t3 = fit_trend("k3", h[:3], -1e-4 * h[:3], np.full(3, 1e-3))
    assert set(t3.fits) == {"none", "linear"}
    assert all(np.isfinite(f.ic) for f in t.fits.values())


def test_scatter_beyond_the_errors_is_estimated_not_ignored():
    """Visits that scatter 10 × their errors around a constant: no trend (the scatter term carries them)."""
    rng = np.random.default_rng(5)
    false = 0
    for _ in range(100):
        n = int(rng.integers(4, 11))
        h = np.arange(n) * 100.0
        t = fit_trend("k3", h, rng.normal(0.0, 1e-2, n), np.full(n, 1e-3))
        false += t.significant
        assert t.fits["none"].scatter2 > 0
    assert false <= 10, false


def _median_at(f, h, rng):
    return float(np.median(paths_of(f, np.array([h]), 4000, rng)))


@settings(max_examples=25, deadline=None)
@given(curv=st.floats(0.0, 4e-8), slope=st.floats(2e-5, 1e-4), err=st.floats(2e-4, 2e-3), seed=st.integers(0, 999))
def test_the_averaged_interval_holds_each_plausible_laws_median(curv, slope, err, seed):
    """Five visits a few laws fit: the model-averaged 90 % band far ahead holds the median of every law with an
    Akaike weight of at least 15 % (with the hedge's 20 % of paths elsewhere, such a law still has ≥ 6 % of the
    paths on each side of its median)."""
    h = np.arange(5) * 200.0
    rng = np.random.default_rng(seed)
    y = slope * h + curv * h ** 2 + rng.normal(0.0, err, 5)
    t = fit_trend("alpha_h", h, y, np.full(5, err))
    far = 3 * h[-1]
    paths = t.sample_paths(np.array([far]), 8000, rng)[:, 0]
    lo, hi = np.quantile(paths, [0.05, 0.95])
    for name, w in t.weights.items():
        if w >= 0.15:
            assert lo <= _median_at(t.fits[name], far, rng) <= hi, (name, w, lo, hi)


def test_three_laws_that_fit_five_visits_widen_the_trip_interval():
    """Five visits within their errors of a line and of gently curved laws: before, AICc's small-sample penalty
    (+24 for a three-coefficient law on five visits) gave the curved laws no weight and the trip interval was the
    line's alone; now each law that fits has its weight and the interval holds each one's own trip median."""
    h = np.arange(5) * 300.0
    err = 1.5e-3
    y = np.array([0.0, 0.0186, 0.0377, 0.0602, 0.0860])  # within 1.5e-3 of a line and of a power 1.2 law
    t = fit_trend("alpha_h", h, y, np.full(5, err))
    assert t.significant
    plausible = {k: w for k, w in t.weights.items() if w >= 0.1}
    assert len(plausible) >= 2, t.weights
    tb = _alpha_only_boundary()
    fc = forecast_trip({"alpha_h": t}, tb, h[-1], 300.0, n_paths=4000)
    lo, hi = fc.trip_interval_90
    hi = hi if hi is not None else np.inf
    medians = {}
    for name in plausible:
        alone = type(t)(t.parameter, t.fits[name], t.fits, True, t.p_value, {name: 1.0})
        medians[name] = forecast_trip({"alpha_h": alone}, tb, h[-1], 300.0, n_paths=4000).trip_operating_hours
    assert all(lo <= m <= hi for m in medians.values()), (medians, lo, hi)
    assert max(medians.values()) - min(medians.values()) > 50.0, medians


def test_no_trend_still_gives_a_lower_bound():
    """Three stable visits: no date, but "no FAULT expected before" a time after the last visit."""
    h = np.array([0.0, 100.0, 200.0])
    y = np.array([0.001, -0.0005, 0.0008])
    t = fit_trend("alpha_h", h, y, np.full(3, 1e-3))
    assert not t.significant
    fc = forecast_trip({"alpha_h": t}, _alpha_only_boundary(), 200.0, 100.0)
    assert fc.trip_operating_hours is None and fc.lower_bound_hours is not None and fc.lower_bound_hours > 200.0


def test_a_two_stage_wear_is_fitted_with_its_knee():
    """Two-stage wear (α_h +0.2 % per 100 h, then +1 % per 100 h from a knee at 1000 h, scatter 3e-4 beyond the
    stated errors): before, no candidate law had a knee — the curved laws bent the kink into an acceleration that
    tripped ~500 h early and only the hedge's paths reached the truth (2280 h). The two-stage law (knee searched at
    the visits and midway between them) now places the knee and its interval holds the truth."""
    f = lambda x: 2e-5 * x + 8e-5 * np.maximum(x - 1000.0, 0.0)  # noqa: E731
    for n in (14, 16, 18):
        h = np.arange(n) * 100.0
        y = f(h) + np.random.default_rng(n).normal(0.0, 3e-4, n)
        t = fit_trend("alpha_h", h, y, np.full(n, 5e-6))
        assert t.best.name == "two_stage" and 900.0 <= (t.best.tau or 0.0) <= 1100.0, (t.best.name, t.best.tau)
        fc = forecast_trip({"alpha_h": t}, _alpha_only_boundary(), h[-1], 100.0, n_paths=2000)
        lo, hi = fc.trip_interval_90
        assert lo <= 2280.0 <= (hi if hi is not None else np.inf), (n, lo, hi)


def test_no_hedge_when_the_law_fits_within_the_errors():
    h = np.arange(10) * 100.0
    y = 0.15 * (h / 1200.0) ** 1.5 + np.random.default_rng(2).normal(0.0, 1e-4, 10)
    t = fit_trend("alpha_h", h, y, np.full(10, 1e-4))
    assert t.significant and t.best.scatter2 == 0.0 and t.recent is None
