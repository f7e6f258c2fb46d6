"""Every decision of the regime table shown to matter (MC/DC style).

For each row of ``regimes.TRANSITIONS``: a tick sequence where its trigger fires, and the same sequence with each
condition of the trigger and of its guard flipped alone, where it does not. Debounces are checked at exactly N
ticks (N-1 does not fire, N does, an interruption restarts the count); every simultaneous SAFE cause is latched; a
re-arm is refused while any one cause persists. Small timers keep the sequences short; the documented values are
checked against the config once.
"""

from __future__ import annotations

import dataclasses

import pytest

from board_config.board import load_board_config
from firmware_sim.regimes import (
    Regime,
    RegimeOutputs,
    RegimeState,
    RegimeTimers,
    TickInputs,
    Trigger,
    is_allowed,
    step,
)

CFG = load_board_config()
T = RegimeTimers(link_loss=2, overrun=5, wake_debounce=3, quiet=4, hv_debounce=3, link_recovery=3, period=0.01)
S, SE, M, X = Regime.STANDBY_HARVEST, Regime.SENSING, Regime.MAINTENANCE, Regime.SAFE
#: the percept that keeps each regime where it is (SENSING needs activity, MAINTENANCE the HV equipment)
HOLD = {S: TickInputs(), SE: TickInputs(wake_signal=True), M: TickInputs(hv_present=True), X: TickInputs()}


class Run:
    """A board's regime machine fed tick by tick; keeps every output and event."""

    def __init__(self, timers: RegimeTimers = T, state: RegimeState | None = None, tick: int = 0) -> None:
        self.timers, self.state, self.tick = timers, state or RegimeState(), tick
        self.outs: list[RegimeOutputs] = []
        self.events: list = []

    def feed(self, *inputs: TickInputs, times: int = 1) -> Run:
        for _ in range(times):
            for inp in inputs:
                self.state, out, ev = step(self.state, inp, self.tick, self.timers)
                self.outs.append(out)
                self.events.extend(ev)
                self.tick += 1
        return self

    @property
    def regime(self) -> Regime:
        return self.state.regime

    def incidents(self, name: str) -> list:
        return [e for e in self.events if e.kind == "incident" and e.data["incident"] == name]

    def changes(self) -> list:
        return [e for e in self.events if e.kind == "regime_change"]


def in_regime(regime: Regime, timers: RegimeTimers = T) -> Run:
    """A board brought into ``regime`` by its own triggers, settled one tick."""
    r = Run(timers)
    if regime is SE:
        r.feed(HOLD[SE], times=timers.wake_debounce)
    elif regime is M:
        r.feed(HOLD[M], times=timers.hv_debounce)
    elif regime is X:
        r.feed(TickInputs(limit_violation=True))
        r.feed(TickInputs())
    assert r.regime is regime
    r.events.clear()
    r.outs.clear()
    return r


def with_(regime: Regime, **kw) -> TickInputs:
    return HOLD[regime]._replace(**kw)


# --- timers from the config ---------------------------------------------------------------------------------

def test_timers_are_the_documented_config_values():
    tm = RegimeTimers.from_config(CFG)
    assert tm == RegimeTimers(CFG.tick_link_loss_ticks, CFG.tick_overrun_ticks, CFG.wake_debounce_ticks,
                              CFG.ticks(CFG.sensing_quiet_period), CFG.ticks(CFG.maintenance_hv_debounce),
                              CFG.ticks(CFG.safe_link_recovery), CFG.tick_period)
    assert tm.overrun == 5 and tm.link_loss == 2 and tm.link_recovery > 0
    off = RegimeTimers.from_config(dataclasses.replace(CFG, safe_link_recovery=0.0))
    assert off.link_recovery == 0
    tiny = RegimeTimers.from_config(dataclasses.replace(CFG, sensing_quiet_period=1e-9, maintenance_hv_debounce=1e-9))
    assert (tiny.quiet, tiny.hv_debounce) == (1, 1)  # never a zero-tick debounce


# --- faults: every non-SAFE regime -------------------------------------------------------------------------

