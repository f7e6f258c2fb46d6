"""The regime machine: transition table, documented behaviour, and hypothesis event sequences (pure logic)."""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from board_config.board import load_board_config
from firmware_sim.regimes import (
    ALLOWED,
    TRANSITIONS,
    Regime,
    RegimeState,
    RegimeTimers,
    TickInputs,
    Trigger,
    step,
    transition_table_markdown,
)

CFG = load_board_config()
TM = RegimeTimers.from_config(CFG)
DOCS = Path(__file__).resolve().parents[2] / "docs" / "board.md"


def run(inputs, state=None, start=0):
    state = state or RegimeState()
    regimes, events = [], []
    for i, inp in enumerate(inputs):
        state, out, ev = step(state, inp, start + i, TM)
        regimes.append(out.regime)
        events.extend(ev)
    return state, regimes, events


def quiet(n, **kw):
    return [TickInputs(**kw)] * n


def test_table_is_consistent():
    # every regime has a way out, no duplicate (source, trigger), priorities order fault rows first
    seen = set()
    for t in TRANSITIONS:
        assert (t.source, t.trigger) not in seen, t
        seen.add((t.source, t.trigger))
        assert t.source is not t.target
    for r in Regime:
        assert any(t.source is r for t in TRANSITIONS), r
        assert any(t.target is r for t in TRANSITIONS), r
    # SAFE is reachable from every other regime on every fault trigger
    for r in (Regime.STANDBY_HARVEST, Regime.SENSING, Regime.MAINTENANCE):
        for trig in (Trigger.LINK_LOST, Trigger.SENSOR_FAULT, Trigger.LIMIT_VIOLATION, Trigger.OVERRUN):
            assert (r, trig) in seen
    # SAFE is left only to STANDBY_HARVEST
    assert {t.target for t in TRANSITIONS if t.source is Regime.SAFE} == {Regime.STANDBY_HARVEST}
    # every trigger fires some row (step() dispatches on the row's trigger; the last branch is REARM's)
    assert {t.trigger for t in TRANSITIONS} == set(Trigger)


def test_docs_print_the_table_from_the_code():
    text = DOCS.read_text()
    assert transition_table_markdown() in text, "docs/board.md must contain transition_table_markdown() verbatim"


def test_wake_needs_debounce_and_energy():
    n = TM.wake_debounce
    _, regs, _ = run(quiet(n - 1, wake_signal=True) + quiet(1))
    assert set(regs) == {Regime.STANDBY_HARVEST}
    _, regs, _ = run(quiet(n, wake_signal=True))
    assert regs[-1] is Regime.SENSING and regs[-2] is Regime.STANDBY_HARVEST
    _, regs, ev = run(quiet(n + 5, wake_signal=True, energy_ok=False))
    assert set(regs) == {Regime.STANDBY_HARVEST}
    refused = [e for e in ev if e.data.get("incident") == "wake_refused"]
    assert len(refused) == 1  # once per comparator episode


def test_quiet_period_returns_to_standby():
    st0, regs, _ = run(quiet(TM.wake_debounce, wake_signal=True))
    assert regs[-1] is Regime.SENSING
    st1, regs, _ = run(quiet(TM.quiet - 1), st0, TM.wake_debounce)
    assert set(regs) == {Regime.SENSING}
    _, regs, ev = run(quiet(1), st1, TM.wake_debounce + TM.quiet - 1)
    assert regs[-1] is Regime.STANDBY_HARVEST
    assert ev[-1].data["trigger"] == "quiet"


def test_activity_restarts_the_quiet_period():
    st0, _, _ = run(quiet(TM.wake_debounce, wake_signal=True))
    seq = quiet(TM.quiet - 10) + quiet(1, wake_signal=True) + quiet(TM.quiet - 1)
    _, regs, _ = run(seq, st0, 100)
    assert set(regs) == {Regime.SENSING}


def test_maintenance_entry_and_exit():
    _, regs, _ = run(quiet(TM.hv_debounce, hv_present=True))
    assert regs[-1] is Regime.MAINTENANCE and regs[-2] is Regime.STANDBY_HARVEST
    st0, _, _ = run(quiet(TM.hv_debounce, hv_present=True))
    _, regs, ev = run(quiet(TM.hv_debounce), st0, 1000)
    assert regs[-1] is Regime.STANDBY_HARVEST and ev[-1].data["trigger"] == "hv_removed"
    # no energy: no maintenance either
    _, regs, ev = run(quiet(TM.hv_debounce + 3, hv_present=True, energy_ok=False))
    assert Regime.MAINTENANCE not in regs
    assert any(e.data.get("incident") == "wake_refused" for e in ev)


@pytest.mark.parametrize("start", [Regime.STANDBY_HARVEST, Regime.SENSING, Regime.MAINTENANCE])
def test_link_loss_goes_safe_in_link_loss_ticks(start):
    st0 = RegimeState(regime=start)
    _, regs, ev = run(quiet(TM.link_loss, sample_ok=False), st0)
    assert regs[-1] is Regime.SAFE
    assert all(r is start for r in regs[:-1])
    assert ev[-1].data["trigger"] == "link_lost"


