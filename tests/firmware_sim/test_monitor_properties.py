"""The condition monitor's bookkeeping and its input checks, as behaviour (docs/monitor.md, Eq. 11, Table 3).

Properties over random error streams with invalid samples, split into random chunks: the streaming monitor, the
chunked one and the flow chart written literally end in the same full state (counter, latched fault and its time,
sample / exceedance / invalid counts, maxima, last time). Time must increase strictly, also across chunks.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from board_config import MonitorSettings, load_monitor_settings
from firmware_sim.condition_monitor import (
    ConditionMonitor,
    MonitorState,
    consecutive_exceedances_to_fault,
    evaluate,
    evaluate_z3,
    normalised_error,
)

SMALL = MonitorSettings(f_mon=100.0, eps_th=0.5, count_max=6, counter_up=2, counter_down=1, e0z=0.75e-3,
                        kerr_z=0.075)
EPS = st.sampled_from([0.0, 0.2, 0.5, 0.50001, 0.9, 3.0, math.nan, math.inf])


def flow_chart(eps: list[float], s: MonitorSettings, t: list[float]) -> MonitorState:
    """docs/monitor.md's flow chart, written literally, with its bookkeeping."""
    count, fault, ft, ne, ni, mc, me = 0, False, None, 0, 0, 0, 0.0
    for tk, e in zip(t, eps, strict=True):
        if not math.isfinite(e):
            ni += 1
        elif e > s.eps_th:
            count += s.counter_up
            ne += 1
            me = max(me, e)
        else:
            count = max(count - s.counter_down, 0)
            me = max(me, e)
        if not fault and count > s.count_max:
            fault, ft = True, tk
        mc = max(mc, count)
    return MonitorState(count, fault, ft, len(eps), ne, ni, mc, me, t[-1] if t else None)


@settings(max_examples=150, deadline=None)
@given(st.lists(EPS, min_size=1, max_size=60), st.lists(st.integers(1, 9), min_size=1, max_size=20))
def test_chunked_and_streamed_end_in_the_flow_charts_state(eps, cuts):
    t = [0.01 * (k + 1) for k in range(len(eps))]
    want = flow_chart(eps, SMALL, t)
    one = ConditionMonitor(SMALL)
    for tk, e in zip(t, eps, strict=True):
        one.update_eps(tk, e)
    assert one.state == want
    chunked = ConditionMonitor(SMALL)
    i = 0
    for c in cuts * 10:
        if i >= len(eps):
            break
        chunked.update_many_eps(np.array(t[i:i + c]), np.array(eps[i:i + c]))
        i += c
    if i < len(eps):
        chunked.update_many_eps(np.array(t[i:]), np.array(eps[i:]))
    assert chunked.state == want
    assert (chunked.fault, chunked.count) == (want.fault, want.count)


def test_a_chunk_whose_first_sample_repeats_the_last_time_is_refused():
    for first in ("one", "chunk"):
        mon = ConditionMonitor(SMALL)
        if first == "one":
            mon.update_eps(0.5, 0.1)
        else:
            mon.update_many_eps(np.array([0.3, 0.4, 0.5]), np.array([0.1, 0.1, 0.1]))
        before = mon.state
        for t0 in (0.5, 0.49):
            with pytest.raises(ValueError, match=rf"must increase: got t=.*{t0}\)? s after t=0\.5 s"):
                mon.update_many_eps(np.array([t0, 0.6]), np.array([0.9, 0.9]))
            with pytest.raises(ValueError, match="must increase"):
                mon.update_eps(t0, 0.9)
        assert mon.state == before  # nothing counted
        mon.update_many_eps(np.array([0.5000001, 0.6]), np.array([0.9, 0.9]))
        assert mon.state.n_samples == before.n_samples + 2


def test_times_inside_a_chunk_must_increase_strictly_and_shapes_match():
    # the messages, exactly (they name what is wrong)
    with pytest.raises(ValueError, match=r"^monitor sample times must increase strictly$"):
        evaluate(np.array([0.1, 0.2]), SMALL, t=np.array([0.0, 0.0]))
    with pytest.raises(ValueError, match=r"^t must have shape \(2,\) to match eps \(2,\), got \(3,\)$"):
        evaluate(np.array([0.1, 0.2]), SMALL, t=np.array([0.0, 0.1, 0.2]))
    with pytest.raises(ValueError, match=r"^eps must have a time axis \(shape \(\.\.\., T\)\)$"):
        evaluate(np.float64(0.3), SMALL)
    with pytest.raises(ValueError, match=r"^a start state can only continue a single trace \(1-D eps\)$"):
        evaluate(np.zeros((2, 3)), SMALL, state=MonitorState(count=1))
    with pytest.raises(ValueError, match=r"^update_many needs 1-D t and eps of equal length, got \(2,\) and \(1,\)$"):
        ConditionMonitor(SMALL).update_many_eps(np.array([0.1, 0.2]), np.array([0.1]))
    # a single sample needs no ordering inside the chunk
    assert evaluate(np.array([0.9]), SMALL, t=np.array([5.0])).t.tolist() == [5.0]


