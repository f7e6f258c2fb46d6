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
* accounting (:class:`PowerLedger`) — charge (C) and energy (J, at the measured voltage) drawn per regime, and the
  first, last and lowest voltage seen.

A tick without a valid voltage (link down, NaN) holds the brown-out decision and refuses waking.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from board_config.board import BoardConfig
from firmware_sim.events import BoardEvent
from firmware_sim.regimes import Regime


class PowerState(NamedTuple):
    """What the brown-out detector remembers."""

    brownout: bool = False
    below_run: int = 0  # consecutive ticks below the brown-out voltage (saturates at brownout_ticks)
    brownouts: int = 0  # brown-outs declared so far


class PowerStatus(NamedTuple):
    energy_ok: bool  # may wake
    brownout: bool  # brown-out in force


_OK = PowerStatus(True, False)
_LOW = PowerStatus(False, False)
_BROWN = PowerStatus(False, True)


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
    """One tick: measured terminal voltage ``v_battery`` (V; NaN if unknown) while in ``regime``.

    ``energy_ok`` uses this tick's voltage; with an unknown voltage the previous decision cannot be re-checked, so the
    board may not wake (``energy_ok`` False) and a brown-out in force stays in force.
    """
    if not v_battery >= budget.brownout:  # below, or NaN
        if v_battery != v_battery or v_battery <= 0.0:  # unknown: hold
            return state, (_BROWN if state.brownout else _LOW), ()
        below_run = min(state.below_run + 1, budget.brownout_ticks)
        if not state.brownout and below_run >= budget.brownout_ticks:
            ev = BoardEvent("incident", tick, tick * budget.period, {
                "incident": "brownout", "detail": f"battery {v_battery:.4f} V below {budget.brownout:.4f} V for "
                                                  f"{below_run} ticks in {regime.value}"})
            return PowerState(True, below_run, state.brownouts + 1), _BROWN, (ev,)
        st = state if below_run == state.below_run else state._replace(below_run=below_run)
        return st, (_BROWN if st.brownout else _LOW), ()
    if state.brownout:
        if v_battery > budget.brownout + budget.hysteresis:
            ev = BoardEvent("incident", tick, tick * budget.period, {
                "incident": "brownout_cleared",
                "detail": f"battery {v_battery:.4f} V above {budget.brownout + budget.hysteresis:.4f} V"})
            return PowerState(False, 0, state.brownouts), (_OK if v_battery >= budget.wake_min else _LOW), (ev,)
        st = state if state.below_run == 0 else state._replace(below_run=0)
        return st, _BROWN, ()
    st = state if state.below_run == 0 else state._replace(below_run=0)
    return st, (_OK if v_battery >= budget.wake_min else _LOW), ()


class PowerLedger:
    """The board's accounting of its own consumption: ticks and charge per regime (from its declared currents),
    energy at the measured voltage, first/last/lowest valid voltage. Plain counters, updated once per tick."""

    __slots__ = ("_charge_per_tick", "budget", "energy_used", "ticks", "v_first", "v_last", "v_min")

    def __init__(self, budget: PowerBudget) -> None:
        self.budget = budget
        self.ticks = {r: 0 for r in Regime}
        self._charge_per_tick = {r: budget.current(r) * budget.period for r in Regime}  # C per tick
        self.energy_used = 0.0  # J
        self.v_first = math.nan
        self.v_last = math.nan
        self.v_min = math.inf

    def add(self, regime: Regime, v_battery: float) -> None:
        self.ticks[regime] += 1
        if v_battery > 0.0:  # valid (NaN compares False)
            self.v_last = v_battery
            if v_battery < self.v_min:
                self.v_min = v_battery
            if self.v_first != self.v_first:
                self.v_first = v_battery
        if self.v_last == self.v_last:
            self.energy_used += self._charge_per_tick[regime] * self.v_last

    def add_many(self, regime: Regime, v_battery: np.ndarray) -> None:
        """``len(v_battery)`` calls of :meth:`add` with valid (positive) voltages, at once (bit-identical: the
        energy is summed in the same order)."""
        n = int(v_battery.shape[0])
        if n == 0:
            return
        self.ticks[regime] += n
        self.v_last = float(v_battery[-1])
        self.v_min = min(self.v_min, float(v_battery.min()))
        if self.v_first != self.v_first:
            self.v_first = float(v_battery[0])
        terms = np.empty(n + 1)
        terms[0] = self.energy_used
        np.multiply(self._charge_per_tick[regime], v_battery, out=terms[1:])
        self.energy_used = float(np.add.accumulate(terms)[-1])  # sequential, as n calls of add

    @property
    def charge_used(self) -> float:
        """Charge drawn (C): declared current x time, summed over the regimes."""
        return sum(self.budget.current(r) * n * self.budget.period for r, n in self.ticks.items())

    def charge_by_regime(self) -> dict[str, float]:
        return {r.value: self.budget.current(r) * n * self.budget.period for r, n in self.ticks.items()}

    def time_by_regime(self) -> dict[str, float]:
        return {r.value: n * self.budget.period for r, n in self.ticks.items()}
