"""State of charge from a battery voltage, as a board that measures only its voltage can know it: the voltage read
on the cell's open-circuit curve (``board_config.battery``), tabulated once so that a publication costs a lookup
(the curve's own inversion is an iteration of several milliseconds: too long for the board's tick)."""

from __future__ import annotations

import math

import numpy as np

from board_config.battery import BatterySpec, load_battery

#: points of the table over the cell's voltage range
POINTS = 512


class SocEstimate:
    """``soc(v)``: 1 full, 0 at the cut-off; None for a non-finite voltage; clipped to the cell's voltage range."""

    def __init__(self, battery: BatterySpec | None = None) -> None:
        self.battery = battery if battery is not None else load_battery()
        lo, hi = self.battery.voltage_range
        self._v = np.linspace(lo, hi, POINTS)
        self._soc = 1.0 - np.asarray(self.battery.discharged_capacity(self._v)) / self.battery.capacity
        order = np.argsort(self._v)
        self._v, self._soc = self._v[order], self._soc[order]

    @property
    def note(self) -> str:
        return f"estimated from the measured voltage on the {self.battery.name} open-circuit curve"

    def soc(self, v: float | None) -> float | None:
        if v is None or not math.isfinite(v):
            return None
        return float(np.interp(v, self._v, self._soc))
