"""The closed forms quiet spans use (firmware_sim.regimes.quiet_standby / quiet_awake, PowerLedger.add_many,
RigCell.ocv_many) against the per-tick functions they replace: the same state, bit for bit, for hypothesis-drawn
states, timers and inputs. Fast (no scenario run): also the room tests of the regimes and power-manager mutation
check (mutation/config.toml)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from firmware_sim.power_manager import PowerBudget, PowerLedger
from firmware_sim.regimes import Regime, RegimeState, RegimeTimers, TickInputs, quiet_awake, quiet_standby, step
from hil_stub.cell import RigCell

# --------------------------------------------------------------
TIMERS = st.builds(RegimeTimers, link_loss=st.integers(1, 6), overrun=st.integers(1, 6),
                   wake_debounce=st.integers(1, 6), quiet=st.integers(1, 12), hv_debounce=st.integers(1, 8),
                   link_recovery=st.integers(0, 6), period=st.just(0.01))


def _state(data, regime: Regime, tm: RegimeTimers) -> RegimeState:
    """A reachable state of ``regime``: of each pair of opposite runs (link failed / link good, comparator above /
    below, HV present / absent) at most one is non-zero — the last tick had one or the other (the stand-by
    shortcut of ``step`` relies on it too)."""
    d = data.draw
    if d(st.booleans()):
        link_fail, link_ok = d(st.integers(1, tm.link_loss - 1)) if tm.link_loss > 1 else 0, 0
    else:
        link_fail, link_ok = 0, d(st.integers(0, max(tm.link_recovery, 1)))
    wake_cap = tm.wake_debounce - 1 if regime is Regime.STANDBY_HARVEST else tm.wake_debounce + 1
    quiet_cap = tm.quiet - 1 if regime is Regime.SENSING else tm.quiet
    if d(st.booleans()) and wake_cap >= 1:
        wake_run, quiet_run = d(st.integers(1, wake_cap)), 0
    else:
        wake_run, quiet_run = 0, d(st.integers(0, quiet_cap))
    hv_cap = tm.hv_debounce + 1 if regime is Regime.MAINTENANCE else tm.hv_debounce - 1
    off_cap = tm.hv_debounce - 1 if regime is Regime.MAINTENANCE else tm.hv_debounce
    if d(st.booleans()) and hv_cap >= 1:
        hv_run, hv_off_run = d(st.integers(1, hv_cap)), 0
    else:
        hv_run, hv_off_run = 0, d(st.integers(0, off_cap))
    # outside SAFE the causes are () once reachable, but step carries whatever it is given: so must the closed forms
    causes = d(st.sampled_from([(), ("link_lost",), ("sensor_fault", "overrun")]))
    return RegimeState(regime, d(st.integers(0, 100)), link_fail, link_ok, d(st.integers(0, tm.overrun - 1)),
                       wake_run, quiet_run, hv_run, hv_off_run, causes)


@settings(max_examples=300, deadline=None)
@given(tm=TIMERS, data=st.data(), m=st.integers(1, 40), energy=st.lists(st.booleans(), min_size=40, max_size=40))
def test_quiet_standby_equals_repeated_steps(tm, data, m, energy) -> None:
    s0 = _state(data, Regime.STANDBY_HARVEST, tm)
    s = s0
    for i in range(m):
        s, out, ev = step(s, TickInputs(energy_ok=energy[i]), 100 + i, tm)
        assert not out.changed and ev == ()
    assert quiet_standby(s0, tm, m) == s


@settings(max_examples=400, deadline=None)
@given(tm=TIMERS, data=st.data(), regime=st.sampled_from([Regime.SENSING, Regime.MAINTENANCE]),
       wake=st.lists(st.booleans(), min_size=0, max_size=40), energy=st.booleans())
def test_quiet_awake_equals_repeated_steps_up_to_the_first_transition(tm, data, regime, wake, energy) -> None:
    s0 = _state(data, regime, tm)
    hv = regime is Regime.MAINTENANCE
    got, m = quiet_awake(s0, tm, wake)
    s = s0
    taken = 0
    for i, w in enumerate(wake):
        nxt, out, ev = step(s, TickInputs(wake_signal=w, hv_present=hv, energy_ok=energy), 100 + i, tm)
        if out.changed or ev:
            break
        s = nxt
        taken += 1
    assert m == taken
    assert got == s
    if regime is Regime.MAINTENANCE:
        assert m == len(wake)  # nothing fires with HV present and good samples


@settings(max_examples=200, deadline=None)
@given(v=st.lists(st.floats(2.0, 3.3), min_size=1, max_size=60), e0=st.floats(0.0, 10.0),
       regime=st.sampled_from(list(Regime)), first=st.booleans())
def test_ledger_add_many_equals_add(v, e0, regime, first) -> None:
    budget = PowerBudget(1e-6, 2e-3, 5e-3, 1e-4, 2.7, 2.2, 0.1, 5, 0.01)
    a, b = PowerLedger(budget), PowerLedger(budget)
    for led in (a, b):
        led.energy_used = e0
        if not first:
            led.add(regime, 3.0)
    for x in v:
        a.add(regime, x)
    b.add_many(regime, np.array(v))
    assert (a.ticks, a.energy_used, a.v_first, a.v_last, a.v_min) == (b.ticks, b.energy_used, b.v_first, b.v_last,
                                                                       b.v_min)


@settings(max_examples=100, deadline=None)
@given(q=st.lists(st.floats(-10.0, 900.0), min_size=1, max_size=50))
def test_cell_ocv_many_equals_ocv(q) -> None:
    cell = RigCell(10.0, 3.0, "test")
    arr = np.array(q)
    got = cell.ocv_many(arr)
    lo, hi = cell._ocv_q0, cell._ocv_q0 + cell._ocv_h * (len(cell._ocv_list) - 1)
    if got is None:
        assert any(not (lo <= x < hi - cell._ocv_h) or int((x - lo) / cell._ocv_h) >= len(cell._ocv_list) - 1
                   or int((x - lo) / cell._ocv_h) < 0 for x in q)
    else:
        assert got.tolist() == [cell.ocv(x) for x in q]


def test_closed_forms_refuse_what_they_do_not_cover() -> None:
    tm = RegimeTimers(3, 3, 2, 5, 4, 0, 0.01)
    for regime in (Regime.SENSING, Regime.MAINTENANCE, Regime.SAFE):
        assert quiet_standby(RegimeState(regime), tm, 5) is None
    for regime in (Regime.STANDBY_HARVEST, Regime.SAFE):
        s = RegimeState(regime)
        assert quiet_awake(s, tm, [False, True]) == (s, 0)
    assert quiet_standby(RegimeState(), tm, 0) is None
    zero_loss = RegimeTimers(0, 3, 2, 5, 4, 0, 0.01)  # a fault row would fire every tick: not a quiet stretch
    zero_overrun = RegimeTimers(3, 0, 2, 5, 4, 0, 0.01)
    for t in (zero_loss, zero_overrun):
        assert quiet_standby(RegimeState(), t, 3) is None
        s = RegimeState(Regime.SENSING)
        assert quiet_awake(s, t, [True]) == (s, 0)
    s = RegimeState(Regime.SENSING, quiet_run=4)
    assert quiet_awake(s, tm, [False, True]) == (s, 0)  # quiet fires at the first tick: nothing taken


def test_ledger_add_many_of_nothing_changes_nothing() -> None:
    budget = PowerBudget(1e-6, 2e-3, 5e-3, 1e-4, 2.7, 2.2, 0.1, 5, 0.01)
    led = PowerLedger(budget)
    led.add(Regime.SENSING, 3.0)
    before = (dict(led.ticks), led.energy_used, led.v_first, led.v_last, led.v_min)
    led.add_many(Regime.SENSING, np.array([]))
    assert (led.ticks, led.energy_used, led.v_first, led.v_last, led.v_min) == before