def test_brownout_forces_standby_or_safe():
    _, regs, _ = run(quiet(1, brownout=True), RegimeState(regime=Regime.SENSING))
    assert regs == [Regime.STANDBY_HARVEST]
    _, regs, ev = run(quiet(1, brownout=True), RegimeState(regime=Regime.MAINTENANCE))
    assert regs == [Regime.SAFE] and ev[-1].data["causes"] == ["brownout"]
    _, regs, _ = run(quiet(3, brownout=True))
    assert set(regs) == {Regime.STANDBY_HARVEST}


def test_safe_needs_an_explicit_rearm_and_refuses_while_a_cause_persists():
    st0, regs, _ = run(quiet(1, sensor_fault=True))
    assert regs == [Regime.SAFE] and st0.safe_causes == ("sensor_fault",)
    # fault gone but no re-arm: stays SAFE for a long time
    st1, regs, _ = run(quiet(500), st0, 1)
    assert set(regs) == {Regime.SAFE}
    # re-arm while the sensor is still faulty: refused, logged, state unchanged
    st2, regs, ev = run([TickInputs(sensor_fault=True, rearm=True)], st1, 501)
    assert regs == [Regime.SAFE]
    assert ev[0].data["incident"] == "rearm_refused" and "sensor_fault" in ev[0].data["detail"]
    _, regs, ev = run([TickInputs(rearm=True)], st2, 502)
    assert regs == [Regime.STANDBY_HARVEST] and ev[-1].data["trigger"] == "rearm"


def test_supervisor_rearms_after_link_loss_only():
    st0, _, _ = run(quiet(TM.link_loss, sample_ok=False))
    assert st0.regime is Regime.SAFE
    _, regs, ev = run(quiet(TM.link_recovery), st0, 10)
    assert regs[-1] is Regime.STANDBY_HARVEST and all(r is Regime.SAFE for r in regs[:-1])
    assert ev[-1].data["trigger"] == "link_recovered"
    # link loss and then a sensor fault while in SAFE: the operator must re-arm
    st1, _, _ = run(quiet(1, sensor_fault=True), st0, 10)
    _, regs, _ = run(quiet(TM.link_recovery * 3), st1, 11)
    assert set(regs) == {Regime.SAFE}


# --- hypothesis: random percept sequences ------------------------------------------------------------------
percept = st.builds(
    TickInputs,
    sample_ok=st.booleans() | st.just(True),
    sensor_fault=st.sampled_from([False] * 8 + [True]),
    limit_violation=st.sampled_from([False] * 15 + [True]),
    overrun=st.sampled_from([False] * 6 + [True]),
    wake_signal=st.booleans(),
    hv_present=st.booleans(),
    energy_ok=st.sampled_from([True] * 5 + [False]),
    brownout=st.sampled_from([False] * 8 + [True]),
    rearm=st.sampled_from([False] * 5 + [True]),
)
# runs: each percept repeated a random number of times, so debounces and timers are exercised; long uneventful
# stretches let the counters saturate (the stand-by shortcut)
runs = st.lists(st.tuples(percept | st.just(TickInputs()), st.integers(1, 80) | st.integers(900, 1200)),
                min_size=1, max_size=25)


@settings(max_examples=100, deadline=None)
@given(runs)
def test_random_sequences_obey_the_table(seq):
    state = RegimeState()
    tick = 0
    lost_run = 0
    for inp, reps in seq:
        for _ in range(reps):
            prev = state.regime
            state, out, events = step(state, inp, tick, TM)
            # only transitions of the table
            if out.changed:
                assert (prev, out.regime) in ALLOWED
                assert out.trigger is not None
                row = [t for t in TRANSITIONS if t.source is prev and t.trigger is out.trigger]
                assert len(row) == 1 and row[0].target is out.regime
            else:
                assert out.regime is prev
            changes = [e for e in events if e.kind == "regime_change"]
            assert len(changes) == int(out.changed)
            # actuation only in MAINTENANCE
            assert out.actuation_allowed == (out.regime is Regime.MAINTENANCE)
            # SAFE within link_loss_ticks of losing the link, and stays SAFE while it is lost
            lost_run = lost_run + 1 if not inp.sample_ok else 0
            if lost_run >= TM.link_loss:
                assert out.regime is Regime.SAFE
            # never leaves SAFE while a fault is present
            if prev is Regime.SAFE and out.regime is not Regime.SAFE:
                assert inp.sample_ok and not inp.sensor_fault and not inp.limit_violation and not inp.brownout
            tick += 1


@settings(max_examples=30, deadline=None)
@given(runs)
def test_replay_is_deterministic(seq):
    flat = [inp for inp, reps in seq for _ in range(reps)]
    a = run(flat)
    b = run(flat)
    assert a[0] == b[0] and a[1] == b[1] and a[2] == b[2]


@settings(max_examples=60, deadline=None)
@given(runs)
def test_standby_shortcut_equals_the_full_evaluation(seq):
    from firmware_sim.regimes import step_full

    a = b = RegimeState()
    tick = 0
    for inp, reps in seq:
        for _ in range(reps):
            a, oa, ea = step(a, inp, tick, TM)
            b, ob, eb = step_full(b, inp, tick, TM)
            assert (a, oa, ea) == (b, ob, eb)
            tick += 1
