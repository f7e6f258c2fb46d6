"""Usage acquisition: streaming turning points + rainflow equal the reference, gate, exceedance, peaks."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from firmware_sim.usage import TurningPoints, UsageEpisode, cycles_of_series, rainflow_cycles


def _sorted(c):
    """Cycles comparable across implementations; zero-range 'cycles' (rainflow counts a flat series as one) carry
    no load and are dropped (below 1e-12 m, far under any sensor resolution)."""
    return sorted((round(r, 12), round(m, 12), n) for r, m, n in c if r > 1e-12)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.integers(-10_000, 10_000), min_size=3, max_size=200))
def test_streaming_cycles_equal_rainflow_on_the_full_series(counts):
    # samples on a 0.1 um grid, as an ADC delivers them (the rainflow package mishandles subnormal differences)
    xs = [c * 1e-7 for c in counts]
    tp = TurningPoints(0.0)
    for i, x in enumerate(xs):
        tp.add(i * 0.01, x)
    assert _sorted(rainflow_cycles(tp.series())) == _sorted(cycles_of_series(np.array(xs)))


def test_gate_removes_noise_cycles_but_keeps_the_load_cycles():
    rng = np.random.default_rng(0)
    t = np.arange(0, 10, 0.01)
    load = 1e-3 * np.sin(2 * np.pi * 0.5 * t)  # 5 cycles of 2 mm range
    noisy = load + 3e-5 * rng.standard_normal(t.size)  # 30 um noise: reversals at every slow part
    raw = cycles_of_series(noisy)
    tp = TurningPoints(gate=2e-4)
    for ti, x in zip(t, noisy):
        tp.add(ti, x)
    gated = rainflow_cycles(tp.series())
    assert sum(c for _, _, c in raw) > 100  # noise makes hundreds of tiny cycles
    big = [r for r, _, c in gated if r > 1e-3]
    assert sum(c for r, _, c in gated if r > 1e-3) == pytest.approx(5.0, abs=0.5)
    assert max(big) == pytest.approx(2e-3, rel=0.1)  # the noise peaks ride on the load peaks
    assert sum(c for _, _, c in gated) < 7


def test_episode_peaks_exceedance_and_record():
    dt = 0.01
    ep = UsageEpisode(100.0, dt, levels=(0.5e-3, 1e-3, 2e-3), gate=0.0, bin_width=0.25e-3)
    t = 100.0 + np.arange(0, 4, dt)
    z = 1.5e-3 * np.sin(2 * np.pi * 1.0 * (t - 100.0))  # 4 cycles, |z| peaks 1.5 mm
    for ti, zi in zip(t, z):
        ep.add(ti, zi, 3.0 * np.sign(zi))
    ep.add(104.0, float("nan"), 0.0)  # skipped
    s = ep.summary(104.0, "quiet")
    assert s.samples == t.size
    assert s.peak_z3 == pytest.approx(1.5e-3, rel=1e-3)
    assert s.peak_z0dd == 3.0
    # time above 1 mm: fraction of a sine above 2/3 of its amplitude = 1 - 2*asin(2/3)/pi
    frac = 1 - 2 * np.arcsin(1 / 1.5) / np.pi
    assert s.exceedance_time[1] == pytest.approx(4 * frac, abs=0.03)
    assert s.exceedance_time[2] == 0.0
    assert s.exceedance_count[1] == 8  # two up-crossings of |z| per cycle
    assert s.n_cycles == pytest.approx(4.0, abs=0.5)
    rec = s.as_record()
    assert rec["reason"] == "quiet" and rec["duration_s"] == pytest.approx(4.0)
    hist = json.loads(rec["rainflow_json"])
    assert sum(b["cycles"] for b in hist) == pytest.approx(s.n_cycles)
    assert all(b["range_high_m"] - b["range_low_m"] == pytest.approx(0.25e-3) for b in hist)


def test_gate_must_be_non_negative():
    with pytest.raises(ValueError, match="gate"):
        TurningPoints(-1.0)
