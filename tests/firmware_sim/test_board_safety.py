"""Safety of the whole board (issue 5, point 6): random event sequences through ``Board.tick`` with hypothesis.

Whatever the samples, the link or a misbehaving sequencer do: no command leaves Table 1's range, the demand is zero
outside MAINTENANCE, the board is SAFE within ``[tick] link_loss_ticks`` of losing the link, no regime change is
absent from the transition table, and a replay of the same sequence gives the same commands and events.
"""

from __future__ import annotations

import math

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from board_config import load_mfc_limits
from board_config.board import load_board_config
from drivers.link import FLAG_LIMIT_REFUSED, FLAG_SENSOR_FAULT, RigSample
from firmware_sim.board import Board
from firmware_sim.regimes import ALLOWED, Regime

LIMITS = load_mfc_limits()
CFG = load_board_config()

KINDS = ("quiet", "wake", "hv", "hv_wake", "low_battery", "brownout", "nan", "link_fail", "frozen", "flag_fault",
         "limit_refused", "rearm", "overrun", "huge_z3")


@pytest.fixture(scope="module")
def nominal_model():
    from plant import PlantModel

    return PlantModel("table2", terminal="amplifier")


def sample_for(kind: str, seq: int, hv_on: bool) -> RigSample | None:
    if kind == "link_fail":
        return None
    v_batt = {"low_battery": 2.6, "brownout": 2.1}.get(kind, 2.95)
    z0dd = 9.0 if kind in ("wake", "hv_wake") else 0.1
    z3 = {"nan": math.nan, "huge_z3": 0.5}.get(kind, 1e-4)
    flags = {"flag_fault": FLAG_SENSOR_FAULT, "limit_refused": FLAG_LIMIT_REFUSED}.get(kind, 0)
    return RigSample(seq=seq, t=seq * 0.01, z3=z3, v_patch=0.01, z0dd=z0dd, v_battery=v_batt,
                     hv_present=hv_on or kind in ("hv", "hv_wake"), flags=flags)


def drive(board: Board, plan: list[tuple[str, int]]):
    """Feed a plan of (kind, repetitions); return per-tick (command, regime, events) and check invariants."""
    seq = 0
    k = 0
    lost = 0
    hv_on = False
    out = []
    prev_regime = board.regime
    for kind, reps in plan:
        if kind == "hv":
            hv_on = True
        elif kind == "quiet":
            hv_on = False
        for _ in range(reps):
            k += 1
            if kind != "frozen":
                seq += 1
            if kind == "rearm":
                board.request_rearm()
            smp = sample_for(kind, seq, hv_on)
            res = board.tick(smp, k, overrun=(kind == "overrun"), link_error="timeout" if smp is None else "")
            cmd = res.command
            # 1. Table 1, always; finite
            for v in (cmd.v_ch1, cmd.v_ch2):
                assert math.isfinite(v) and LIMITS.voltage_min <= v <= LIMITS.voltage_max, (kind, cmd)
            # 2. zero demand outside MAINTENANCE
            if res.regime is not Regime.MAINTENANCE:
                assert cmd.v_ch1 == 0.0 and cmd.v_ch2 == 0.0, (res.regime, cmd)
            # 3. the board's current is its regime's
            assert cmd.board_current == board.budget.current(res.regime)
            # 4. SAFE within link_loss_ticks of link loss
            lost = lost + 1 if smp is None else 0
            if lost >= CFG.tick_link_loss_ticks:
                assert res.regime is Regime.SAFE
            # 5. only table transitions, one regime_change event per change
            changes = [e for e in res.events if e.kind == "regime_change"]
            if res.regime is not prev_regime:
                assert (prev_regime, res.regime) in ALLOWED
                assert len(changes) == 1
                assert changes[0].data["from_regime"] == prev_regime.value
                assert changes[0].data["to_regime"] == res.regime.value
            else:
                assert not changes
            prev_regime = res.regime
            out.append((cmd, res.regime, [(e.kind, e.tick, dict(e.data)) for e in res.events]))
    return out


plans = st.lists(st.tuples(st.sampled_from(KINDS), st.integers(1, 120)), min_size=1, max_size=12)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(plan=plans)
def test_random_event_sequences_are_safe_and_replay_identically(plan, nominal_model):
    a = drive(Board(CFG, nominal_model=nominal_model), plan)
    b = drive(Board(CFG, nominal_model=nominal_model), plan)
    assert a == b


def test_maintenance_sequence_actuates_within_limits(nominal_model):
    """A long HV presence reaches the MBITs: commands are non-zero, inside Table 1, and a verdict is logged."""
    board = Board(CFG, nominal_model=nominal_model)
    res = drive(board, [("hv", 3500)])
    regimes = {r for _, r, _ in res}
    assert Regime.MAINTENANCE in regimes
    peak = max(max(abs(c.v_ch1), abs(c.v_ch2)) for c, _, _ in res)
    assert peak > 500.0  # MBIT.a drives one channel to 700 V (600 V sine + 100 V bias)
    kinds = [k for _, _, evs in res for k, _, _ in evs]
    assert "mbit_result" in kinds and "maintenance_verdict" in kinds


def test_output_guard_catches_a_misbehaving_sequencer(nominal_model):
    """Even if the MBIT generator asked for 1e6 V or NaN, nothing outside Table 1 leaves the board, and it goes SAFE."""
    board = Board(CFG, nominal_model=nominal_model)
    drive(board, [("hv", 60)])
    assert board.regime is Regime.MAINTENANCE
    for wild in ((1e6, -1e6), (math.nan, 0.0), (0.0, math.inf), (LIMITS.voltage_max + 1.0, 0.0)):
        board.maintenance.step = lambda k, z3, w=wild: (w, [])  # type: ignore[method-assign]
        res = board.tick(sample_for("hv", 10_000 + board.ticks, True), 10_000 + board.ticks)
        assert res.command.v_ch1 == 0.0 and res.command.v_ch2 == 0.0
        nxt = board.tick(sample_for("hv", 20_000 + board.ticks, True), 20_000 + board.ticks)
        assert nxt.regime is Regime.SAFE
        assert any(e.data.get("incident") == "limit_violation" for e in nxt.events)
        assert nxt.command.v_ch1 == 0.0 and nxt.command.v_ch2 == 0.0
        board.state = board.state._replace(regime=Regime.MAINTENANCE)  # force back for the next wild value
        board.maintenance.active = True


def test_monitor_rate_must_match_the_tick(nominal_model):
    from dataclasses import replace

    from board_config import load_monitor_settings

    with pytest.raises(ValueError, match="f_mon"):
        Board(CFG, monitor=replace(load_monitor_settings(), f_mon=50.0), nominal_model=nominal_model)