def _safe_at_the_nth_consecutive(src, fault: TickInputs, n: int, trigger: Trigger, cause: str) -> None:
    """From ``src``, ``n - 1`` ticks of ``fault`` keep the regime, the ``n``-th goes SAFE with ``trigger`` and
    ``cause``; one good tick in between restarts the count."""
    r = in_regime(src).feed(fault, times=n - 1)
    assert r.regime is src
    r.feed(fault)
    assert (r.regime, r.outs[-1].trigger, r.state.safe_causes) == (X, trigger, (cause,))
    r = in_regime(src).feed(fault, times=n - 1).feed(HOLD[src]).feed(fault, times=n - 1)
    assert r.regime is src


@pytest.mark.parametrize("src", [S, SE, M])
def test_link_lost_after_exactly_link_loss_consecutive_failures(src):
    _safe_at_the_nth_consecutive(src, with_(src, sample_ok=False), T.link_loss, Trigger.LINK_LOST, "link_lost")


@pytest.mark.parametrize("src", [S, SE, M])
def test_sensor_fault_needs_a_sample(src):
    r = in_regime(src).feed(with_(src, sensor_fault=True))
    assert r.regime is X and r.state.safe_causes == ("sensor_fault",)
    r = in_regime(src).feed(with_(src, sensor_fault=True, sample_ok=False))  # no sample: only a link failure
    assert r.regime is src


@pytest.mark.parametrize("src", [S, SE, M])
def test_limit_violation_is_immediate(src):
    r = in_regime(src).feed(with_(src, limit_violation=True))
    assert (r.regime, r.outs[-1].trigger, r.state.safe_causes) == (X, Trigger.LIMIT_VIOLATION, ("limit_violation",))


@pytest.mark.parametrize("src", [S, SE, M])
def test_five_consecutive_overruns_go_safe(src):
    _safe_at_the_nth_consecutive(src, with_(src, overrun=True), T.overrun, Trigger.OVERRUN, "overrun")
    # the documented value: five
    tm = RegimeTimers.from_config(CFG)
    r = Run(tm).feed(TickInputs(overrun=True), times=4)
    assert r.regime is S
    r.feed(TickInputs(overrun=True))
    assert r.regime is X and r.state.safe_causes == ("overrun",)


@pytest.mark.parametrize("src", [S, SE, M])
def test_every_simultaneous_cause_is_latched(src):
    r = in_regime(src).feed(with_(src, overrun=True), times=T.overrun - 1)
    r.feed(with_(src, overrun=True, sensor_fault=True, limit_violation=True))
    assert r.regime is X
    assert r.state.safe_causes == ("sensor_fault", "limit_violation", "overrun")
    assert r.changes()[-1].data["causes"] == ["sensor_fault", "limit_violation", "overrun"]
    r = in_regime(src).feed(with_(src, sample_ok=False, overrun=True), times=T.link_loss - 1)
    r.feed(with_(src, sample_ok=False, overrun=True, limit_violation=True))
    assert r.state.safe_causes == ("link_lost", "limit_violation")
    assert r.outs[-1].trigger is Trigger.LINK_LOST  # highest priority names the transition


def test_causes_arising_in_safe_are_added_once():
    r = in_regime(S).feed(TickInputs(sample_ok=False), times=T.link_loss)
    assert r.state.safe_causes == ("link_lost",)
    r.feed(TickInputs(sample_ok=False, limit_violation=True))
    r.feed(TickInputs(limit_violation=True, sensor_fault=True))
    assert r.state.safe_causes == ("link_lost", "limit_violation", "sensor_fault")
    r.feed(TickInputs(), times=T.link_recovery * 3)  # the link is healthy, but the SAFE was not link loss only
    assert r.regime is X and r.state.safe_causes == ("link_lost", "limit_violation", "sensor_fault")


# --- brown-out ---------------------------------------------------------------------------------------------

def test_brownout_stops_maintenance_and_sensing_not_standby():
    r = in_regime(M).feed(with_(M, brownout=True))
    assert (r.regime, r.outs[-1].trigger, r.state.safe_causes) == (X, Trigger.BROWNOUT, ("brownout",))
    r = in_regime(SE).feed(with_(SE, brownout=True))
    assert (r.regime, r.outs[-1].trigger, r.state.safe_causes) == (S, Trigger.BROWNOUT, ())
    r = in_regime(S).feed(TickInputs(brownout=True), times=3)
    assert r.regime is S and not r.changes()
    # a fault outranks the brown-out and names all its causes
    r = in_regime(M).feed(with_(M, brownout=True, limit_violation=True))
    assert r.outs[-1].trigger is Trigger.LIMIT_VIOLATION and r.state.safe_causes == ("limit_violation",)


