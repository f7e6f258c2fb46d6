"""Issue 31 point 6: what each fleet worker pays in memory. A board's forecast asks the monitor's trip boundary about
millions of points (2000 paths × 1500 times); interpolated at once, the temporaries were ~0.5 GB that every fresh
worker process faulted in page by page in its first board (0.5 s of CPU in the kernel) and that two workers pushed
through the shared cache side by side. In slices the answer is the same, point for point, and the memory small."""

from __future__ import annotations

import tracemalloc

import numpy as np

from studies.health import trip
from studies.health.trip import TripBoundary


def _boundary() -> TripBoundary:
    k3, beta = np.linspace(-0.5, 0.5, 11), np.linspace(-0.5, 0.5, 9)
    lo = -0.2 - 0.1 * np.add.outer(k3, beta) ** 2
    hi = 0.2 + 0.1 * np.add.outer(k3, -beta)
    lo[0, 0], hi[-1, -1] = -np.inf, np.inf  # no trip down / up to the span's end
    return TripBoundary(k3, beta, lo, hi, "test")


def test_the_trip_boundary_answers_a_forecasts_points_in_slices_the_same_as_at_once(monkeypatch) -> None:
    b = _boundary()
    devs = np.random.default_rng(3).normal(0.0, 0.25, (800, 500, 3))  # 400 000 points, 9.6 MB
    b.fault(devs[:1])  # scipy.interpolate imported outside the count
    tracemalloc.start()
    try:
        sliced = b.fault(devs)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 12e6, f"{peak / 1e6:.1f} MB for 400 000 points"  # at once: ~36 MB of temporaries
    monkeypatch.setattr(trip, "FAULT_SLICE", 10**9)
    assert sliced.shape == (800, 500) and 0.05 < sliced.mean() < 0.95
    assert np.array_equal(sliced, b.fault(devs))
