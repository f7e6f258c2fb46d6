"""The campaign's Wilson interval against an independent oracle (SciPy's binomtest, Wilson method) and its input
limits; the detection-statistics row is exact."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.stats import binomtest

from studies.campaign.statistics import DetectionStat, wilson_interval


@settings(max_examples=80, deadline=None)
@given(st.integers(1, 400), st.floats(0.0, 1.0), st.sampled_from([0.5, 0.8, 0.9, 0.95, 0.99, 0.999]))
def test_equals_scipys_wilson_interval(n, frac, confidence):
    k = round(frac * n)
    ci = binomtest(k, n).proportion_ci(confidence_level=confidence, method="wilson")
    lo, hi = wilson_interval(k, n, confidence)
    assert lo == pytest.approx(ci.low, abs=1e-12) and hi == pytest.approx(ci.high, abs=1e-12)


def test_textbook_values():
    assert wilson_interval(5, 10) == pytest.approx((0.2365931, 0.7634069), abs=1e-7)
    assert wilson_interval(0, 10) == pytest.approx((0.0, 0.2775328), abs=1e-7)
    assert wilson_interval(10, 10) == pytest.approx((0.7224672, 1.0), abs=1e-7)
    assert wilson_interval(1, 1, 0.5)[1] == 1.0


def test_limits_of_the_inputs():
    assert all(math.isnan(x) for x in wilson_interval(0, 0))
    for bad in (0.0, 1.0, -0.1, 1.5):
        with pytest.raises(ValueError, match="confidence must be in"):
            wilson_interval(1, 2, bad)
    for k, n in ((-1, 3), (4, 3), (0, -1)):
        with pytest.raises(ValueError, match=f"k={k}, n={n}"):
            wilson_interval(k, n)
    wilson_interval(3, 3)  # k == n is fine


def test_detection_stat_row():
    s = DetectionStat("a", "MBIT.a", 0.1, 0.2, n_runs=12, n_failed=2, n_detected=4)
    lo, hi = wilson_interval(4, 10)
    assert (s.n_valid, s.probability, s.interval, s.range_label) == (10, 0.4, (lo, hi), "10-20%")
    assert s.row() == {"mbit": "a", "label": "MBIT.a", "range_lo_pct": pytest.approx(10.0),
                       "range_hi_pct": pytest.approx(20.0), "n_runs": 12, "n_failed": 2, "n_detected": 4,
                       "probability": 0.4, "ci95_low": lo, "ci95_high": hi}
    empty = DetectionStat("any", "any", 0.0, 0.05, n_runs=3, n_failed=3, n_detected=0)
    assert empty.n_valid == 0 and math.isnan(empty.probability) and all(math.isnan(x) for x in empty.interval)
    assert empty.range_label == "0-5%"
