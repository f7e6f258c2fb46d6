"""The power manager's decisions, each condition shown to matter (MC/DC style), and a tick-sequence property.

Oracle: the rules of ``firmware_sim/power_manager.py``'s docstring and docs/board.md — a brown-out is declared after
``brownout_ticks`` *consecutive* ticks with a valid voltage below ``brownout_voltage`` (a tick without a valid
voltage — NaN, or not positive — neither counts nor breaks the run), it clears strictly above
``brownout_voltage + brownout_hysteresis``; waking needs ``v >= wake_min_voltage`` and no brown-out.
"""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from board_config.board import load_board_config
from firmware_sim.power_manager import PowerBudget, PowerLedger, PowerState, power_step
from firmware_sim.regimes import Regime

CFG = load_board_config()
B = PowerBudget.from_config(CFG)
N = B.brownout_ticks
LOW = B.brownout - 0.05  # a valid voltage below the brown-out threshold
HIGH = B.wake_min + 0.2  # comfortably able to wake
CLEAR = B.brownout + B.hysteresis


def feed(voltages, state=None, start=0, regime=Regime.SENSING):
    s = state or PowerState()
    out = []
    for k, v in enumerate(voltages, start=start):
        s, status, ev = power_step(s, v, regime, k, B)
        out.append((s, status, ev))
    return out


def incidents(out):
    return [e for _, _, ev in out for e in ev]


def test_budget_is_the_config():
    want = PowerBudget(CFG.power_current_standby, CFG.power_current_sensing, CFG.power_current_maintenance,
                       CFG.power_current_safe, CFG.power_wake_min_voltage, CFG.power_brownout_voltage,
                       CFG.power_brownout_hysteresis, CFG.power_brownout_ticks, CFG.tick_period)
    assert PowerBudget.from_config(CFG) == want == B
    assert N >= 2  # the consecutive-ticks tests below need a run of at least two


def test_brownout_after_exactly_n_consecutive_ticks_with_its_incident():
    out = feed([HIGH] + [LOW] * N, start=100)
    assert [o[1].brownout for o in out] == [False] * N + [True]
    (ev,) = incidents(out)
    k = 100 + N
    assert (ev.kind, ev.tick, ev.time) == ("incident", k, pytest.approx(k * B.period))
    assert ev.data["incident"] == "brownout"
    detail = ev.data["detail"]
    assert f"{LOW:.4f} V" in detail and f"{B.brownout:.4f} V" in detail
    assert f"{N} ticks" in detail and Regime.SENSING.value in detail
    assert out[-1][0] == PowerState(True, N, 1)


def test_below_run_must_be_consecutive():
    # N-1 below, one valid tick at/above the threshold, N-1 below: never N consecutive -> no brown-out
    for breaker in (B.brownout, HIGH, CLEAR):
        out = feed([LOW] * (N - 1) + [breaker] + [LOW] * (N - 1))
        assert not any(o[1].brownout for o in out), breaker
        assert out[N - 1][0].below_run == 0
    # a run of one, broken, then N-1: still not N consecutive
    out = feed([LOW, HIGH] + [LOW] * (N - 1))
    assert not any(o[1].brownout for o in out)


def test_exactly_at_the_threshold_is_not_below():
    out = feed([B.brownout] * (N + 2))
    assert not incidents(out) and not out[-1][1].brownout
    assert all(o[0].below_run == 0 for o in out)


@pytest.mark.parametrize("unknown", [math.nan, 0.0, -1.0])
def test_unknown_voltage_holds_the_decision(unknown):
    # N-1 below, then an unknown tick: no brown-out, may not wake, the run is kept (neither counted nor broken)
    out = feed([LOW] * (N - 1) + [unknown])
    assert out[-1][0] == out[-2][0] and not incidents(out)
    assert out[-1][1].energy_ok is False and out[-1][1].brownout is False
    out = feed([LOW] * (N - 1) + [unknown, LOW])
    assert out[-1][1].brownout and len(incidents(out)) == 1
    # during a brown-out an unknown voltage keeps it in force
    out = feed([LOW] * N + [unknown, unknown])
    assert out[-1][1].brownout and out[-1][0].brownout


def test_a_small_valid_voltage_is_below_not_unknown():
    out = feed([0.5] * N)
    assert out[-1][1].brownout


def test_brownout_stays_while_below_and_counts_saturate():
    out = feed([LOW] * (N + 5))
    assert all(o[1].brownout for o in out[N - 1:])
    assert not any(o[1].energy_ok for o in out)
    assert out[-1][0] == PowerState(True, N, 1)
    assert len(incidents(out)) == 1


