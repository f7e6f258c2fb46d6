"""The power manager: the board's own view of its energy — pure logic, one call per tick.

The cell is rig hardware (``hil_stub.rig``: the harvesting model of ``plant.effects.harvesting`` charges it, the
board's load discharges it); the board only *measures* its terminal voltage in every sample and *declares* its own
current draw in every command. From those:

* ``current(regime)`` — the current the board draws in each regime (``[power] current_*`` of ``board.toml``); the
  board sends it with its command, so the rig's battery sees it.
* ``energy_ok`` — the board may wake (into SENSING or MAINTENANCE) only with the battery at or above
  ``wake_min_voltage`` and no brown-out in force: *it cannot wake without energy*.
* brown-out — the voltage below ``brownout_voltage`` for ``brownout_ticks`` consecutive ticks declares one (an
  ``incident`` event, ``brownout``); it clears above ``brownout_voltage + brownout_hysteresis`` (``brownout_cleared``).
  The regime machine then forces stand-by (from SENSING) or SAFE (from MAINTENANCE): see ``regimes.TRANSITIONS``.
* accounting — charge (C) and energy (J, at the measured voltage) drawn per regime, and the lowest voltage seen.

A tick without a valid voltage (link down, NaN) holds every decision.
"""

from __future__ import annotations

import math
from typing import NamedTuple

from board_config.board import BoardConfig
from firmware_sim.events import BoardEvent
from firmware_sim.regimes import Regime


class PowerState(NamedTuple):
    brownout: bool = False
    below_run: int = 0  # consecutive ticks below the brown-out voltage
    v_last: float = math.nan  # last valid measured battery voltage (V)
    v_min: float = math.inf  # lowest valid measured voltage (V)
    charge_used: float = 0.0  # C, drawn by the board (its declared current x tick)
    energy_used: float = 0.0  # J, charge x measured voltage
    brownouts: int = 0  # brown-outs declared so far


class PowerStatus(NamedTuple):
    energy_ok: bool  # may wake
    brownout: bool  # brown-out in force
    current: float  # A, the board's draw this tick


class PowerBudget(NamedTuple):
    """Currents per regime (A) and the voltage thresholds (V), from ``board.toml``."""

    standby: float
    sensing: float
    maintenance: float
    safe: float
    wake_min: float
    brownout: float
    hysteresis: float
    brownout_ticks: int
    period: float  # s

    @classmethod
    def from_config(cls, cfg: BoardConfig) -> PowerBudget:
        return cls(cfg.power_current_standby, cfg.power_current_sensing, cfg.power_current_maintenance,
                   cfg.power_current_safe, cfg.power_wake_min_voltage, cfg.power_brownout_voltage,
                   cfg.power_brownout_hysteresis, cfg.power_brownout_ticks, cfg.tick_period)

    def current(self, regime: Regime) -> float:
        """Current the board draws in ``regime`` (A)."""
        if regime is Regime.STANDBY_HARVEST:
            return self.standby
        if regime is Regime.SENSING:
            return self.sensing
        if regime is Regime.MAINTENANCE:
            return self.maintenance
        return self.safe


def power_step(state: PowerState, v_battery: float, regime: Regime, tick: int, budget: PowerBudget
               ) -> tuple[PowerState, PowerStatus, tuple[BoardEvent, ...]]:
    """One tick: measured terminal voltage ``v_battery`` (V; NaN if unknown) while in ``regime``."""
    i = budget.current(regime)
    dq = i * budget.period
    valid = math.isfinite(v_battery) and v_battery > 0.0
    if not valid:
        st = state._replace(charge_used=state.charge_used + dq,
                            energy_used=state.energy_used + dq * (state.v_last if math.isfinite(state.v_last) else 0.0))
        return st, PowerStatus(not st.brownout and st.v_last >= budget.wake_min, st.brownout, i), ()
    events: tuple[BoardEvent, ...] = ()
    below_run = state.below_run + 1 if v_battery < budget.brownout else 0
    brownout = state.brownout
    n_brownouts = state.brownouts
    now = tick * budget.period
    if not brownout and below_run >= budget.brownout_ticks:
        brownout = True
        n_brownouts += 1
        events = (BoardEvent("incident", tick, now, {
            "incident": "brownout", "detail": f"battery {v_battery:.4f} V below {budget.brownout:.4f} V for "
                                              f"{below_run} ticks in {regime.value}"}),)
    elif brownout and v_battery > budget.brownout + budget.hysteresis:
        brownout = False
        events = (BoardEvent("incident", tick, now, {
            "incident": "brownout_cleared",
            "detail": f"battery {v_battery:.3f} V above {budget.brownout + budget.hysteresis:.3f} V"}),)
    st = PowerState(brownout, below_run, v_battery, min(state.v_min, v_battery), state.charge_used + dq,
                    state.energy_used + dq * v_battery, n_brownouts)
    return st, PowerStatus(not brownout and v_battery >= budget.wake_min, brownout, i), events