def test_empty_chunks_and_traces():
    mon = ConditionMonitor(SMALL)
    mon.update_eps(0.1, 0.9)
    before = mon.state
    tr = mon.update_many_eps(np.array([]), np.array([]))
    assert mon.state == before and tr.count.shape == (0,)
    tr = evaluate(np.zeros((3, 0)), SMALL)
    assert tr.detected.tolist() == [False] * 3 and tr.fault_index.tolist() == [-1] * 3
    assert np.isnan(tr.fault_time).all() and tr.max_count.tolist() == [0, 0, 0]


def test_default_times_are_the_monitor_rate():
    tr = evaluate(np.zeros(4), SMALL)
    assert tr.t.tolist() == pytest.approx([0.0, 0.01, 0.02, 0.03])


def test_the_fault_latches_once_at_the_first_crossing_in_a_batch():
    k = consecutive_exceedances_to_fault(SMALL.count_max, SMALL.counter_up)
    assert k == 4  # 6 // 2 + 1
    eps = np.array([[0.9] * (k + 3), [0.9] * (k - 1) + [0.1] * 4, [0.1] * (k + 3)])
    tr = evaluate(eps, SMALL, t=np.arange(k + 3) * 0.5 + 2.0)
    assert tr.fault_index.tolist() == [k - 1, -1, -1]
    assert tr.fault_time[0] == 2.0 + (k - 1) * 0.5 and np.isnan(tr.fault_time[1:]).all()
    assert tr.detected.tolist() == [True, False, False]
    assert tr.max_count.tolist() == [2 * (k + 3), 2 * (k - 1), 0]
    # continuing a stream whose fault is latched: every sample faulted, no new latch
    tr = evaluate(np.array([0.1, 0.1]), SMALL, t=np.array([1.0, 2.0]), state=MonitorState(count=9, fault=True))
    assert tr.fault.tolist() == [True, True] and int(tr.fault_index) == -1
    assert tr.count.tolist() == [8, 7]
    mon = ConditionMonitor(SMALL)
    for j in range(k + 5):
        mon.update_eps(0.1 * (j + 1), 0.9)
    assert mon.state.fault_time == pytest.approx(0.1 * k)  # the first latch, not a later sample
    tr = mon.update_many_eps(np.array([10.0, 11.0]), np.array([0.9, 0.9]))
    assert int(tr.fault_index) == -1 and mon.state.fault_time == pytest.approx(0.1 * k)


