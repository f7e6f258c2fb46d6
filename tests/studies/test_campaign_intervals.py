"""The campaign's interval arithmetic (issue 15, point 4): the Wilson interval of k detections in n runs always
contains k/n, stays inside [0, 1], and the Fig. 11 error bars built from it are never negative — in particular at
p = 0 and p = 1 for every n (the edges came out a hair on the wrong side of p for n = 40, 60, ..., which failed the
figure with "'yerr' must not contain negative values")."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from studies.campaign.statistics import DetectionStat, wilson_interval


def _check(k: int, n: int, confidence: float = 0.95) -> tuple[float, float]:
    lo, hi = wilson_interval(k, n, confidence)
    p = k / n
    assert 0.0 <= lo <= p <= hi <= 1.0, (k, n, lo, p, hi)
    return lo, hi


def test_edges_for_every_n_up_to_5000():
    """p = 0 and p = 1 exhaustively: lo is exactly 0 at k = 0 and hi exactly 1 at k = n."""
    for n in range(1, 5001):
        lo0, hi0 = _check(0, n)
        lo1, hi1 = _check(n, n)
        assert lo0 == 0.0 and hi1 == 1.0
        assert 0.0 < hi0 < 1.0 and 0.0 < lo1 < 1.0
        assert math.isclose(hi0, 1.0 - lo1, rel_tol=1e-9, abs_tol=1e-12)  # symmetric under k -> n - k


@given(n=st.integers(1, 10**6), frac=st.floats(0.0, 1.0), confidence=st.floats(0.5, 0.999))
def test_interval_contains_the_estimate(n, frac, confidence):
    k = min(n, round(frac * n))
    lo, hi = _check(k, n, confidence)
    lo_c, hi_c = wilson_interval(n - k, n, confidence)
    assert math.isclose(lo, 1.0 - hi_c, abs_tol=1e-9) and math.isclose(hi, 1.0 - lo_c, abs_tol=1e-9)


@given(n=st.integers(1, 2000), frac=st.floats(0.0, 1.0))
def test_wider_confidence_is_a_wider_interval(n, frac):
    k = min(n, round(frac * n))
    lo90, hi90 = wilson_interval(k, n, 0.90)
    lo99, hi99 = wilson_interval(k, n, 0.99)
    assert lo99 <= lo90 + 1e-15 and hi99 >= hi90 - 1e-15


@given(n_runs=st.integers(0, 600), failed_frac=st.floats(0.0, 1.0), det_frac=st.floats(0.0, 1.0))
def test_detection_stat_error_bars_are_never_negative(n_runs, failed_frac, det_frac):
    """What fig11 draws: yerr = [p - lo, hi - p] ≥ 0 (NaN only when no valid run is left)."""
    n_failed = min(n_runs, int(failed_frac * n_runs))
    n_valid = n_runs - n_failed
    s = DetectionStat("a", "MBIT.a", 0.0, 0.1, n_runs, n_failed, min(n_valid, round(det_frac * n_valid)))
    lo, hi = s.interval
    if n_valid == 0:
        assert math.isnan(s.probability) and math.isnan(lo) and math.isnan(hi)
        return
    yerr = np.array([s.probability - lo, hi - s.probability])
    assert np.all(yerr >= 0.0)
    row = s.row()
    assert row["ci95_low"] <= row["probability"] <= row["ci95_high"]


def test_rejects_impossible_counts():
    import pytest

    for k, n in ((-1, 5), (6, 5), (0, -1)):
        with pytest.raises(ValueError):
            wilson_interval(k, n)
    assert all(math.isnan(v) for v in wilson_interval(0, 0))