# --- maintenance -------------------------------------------------------------------------------------------

def test_hv_present_debounce_and_guard_from_standby():
    hv = TickInputs(hv_present=True)
    r = Run().feed(hv, times=T.hv_debounce - 1)
    assert r.regime is S
    r.feed(hv)
    assert (r.regime, r.outs[-1].trigger) == (M, Trigger.HV_PRESENT) and r.outs[-1].actuation_allowed
    r = Run().feed(hv, times=T.hv_debounce - 1).feed(TickInputs()).feed(hv, times=T.hv_debounce - 1)
    assert r.regime is S  # interrupted
    r = Run().feed(hv, times=T.hv_debounce - 1).feed(hv._replace(sample_ok=False)).feed(hv)
    assert r.regime is S  # a tick without a sample restarts the debounce
    for flip in ({"energy_ok": False}, {"brownout": True}):
        r = Run().feed(hv._replace(**flip), times=T.hv_debounce + 4)
        assert r.regime is S, flip
        (ev,) = r.incidents("wake_refused")
        assert ev.data["detail"] == "HV equipment present but the battery cannot afford waking into MAINTENANCE"
        assert ev.tick == T.hv_debounce - 1
        assert ev.time == pytest.approx((T.hv_debounce - 1) * T.period)
        r.feed(hv)  # energy back, equipment still there: enters at once
        assert r.regime is M


def test_hv_present_from_sensing_has_no_energy_guard():
    r = in_regime(SE).feed(with_(SE, hv_present=True, energy_ok=False), times=T.hv_debounce - 1)
    assert r.regime is SE
    r.feed(with_(SE, hv_present=True, energy_ok=False))
    assert (r.regime, r.outs[-1].trigger) == (M, Trigger.HV_PRESENT)


def test_hv_removed_debounce():
    off = TickInputs()
    r = in_regime(M).feed(off, times=T.hv_debounce - 1)
    assert r.regime is M and r.outs[-1].actuation_allowed
    r.feed(off)
    assert (r.regime, r.outs[-1].trigger, r.outs[-1].actuation_allowed) == (S, Trigger.HV_REMOVED, False)
    r = in_regime(M).feed(off, times=T.hv_debounce - 1).feed(HOLD[M]).feed(off, times=T.hv_debounce - 1)
    assert r.regime is M
    # a tick without a sample neither counts nor restarts the absence
    r = in_regime(M).feed(off, times=T.hv_debounce - 1).feed(off._replace(sample_ok=False))
    assert r.regime is M
    r.feed(off)
    assert r.regime is S


# --- flight ------------------------------------------------------------------------------------------------

def test_wake_debounce_and_each_guard():
    w = TickInputs(wake_signal=True)
    r = Run().feed(w, times=T.wake_debounce - 1)
    assert r.regime is S
    r.feed(w)
    assert (r.regime, r.outs[-1].trigger, r.outs[-1].changed) == (SE, Trigger.WAKE, True)
    assert not r.outs[-1].actuation_allowed
    r = Run().feed(w, times=T.wake_debounce - 1).feed(TickInputs()).feed(w, times=T.wake_debounce - 1)
    assert r.regime is S
    r = Run().feed(w, times=T.wake_debounce - 1).feed(w._replace(sample_ok=False)).feed(w)
    assert r.regime is S
    for flip in ({"energy_ok": False}, {"brownout": True}):
        r = Run().feed(w._replace(**flip), times=T.wake_debounce + 5)
        assert r.regime is S, flip
        (ev,) = r.incidents("wake_refused")  # once per comparator episode
        assert ev.data["detail"] == ("wake comparator fired but the battery cannot afford waking "
                                     "(below wake_min_voltage or brown-out)")
        assert ev.tick == T.wake_debounce - 1 and ev.time == pytest.approx((T.wake_debounce - 1) * T.period)
        r.feed(w)
        assert r.regime is SE


def test_a_sensor_fault_tick_does_not_count_toward_waking():
    w = TickInputs(wake_signal=True)
    r = Run().feed(w, times=T.wake_debounce - 1).feed(w._replace(sensor_fault=True))
    assert r.regime is X
    r.feed(w._replace(rearm=True))
    assert r.regime is S
    r.feed(w, times=T.wake_debounce - 2)
    assert r.regime is S  # the count restarted at the fault
    r.feed(w)
    assert r.regime is SE