@pytest.mark.parametrize("count", [0, 1, 4, 5, 6])
def test_samples_to_fault_is_exact_from_any_counter(count):
    mon = ConditionMonitor(SMALL)
    tk = iter(np.arange(1, 100) * 0.01)
    for _ in range((count + 1) // 2):
        mon.update_eps(next(tk), 0.9)
    if count % 2:
        mon.update_eps(next(tk), 0.1)
    assert mon.count == count and not mon.fault
    k = mon.samples_to_fault
    assert k == (SMALL.count_max - count) // SMALL.counter_up + 1
    for _ in range(k - 1):
        assert not mon.update_eps(next(tk), 0.9).fault
    assert mon.update_eps(next(tk), 0.9).fault
    assert mon.samples_to_fault == 1  # above count_max: the next counted sample keeps it above


def test_exceedances_to_fault_formula_at_and_above_count_max():
    assert consecutive_exceedances_to_fault(200, 2) == 101  # Table 3: 1.00 s at 100 Hz
    assert consecutive_exceedances_to_fault(200, 2, 200) == 1
    assert consecutive_exceedances_to_fault(200, 2, 199) == 1
    assert consecutive_exceedances_to_fault(200, 2, 198) == 2
    assert consecutive_exceedances_to_fault(200, 3, 201) == 1
    assert consecutive_exceedances_to_fault(200, 3, 500) == 1


def test_reset_forgets_everything():
    mon = ConditionMonitor(SMALL)
    for j in range(10):
        mon.update_eps(j + 1.0, 0.9)
    assert mon.fault
    mon.reset()
    assert mon.state == MonitorState() and mon.count == 0 and not mon.fault
    mon.update_eps(0.5, 0.1)  # time may restart after a reset


def test_eq11_scalar_array_and_method_agree_with_the_floor():
    s = load_monitor_settings()
    floor = s.e0z / s.kerr_z
    assert floor == pytest.approx(0.01)
    assert normalised_error(2e-3, 1e-3, s.e0z, s.kerr_z) == pytest.approx(1e-3 / (1e-3 + floor))
    assert normalised_error(0, -1e-3, s.e0z, s.kerr_z) == pytest.approx(1e-3 / (1e-3 + floor))
    arr = normalised_error(np.array([2e-3, -5e-3]), np.array([1e-3, -2e-3]), s.e0z, s.kerr_z)
    assert arr.tolist() == pytest.approx([1e-3 / (1e-3 + floor), 3e-3 / (2e-3 + floor)])
    mon = ConditionMonitor(s)
    assert mon.error(-5e-3, -2e-3) == pytest.approx(arr[1])
    smp = mon.update(0.0, -5e-3, -2e-3)
    assert smp.eps == pytest.approx(arr[1]) and smp.valid and smp.exceeded is bool(arr[1] > s.eps_th)
    tr = evaluate_z3(np.array([2e-3, -5e-3]), np.array([1e-3, -2e-3]), s)
    assert tr.eps.tolist() == pytest.approx(arr.tolist())
    tr2 = mon.update_many(np.array([1.0, 2.0]), np.array([2e-3, -5e-3]), np.array([1e-3, -2e-3]))
    assert tr2.eps.tolist() == pytest.approx(arr.tolist())


def test_invalid_samples_are_counted_and_hold_the_counter():
    mon = ConditionMonitor(SMALL)
    mon.update_eps(0.1, 0.9)
    for j, bad in enumerate((math.nan, math.inf, -math.inf)):
        smp = mon.update_eps(0.2 + j, bad)
        assert (smp.valid, smp.exceeded, smp.count) == (False, False, 2)
    assert (mon.state.n_invalid, mon.state.n_exceed, mon.state.max_eps) == (3, 1, 0.9)


def test_evaluate_z3_takes_the_given_settings_and_times_else_table3_at_f_mon():
    # 3 mm of model error at rest over the 10 mm floor: eps = 0.3, above Table 3's 0.225, below SMALL's 0.5
    z_md, z_hw = np.full(12, 3e-3), np.zeros(12)
    t = 5.0 + 0.01 * np.arange(12)
    small = evaluate_z3(z_md, z_hw, SMALL, t)
    assert small.t.tolist() == t.tolist() and small.count.tolist() == [0] * 12 and not small.detected
    table3 = evaluate_z3(z_md, z_hw)  # Table 3 settings, t = k / f_mon
    assert table3.t.tolist() == (np.arange(12) / 100.0).tolist()
    assert table3.count.tolist() == list(range(2, 25, 2)) and table3.eps.tolist() == pytest.approx([0.3] * 12)
    # 6 mm: eps = 0.6 exceeds SMALL too; its counter passes count_max = 6 on the 4th sample, at that sample's time
    fast = evaluate_z3(np.full(12, 6e-3), z_hw, SMALL, t)
    assert int(fast.fault_index) == 3 and float(fast.fault_time) == t[3]


def test_update_many_takes_any_numbers_as_floats():
    mon, ref = ConditionMonitor(SMALL), ConditionMonitor(SMALL)
    trace = mon.update_many_eps([1, 2, 3], [1, 0, 2])  # Python ints: times 1..3 s, eps 1, 0, 2
    ref.update_many_eps(np.array([1.0, 2.0, 3.0]), np.array([1.0, 0.0, 2.0]))
    assert mon.state == ref.state and trace.count.tolist() == [2, 1, 3]
    assert mon.state.max_eps == 2.0 and mon.state.t_last == 3.0
    assert isinstance(mon.state.max_eps, float) and isinstance(mon.state.t_last, float)
    assert trace.eps.dtype == np.float64 and trace.t.dtype == np.float64  # the traces are float too
    whole = evaluate([0, 1, 2], SMALL, [1, 2, 3])
    assert whole.eps.dtype == np.float64 and whole.t.dtype == np.float64 and whole.count.tolist() == [0, 2, 4]


def test_evaluate_without_settings_is_table3_at_f_mon():
    eps = np.full(102, 0.3)  # above Table 3's 0.225: +2 per sample, the fault latches on the 101st (index 100)
    tr = evaluate(eps)
    assert int(tr.fault_index) == 100 and float(tr.fault_time) == pytest.approx(1.0)
    assert evaluate(eps, SMALL).count[0] == 0  # SMALL's threshold is 0.5


def test_a_monitor_without_settings_runs_table3_and_samples_carry_their_time():
    mon = ConditionMonitor()
    assert mon.settings == load_monitor_settings()
    smp = mon.update_eps(np.float64(0.25), 0.3)  # above Table 3's 0.225 (SMALL's threshold is 0.5)
    assert smp.t == 0.25 and type(smp.t) is float and smp.exceeded and smp.count == 2
