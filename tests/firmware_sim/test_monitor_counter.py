"""Property tests of the condition monitor's fault counter (seed Sec. 4.1, Fig. 10, Table 3).

Derived numbers under test (strict comparisons, as documented in firmware_sim/condition_monitor.py):
from a counter at c, K(c) = (count_max - c) // up + 1 consecutive exceedances latch a fault; with Table 3
(count_max 200, up 2) K(0) = 101 samples, i.e. the fault latches 1.00 s after the first exceeding sample.

The last test runs the same checks against deliberately wrong counters (>= instead of >, a threshold that counts
eps == eps_th, a counter that may go negative, a non-latching flag) and asserts that each one is caught.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from board_config import MonitorSettings, load_monitor_settings
from firmware_sim.condition_monitor import (
    ConditionMonitor,
    consecutive_exceedances_to_fault,
    counter_trajectory,
    evaluate,
)

TABLE3 = load_monitor_settings()

monitor_settings = st.builds(
    MonitorSettings,
    f_mon=st.just(100.0),
    eps_th=st.sampled_from([0.05, 0.225, 0.5]),
    count_max=st.integers(1, 60),
    counter_up=st.integers(1, 4),
    counter_down=st.integers(0, 3),
    e0z=st.just(0.75e-3),
    kerr_z=st.just(0.075),
)


def eps_sequences(th: float, max_size: int = 400, invalid: bool = True):
    """Errors clustered around the threshold (including exactly the threshold), optionally with NaN/inf."""
    values = [st.just(th), st.just(0.0), st.floats(0.0, th, allow_nan=False),
              st.floats(th, 3 * th, allow_nan=False, exclude_min=True)]
    if invalid:
        values += [st.just(math.nan), st.just(math.inf)]
    return st.lists(st.one_of(*values), min_size=0, max_size=max_size)


def bursty(th: float, max_runs: int = 30):
    """Sequences made of runs of exceedances and non-exceedances (long runs exercise latching)."""
    run = st.tuples(st.booleans(), st.integers(1, 120))
    return st.lists(run, min_size=1, max_size=max_runs).map(
        lambda runs: [2 * th if exc else 0.5 * th for exc, n in runs for _ in range(n)])


def reference(eps: list[float], s: MonitorSettings) -> tuple[list[int], list[bool]]:
    """The flow chart of Fig. 10, written as literally as possible (the oracle)."""
    count, fault, counts, faults = 0, False, [], []
    for e in eps:
        if math.isfinite(e):
            if e > s.eps_th:
                count = count + s.counter_up
            elif count > 0:
                count = max(count - s.counter_down, 0)
            else:
                count = 0
        if count > s.count_max:
            fault = True
        counts.append(count)
        faults.append(fault)
    return counts, faults


def stream(eps: list[float], s: MonitorSettings):
    mon = ConditionMonitor(s)
    out = [mon.update_eps(k / s.f_mon, e) for k, e in enumerate(eps)]
    return [o.count for o in out], [o.fault for o in out], mon


# --- the properties ---------------------------------------------------------------------------------------


@settings(max_examples=150, deadline=None)
@given(s=monitor_settings, data=st.data())
def test_counter_never_negative_and_steps_are_up_down_or_floor(s, data):
    eps = data.draw(eps_sequences(s.eps_th))
    counts, _, _ = stream(eps, s)
    prev = 0
    for e, c in zip(eps, counts):
        assert c >= 0
        if not math.isfinite(e):
            assert c == prev  # invalid samples are not counted
        elif e > s.eps_th:
            assert c - prev == s.counter_up
        else:
            # a full -down step, or a shorter one that stops exactly at the floor
            assert c - prev == -s.counter_down or (c == 0 and prev <= s.counter_down)
        prev = c


@settings(max_examples=100, deadline=None)
@given(data=st.data())
def test_table3_steps_are_exactly_plus2_minus1_or_zero_at_floor(data):
    eps = data.draw(eps_sequences(TABLE3.eps_th, invalid=False))
    counts, _, _ = stream(eps, TABLE3)
    steps = np.diff([0, *counts])
    prev = np.array([0, *counts[:-1]])
    assert set(np.unique(steps)) <= {2, -1, 0}
    assert np.all(prev[steps == 0] == 0)  # no change only at the floor


@settings(max_examples=150, deadline=None)
@given(s=monitor_settings, data=st.data())
def test_never_a_fault_while_error_at_or_below_threshold(s, data):
    eps = data.draw(st.lists(st.one_of(st.just(s.eps_th), st.floats(0.0, s.eps_th)), max_size=600))
    counts, faults, mon = stream(eps, s)
    assert not any(faults) and max(counts, default=0) == 0
    assert not evaluate(np.array(eps, dtype=float), s).fault.any()
    assert mon.state.n_exceed == 0


def test_consecutive_exceedances_needed_from_zero_table3():
    k = consecutive_exceedances_to_fault(TABLE3.count_max, TABLE3.counter_up)
    assert k == 101  # 200 // 2 + 1: the counter must pass 200, reaching 202
    mon = ConditionMonitor(TABLE3)
    for i in range(k - 1):
        assert not mon.update_eps(i / 100, 1.0).fault
    assert mon.count == 200  # exactly count_max: not yet a fault (strict ">")
    s = mon.update_eps((k - 1) / 100, 1.0)
    assert s.fault and s.count == 202
    assert mon.state.fault_time == pytest.approx(1.00)  # 100 ticks after the first exceedance at t = 0


@settings(max_examples=150, deadline=None)
@given(s=monitor_settings, data=st.data())
def test_always_a_fault_after_enough_consecutive_exceedances(s, data):
    prefix = data.draw(eps_sequences(s.eps_th, max_size=200))
    _, faults, mon = stream(prefix, s)
    c = mon.count
    k = consecutive_exceedances_to_fault(s.count_max, s.counter_up, c)
    assert k <= consecutive_exceedances_to_fault(s.count_max, s.counter_up, 0)
    t0 = len(prefix) / s.f_mon
    samples = [mon.update_eps(t0 + i / s.f_mon, 2 * s.eps_th) for i in range(k)]
    assert samples[-1].fault
    if not (faults and faults[-1]) and c <= s.count_max:
        # and not one sample earlier (the bound is tight)
        assert not samples[-2].fault if k >= 2 else True


@settings(max_examples=150, deadline=None)
@given(s=monitor_settings, gap=st.integers(1, 50))
def test_one_exceedance_short_of_k_from_zero_never_latches(s, gap):
    k = consecutive_exceedances_to_fault(s.count_max, s.counter_up)
    eps = [2 * s.eps_th] * (k - 1) + [0.0] * gap
    _, faults, mon = stream(eps, s)
    assert not any(faults)
    assert mon.state.max_count == (k - 1) * s.counter_up <= s.count_max


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(s=monitor_settings, data=st.data())
def test_latency_bounds(s, data):
    eps = data.draw(bursty(s.eps_th))
    tr = evaluate(np.array(eps), s)
    k0 = consecutive_exceedances_to_fault(s.count_max, s.counter_up)
    exceeded = np.array(eps) > s.eps_th
    # upper bound: the first run of >= K(0) consecutive exceedances starting at j latches by j + K(0) - 1
    run = 0
    bound = None
    for i, e in enumerate(exceeded):
        run = run + 1 if e else 0
        if run == k0:
            bound = i
            break
    if bound is not None:
        assert 0 <= tr.fault_index <= bound
    # lower bounds: no fault before K(0) samples, and not before ceil((count_max+1)/up) exceedances were seen
    if tr.fault_index >= 0:
        assert tr.fault_index >= k0 - 1
        assert exceeded[: tr.fault_index + 1].sum() >= math.ceil((s.count_max + 1) / s.counter_up)
    else:
        assert bound is None


@settings(max_examples=100, deadline=None)
@given(s=monitor_settings, r=st.integers(1, 10), m_extra=st.integers(0, 10), periods=st.integers(1, 80))
def test_periodic_exceedances_with_positive_drift_latch_within_bound(s, r, m_extra, periods):
    m = r + m_extra
    gain = s.counter_up * r - s.counter_down * (m - r)
    assume(gain > 0)
    pattern = [2 * s.eps_th] * r + [0.0] * (m - r)
    n_periods = s.count_max // gain + 1  # the counter after P periods is >= P * gain (the floor only helps)
    tr = evaluate(np.array(pattern * n_periods), s)
    assert tr.fault_index >= 0 and tr.fault_index <= n_periods * m - 1


@settings(max_examples=150, deadline=None)
@given(s=monitor_settings, data=st.data())
def test_fault_latches(s, data):
    eps = data.draw(bursty(s.eps_th))
    _, faults, mon = stream(eps, s)
    if any(faults):
        first = faults.index(True)
        assert all(faults[first:])
        assert mon.state.fault_time == pytest.approx(first / s.f_mon)
        # the counter keeps running, and may fall back to zero, but the flag stays
        n_decay = mon.count // s.counter_down + 1 if s.counter_down else 50
        more = [mon.update_eps((len(eps) + i) / s.f_mon, 0.0).fault for i in range(n_decay)]
        assert all(more)
        assert mon.count == (0 if s.counter_down > 0 else mon.state.max_count)
        mon.reset()
        assert not mon.fault and mon.count == 0


@settings(max_examples=200, deadline=None)
@given(s=monitor_settings, data=st.data())
def test_streaming_equals_vectorised_equals_flow_chart(s, data):
    eps = data.draw(st.one_of(eps_sequences(s.eps_th), bursty(s.eps_th)))
    ref_counts, ref_faults = reference(eps, s)
    counts, faults, mon = stream(eps, s)
    tr = evaluate(np.array(eps, dtype=float), s)
    assert counts == ref_counts == tr.count.tolist()
    assert faults == ref_faults == tr.fault.tolist()
    first = ref_faults.index(True) if True in ref_faults else -1
    assert tr.fault_index == first
    if first >= 0:
        assert tr.fault_time == mon.state.fault_time
    assert tr.max_count == (max(ref_counts) if ref_counts else 0) == mon.state.max_count


@settings(max_examples=150, deadline=None)
@given(s=monitor_settings, data=st.data())
def test_invariant_to_chunking(s, data):
    eps = data.draw(st.one_of(eps_sequences(s.eps_th, max_size=300), bursty(s.eps_th)))
    n = len(eps)
    cuts = sorted(set(data.draw(st.lists(st.integers(0, n), max_size=8))))
    edges = [0, *cuts, n]
    t = np.arange(n) / s.f_mon
    whole = evaluate(np.array(eps, dtype=float), s, t)
    mon = ConditionMonitor(s)
    counts, faults = [], []
    for a, b in itertools.pairwise(edges):
        if b - a == 1 and data.draw(st.booleans()):  # mix single-sample and chunk updates
            smp = mon.update_eps(t[a], eps[a])
            counts.append(smp.count)
            faults.append(smp.fault)
        elif b > a:
            tr = mon.update_many_eps(t[a:b], np.array(eps[a:b], dtype=float))
            counts += tr.count.tolist()
            faults += tr.fault.tolist()
    assert counts == whole.count.tolist()
    assert faults == whole.fault.tolist()
    st_one = ConditionMonitor(s)
    for k in range(n):
        st_one.update_eps(t[k], eps[k])
    assert mon.state == st_one.state


def test_batched_vectorised_matches_row_by_row():
    rng = np.random.default_rng(3)
    eps = rng.uniform(0, 0.45, (7, 500))
    eps[2, 100:220] = 0.3  # a sustained exceedance
    tr = evaluate(eps, TABLE3)
    for row in range(eps.shape[0]):
        one = evaluate(eps[row], TABLE3)
        assert np.array_equal(one.count, tr.count[row]) and one.fault_index == tr.fault_index[row]
    assert tr.detected[2]


def test_closed_form_counter_with_start_value():
    exc = np.array([False, False, True, False, False, False])
    assert counter_trajectory(exc, None, 2, 1, count0=1).tolist() == [0, 0, 2, 1, 0, 0]
    assert counter_trajectory(exc, None, 2, 1, count0=5).tolist() == [4, 3, 5, 4, 3, 2]
    assert counter_trajectory(exc, np.array([True, False, True, True, True, True]), 2, 1, 5).tolist() == [
        4, 4, 6, 5, 4, 3]
    # by default the counter starts at 0; flags may be any truthy/falsy numbers; an empty trace is an empty int trace
    assert counter_trajectory([True, False, False], None, 2, 1).tolist() == [2, 1, 0]
    assert counter_trajectory([1, 0, 3], [1, 1, 0], 2, 1).tolist() == [2, 1, 1]
    empty = counter_trajectory(np.zeros((2, 0), bool), None, 2, 1, count0=3)
    assert empty.shape == (2, 0) and empty.dtype == np.int64
    assert counter_trajectory(exc, None, 2, 1).dtype == np.int64


# --- the tests above must fail for wrong counters -------------------------------------------------------------


def _mutant_stream(kind: str):
    def run(eps, s):
        count, fault, counts, faults = 0, False, [], []
        for e in eps:
            if kind == "ge_threshold":
                exc = e >= s.eps_th
            else:
                exc = e > s.eps_th
            if exc:
                count += s.counter_up
            else:
                count = count - s.counter_down if kind == "no_floor" else max(count - s.counter_down, 0)
            latch = count >= s.count_max if kind == "ge_count" else count > s.count_max
            fault = latch if kind == "not_latching" else (fault or latch)
            counts.append(count)
            faults.append(fault)
        return counts, faults
    return run


@pytest.mark.parametrize("kind", ["ge_count", "ge_threshold", "no_floor", "not_latching"])
def test_the_checks_catch_off_by_one_and_other_mutants(kind):
    mutant = _mutant_stream(kind)
    s = TABLE3
    k = consecutive_exceedances_to_fault(s.count_max, s.counter_up)
    failures = []
    # 1. K-1 consecutive exceedances from zero must not latch; K must.
    c, f = mutant([1.0] * (k - 1) + [0.0] * 10, s)
    if any(f):
        failures.append("latched one sample early")
    # 2. eps exactly at the threshold never counts.
    c, f = mutant([s.eps_th] * 500, s)
    if max(c) > 0:
        failures.append("counted eps == eps_th")
    # 3. never negative.
    c, f = mutant([0.0] * 5, s)
    if min(c) < 0:
        failures.append("negative counter")
    # 4. latching.
    c, f = mutant([1.0] * (k + 5) + [0.0] * 300, s)
    if not all(f[k - 1:]):
        failures.append("fault did not latch")
    # 5. agreement with the oracle.
    ref = reference([1.0] * (k - 1) + [0.0] * 10 + [s.eps_th] * 20 + [1.0] * (k + 5) + [0.0] * 300, s)
    if mutant([1.0] * (k - 1) + [0.0] * 10 + [s.eps_th] * 20 + [1.0] * (k + 5) + [0.0] * 300, s) != ref:
        failures.append("differs from the flow chart")
    assert failures, f"mutant {kind} passed every check"
    # and the real implementation passes the same checks
    real = [stream(e, s)[:2] for e in ([1.0] * (k - 1) + [0.0] * 10, [s.eps_th] * 500)]
    assert not any(real[0][1]) and max(real[1][0]) == 0


def test_table3_settings_drive_the_monitor():
    assert (TABLE3.f_mon, TABLE3.eps_th, TABLE3.count_max, TABLE3.counter_up, TABLE3.counter_down) == (
        100.0, 0.225, 200, 2, 1)
    other = replace(TABLE3, count_max=10)
    _, faults, _ = stream([1.0] * 6, other)
    assert faults == [False] * 5 + [True]  # 6 × 2 = 12 > 10; 5 × 2 = 10 is not