def test_quiet_period_returns_to_standby():
    q = TickInputs()
    r = in_regime(SE).feed(q, times=T.quiet - 1)
    assert r.regime is SE
    r.feed(q)
    assert (r.regime, r.outs[-1].trigger) == (S, Trigger.QUIET)
    r = in_regime(SE).feed(q, times=T.quiet - 1).feed(HOLD[SE]).feed(q, times=T.quiet - 1)
    assert r.regime is SE  # activity restarts the quiet period
    r = in_regime(SE).feed(q, times=T.quiet - 1).feed(q._replace(sample_ok=False))
    assert r.regime is SE  # no sample: neither quiet nor active
    r.feed(q)
    assert r.regime is S
    # a sensor fault is not activity: the sensor fault takes SAFE, never a fresh SENSING episode
    r = in_regime(SE).feed(q, times=T.quiet - 1).feed(with_(SE, sensor_fault=True))
    assert r.regime is X


# --- leaving SAFE ------------------------------------------------------------------------------------------

def link_lost_safe(timers: RegimeTimers = T) -> Run:
    r = Run(timers).feed(TickInputs(sample_ok=False), times=timers.link_loss)
    assert r.regime is X and r.state.safe_causes == ("link_lost",)
    r.events.clear()
    return r


def test_link_recovered_after_exactly_link_recovery_good_ticks():
    r = link_lost_safe().feed(TickInputs(), times=T.link_recovery - 1)
    assert r.regime is X
    r.feed(TickInputs())
    assert (r.regime, r.outs[-1].trigger, r.state.safe_causes) == (S, Trigger.LINK_RECOVERED, ())
    # interrupted by a failed exchange (not enough for a new link loss): the healthy time restarts
    r = link_lost_safe().feed(TickInputs(), times=T.link_recovery - 1).feed(TickInputs(sample_ok=False))
    r.feed(TickInputs(), times=T.link_recovery - 1)
    assert r.regime is X


def test_link_recovery_of_one_tick_recovers_on_the_first_good_exchange():
    one = dataclasses.replace(T, link_recovery=1)  # the smallest enabled recovery time
    r = link_lost_safe(one).feed(TickInputs())
    assert (r.regime, r.outs[-1].trigger, r.state.safe_causes) == (S, Trigger.LINK_RECOVERED, ())


def test_link_recovered_each_guard():
    off = dataclasses.replace(T, link_recovery=0)
    r = link_lost_safe(off).feed(TickInputs(), times=50)
    assert r.regime is X  # disabled: operator re-arm only
    for flip in ({"brownout": True}, {"limit_violation": True}, {"sensor_fault": True}):
        r = link_lost_safe().feed(TickInputs(), times=T.link_recovery - 1).feed(TickInputs(**flip))
        assert r.regime is X, flip
    r = link_lost_safe().feed(TickInputs(), times=T.link_recovery - 1).feed(TickInputs(brownout=True))
    r.feed(TickInputs())
    assert r.regime is S  # the brown-out was not latched: recovery as soon as it is gone
    r = link_lost_safe().feed(TickInputs(overrun=True), times=T.overrun + 2)
    assert r.regime is X and "overrun" in r.state.safe_causes


@pytest.mark.parametrize(("persisting", "named"), [
    ({"sample_ok": False}, ["no sample"]),
    ({"sensor_fault": True}, ["sensor_fault"]),
    ({"limit_violation": True}, ["limit_violation"]),
    ({"brownout": True}, ["brownout"]),
])
def test_rearm_refused_while_any_one_cause_persists(persisting, named):
    r = in_regime(X).feed(TickInputs(rearm=True, **persisting))
    assert r.regime is X and not r.outs[-1].changed
    (ev,) = r.incidents("rearm_refused")
    assert ev.data["detail"] == "re-arm refused: " + ", ".join(named)
    assert (ev.tick, ev.time) == (r.tick - 1, pytest.approx((r.tick - 1) * T.period))
    r.feed(TickInputs(rearm=True))
    assert (r.regime, r.outs[-1].trigger) == (S, Trigger.REARM)
    (ch,) = r.changes()
    assert ch.data == {"from_regime": "SAFE", "to_regime": "STANDBY_HARVEST", "trigger": "rearm", "causes": []}
    assert (ch.tick, ch.time, r.state.entered_tick) == (r.tick - 1, pytest.approx((r.tick - 1) * T.period),
                                                         r.tick - 1)