def test_clears_strictly_above_the_hysteresis_band_once():
    base = [LOW] * N
    # at the band edge, or between threshold and edge: still in force, run reset
    out = feed([*base, CLEAR, B.brownout + B.hysteresis / 2])
    assert out[-1][1].brownout and out[-2][1].brownout
    assert out[-1][0] == PowerState(True, 0, 1)
    out = feed([*base, CLEAR + 1e-06, HIGH, HIGH], start=7)
    detail = feed([*base, HIGH])[-1][2][0].data["detail"]
    assert detail == f"battery {HIGH:.4f} V above {CLEAR:.4f} V"
    cleared = out[N]
    assert cleared[1].brownout is False and cleared[0] == PowerState(False, 0, 1)
    evs = incidents(out)
    assert [e.data["incident"] for e in evs] == ["brownout", "brownout_cleared"]  # the flag clears: once
    ev = evs[1]
    k = 7 + N
    assert (ev.kind, ev.tick, ev.time) == ("incident", k, pytest.approx(k * B.period))
    assert f"{CLEAR + 1e-6:.4f} V" in ev.data["detail"] and f"{CLEAR:.4f} V" in ev.data["detail"]
    assert not out[-1][1].brownout and out[-1][1].energy_ok
    # a second brown-out counts
    out = feed([LOW] * N, state=out[-1][0])
    assert out[-1][0].brownouts == 2


def test_below_run_counts_consecutive_ticks_also_during_a_brownout():
    # PowerState.below_run is "consecutive ticks below the brown-out voltage": a tick in the hysteresis band ends
    # the run whatever its length, 1 included
    band = B.brownout + B.hysteresis / 2
    out = feed([LOW] * N + [band, LOW, band, LOW, LOW, band])
    assert [o[0].below_run for o in out[N:]] == [0, 1, 0, 1, 2, 0]
    assert all(o[1].brownout for o in out[N - 1:]) and out[-1][0].brownouts == 1


@pytest.mark.parametrize(("v", "ok"), [(B.wake_min, True), (B.wake_min - 1e-6, False)])
def test_wake_threshold_is_inclusive_on_every_path(v, ok):
    assert feed([v])[0][1].energy_ok is ok  # no brown-out in force
    # the tick that clears a brown-out
    if v > CLEAR:
        out = feed([LOW] * N + [v])
        assert out[-1][1].brownout is False and out[-1][1].energy_ok is ok


def reference(voltages):
    """The documented rules, tick by tick: (brownout, energy_ok, incident names, consecutive ticks below)."""
    brown, run, out = False, 0, []
    for v in voltages:
        evs = []
        if not (v > 0.0):  # NaN or not positive: unknown, hold
            out.append((brown, False, evs, run))
            continue
        if v < B.brownout:
            run = min(run + 1, N)
            if not brown and run == N:
                brown = True
                evs.append("brownout")
        else:
            run = 0
            if brown and v > CLEAR:
                brown = False
                evs.append("brownout_cleared")
        out.append((brown, (not brown) and v >= B.wake_min, evs, run))
    return out


VOLTS = st.sampled_from([math.nan, 0.0, 0.5, LOW, B.brownout, B.brownout + B.hysteresis / 2, CLEAR, CLEAR + 1e-6,
                         B.wake_min - 1e-6, B.wake_min, HIGH])


@settings(max_examples=300, deadline=None)
@given(st.lists(VOLTS, min_size=1, max_size=40))
def test_random_voltage_sequences_follow_the_rules(seq):
    got = feed(seq)
    want = reference(seq)
    for (s, status, ev), (brown, ok, names, run) in zip(got, want, strict=True):
        assert (status.brownout, status.energy_ok, [e.data["incident"] for e in ev]) == (brown, ok, names)
        assert (s.brownout, s.below_run) == (brown, run)
    assert got[-1][0].brownouts == sum(w[2].count("brownout") for w in want)


def test_ledger_counts_valid_voltages_only():
    led = PowerLedger(B)
    assert (math.isnan(led.v_first), math.isnan(led.v_last), led.v_min, led.energy_used) == (True, True, math.inf, 0)
    led.add(Regime.SAFE, 0.0)  # not a valid voltage: time counted, no energy (nothing known yet)
    assert led.energy_used == 0.0 and math.isnan(led.v_last) and led.v_min == math.inf
    led.add(Regime.MAINTENANCE, 3.0)
    led.add(Regime.MAINTENANCE, 3.5)
    led.add(Regime.SAFE, math.nan)
    assert (led.v_first, led.v_last, led.v_min) == (3.0, 3.5, 3.0)
    low = PowerLedger(B)
    low.add(Regime.SAFE, 0.5)  # a deeply discharged cell is still a measurement
    assert (low.v_first, low.v_last, low.v_min) == (0.5, 0.5, 0.5)
    assert led.energy_used == pytest.approx(B.period * (B.maintenance * 3.0 + B.maintenance * 3.5 + B.safe * 3.5))
    assert led.ticks == {Regime.STANDBY_HARVEST: 0, Regime.SENSING: 0, Regime.MAINTENANCE: 2, Regime.SAFE: 2}
    assert led.charge_by_regime() == pytest.approx({"STANDBY_HARVEST": 0.0, "SENSING": 0.0,
                                                    "MAINTENANCE": 2 * B.maintenance * B.period,
                                                    "SAFE": 2 * B.safe * B.period})
    assert led.time_by_regime() == pytest.approx({"STANDBY_HARVEST": 0.0, "SENSING": 0.0,
                                                  "MAINTENANCE": 2 * B.period, "SAFE": 2 * B.period})
    assert led.charge_used == pytest.approx(sum(led.charge_by_regime().values()))
