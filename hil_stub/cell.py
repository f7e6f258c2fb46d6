"""The board's cell as rig hardware, while it is not a state of the truth plant.

In flight the cell is the state ``bat_qd`` of the harvesting terminal (charged by the bridge, discharged by the
board); while another terminal is active (the amplifier, or the open circuit of the idle-bridge reduction) the rig
keeps its discharged capacity here and discharges it by the board's load. The cell is a
:class:`plant.battery.TheveninBattery` (its :class:`~board_config.battery.BatterySpec` and internal resistance);
the open-circuit voltage outside the plant is the spec's table, tabulated finely for per-tick use.
"""

from __future__ import annotations

import numpy as np

from board_config import ConfigError
from plant.battery import TheveninBattery

#: the board's cell (the harvesting issue's table)
BOARD_CELL = "ML2032"


class RigCell:
    """The board cell: discharged capacity ``qd`` (C; 0 = full) while outside the plant, open-circuit voltage,
    terminal voltage under a load. ``r_int``: internal resistance (ohm), as the harvesting terminal has it."""

    def __init__(self, r_int: float, initial_voltage: float, where: str) -> None:
        self.battery = TheveninBattery(BOARD_CELL, r_int=r_int)
        self.spec = self.battery.spec
        self.r_int = float(r_int)
        lo, hi = self.spec.voltage_range
        if not lo <= initial_voltage <= hi:
            raise ConfigError(where, "rig.battery_initial_voltage",
                              f"{initial_voltage:g} V is outside the cell's open-circuit-voltage table "
                              f"[{lo:g}, {hi:g}] V")
        self.qd = float(self.spec.discharged_capacity(initial_voltage))  # C, discharged while not in the plant
        # the cell curve tabulated finely for per-tick use (linear between 2049 points of the PCHIP curve)
        ocv_q = np.linspace(-0.05, 1.05, 2049) * self.spec.capacity
        self._ocv_q0 = float(ocv_q[0])
        self._ocv_h = float(ocv_q[1] - ocv_q[0])
        self._ocv_array = np.asarray(self.spec.ocv(ocv_q), dtype=float)
        self._ocv_list = self._ocv_array.tolist()

    @property
    def name(self) -> str:
        return self.spec.name

    @property
    def capacity(self) -> float:
        """C"""
        return float(self.spec.capacity)

    def ocv(self, qd: float) -> float:
        """Open-circuit voltage (V) at discharged capacity ``qd`` (C): linear on a fine table of the cell curve."""
        q0, h, v = self._ocv_q0, self._ocv_h, self._ocv_list
        i = int((qd - q0) / h)
        if i < 0 or i >= len(v) - 1:
            return float(self.spec.ocv(qd))
        f = (qd - q0) / h - i
        return v[i] + (v[i + 1] - v[i]) * f

    def ocv_many(self, qd: np.ndarray) -> np.ndarray | None:
        """:meth:`ocv` of every element of ``qd`` (C), with the same arithmetic (bit-identical); None if one falls
        outside the fine table."""
        x = (qd - self._ocv_q0) / self._ocv_h
        i = x.astype(np.int64)  # truncation, as int()
        v = self._ocv_array
        if qd.size == 0 or int(i.min()) < 0 or int(i.max()) >= v.size - 1:
            return None
        f = x - i
        vi = v[i]
        return vi + (v[i + 1] - vi) * f

    def discharge(self, i_load: float, dt: float) -> None:
        """Draw ``i_load`` (A) for ``dt`` (s) from the cell outside the plant."""
        self.qd += i_load * dt