def test_rearm_refused_while_overruns_or_link_loss_persist():
    r = in_regime(X).feed(TickInputs(overrun=True), times=T.overrun - 1).feed(TickInputs(overrun=True, rearm=True))
    assert r.regime is X and r.incidents("rearm_refused")[0].data["detail"] == "re-arm refused: overrun"
    r = in_regime(X).feed(TickInputs(sample_ok=False), times=T.link_loss - 1)
    r.feed(TickInputs(sample_ok=False, rearm=True))
    assert r.incidents("rearm_refused")[0].data["detail"] == "re-arm refused: link_lost, no sample"
    r = in_regime(X).feed(TickInputs(), times=20)
    assert r.regime is X  # no re-arm asked: SAFE stays
    assert r.state.entered_tick == 0  # the tick it went SAFE, kept while it stays


def test_every_change_is_allowed_and_only_maintenance_actuates():
    r = Run()
    seq = [TickInputs(wake_signal=True)] * 3 + [TickInputs(wake_signal=True, hv_present=True)] * 3 + \
          [TickInputs(limit_violation=True), TickInputs(rearm=True)] + [TickInputs()] * 2
    prev = r.regime
    for inp in seq:
        r.feed(inp)
        out = r.outs[-1]
        assert out.actuation_allowed is (out.regime is M)
        assert out.changed is (out.regime is not prev)
        if out.changed:
            assert is_allowed(prev, out.regime)
        prev = out.regime
    assert [c.data["to_regime"] for c in r.changes()] == ["SENSING", "MAINTENANCE", "SAFE", "STANDBY_HARVEST"]
    assert not is_allowed(S, S) and not is_allowed(X, SE)


@pytest.mark.parametrize(("field", "n"), [("overrun", T.overrun), ("wake_signal", T.wake_debounce),
                                          ("hv_present", T.hv_debounce)])
def test_one_uneventful_tick_restarts_every_count_in_a_settled_standby(field, n):
    # a settled stand-by (every counter saturated or zero: the tick the board spends most of its life in)
    r = Run().feed(TickInputs(), times=T.quiet + T.hv_debounce + T.link_recovery)
    ev = TickInputs(**{field: True})
    r.feed(ev).feed(TickInputs()).feed(ev, times=n - 1)  # one, a break, then one short of the debounce
    assert r.regime is S and not r.changes()
    r.feed(ev)
    assert r.regime is not S


@pytest.mark.parametrize("link_recovery", [0, 1, 3])
def test_a_settled_standby_tick_hands_the_state_back_unchanged(link_recovery):
    # step()'s documented shortcut: once every debounce run is saturated, an uneventful stand-by tick (with or without
    # the energy to wake) costs nothing: the very same state comes back, no change, no event
    tm = dataclasses.replace(T, link_recovery=link_recovery)
    r = Run(tm).feed(TickInputs(), times=max(tm.quiet, tm.hv_debounce, tm.link_recovery))
    settled = r.state
    for inp in (TickInputs(), TickInputs(energy_ok=False)):
        new, out, events = step(settled, inp, r.tick, tm)
        assert new is settled and out == RegimeOutputs(S, False, False, None) and events == ()
    # an eventful percept is evaluated (and changes the state)
    assert step(settled, TickInputs(wake_signal=True), r.tick, tm)[0] != settled


def test_a_brownout_in_sensing_restarts_the_wake_debounce():
    # SENSING counts the comparator afresh from its entry: forced back to stand-by by a brown-out one tick later, the
    # board reports the refused wake when the comparator has been up a full debounce since then, not at once
    r = in_regime(SE).feed(with_(SE, brownout=True))
    assert r.regime is S and r.outs[-1].trigger is Trigger.BROWNOUT
    r.feed(with_(SE, brownout=True), times=T.wake_debounce - 2)
    assert not r.incidents("wake_refused")
    r.feed(with_(SE, brownout=True))
    assert len(r.incidents("wake_refused")) == 1 and r.regime is S
