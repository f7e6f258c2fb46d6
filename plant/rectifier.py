"""Full-bridge rectifier between the patch terminals and the cell: ideal, or with a forward drop per diode.

Two diodes conduct in every half-cycle, so the bridge output is ``|v_in| - 2 V_diode`` while current flows and the
bridge blocks reverse current. Charging a cell (open-circuit voltage ``v_oc`` behind ``R_int``) that also supplies
a board load ``i_board`` from a source ``v_src`` behind ``R_src``, Kirchhoff's laws give the bridge output current
in closed form (no iteration)::

    i = max(0, (|v_src| - 2 V_diode - v_oc + R_int i_board) / (R_src + R_int))

The compiled harvesting terminals (:mod:`plant.effects.harvesting`) use the same function; this module is the
Python-side view of it (vectorised, validated) for analyses, tests and rigs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from board_config.errors import InputError
from plant.effects.harvesting import bridge_charging_current

#: largest diode drop accepted (V); silicon ~0.6-0.7 V, Schottky ~0.2-0.4 V
MAX_DIODE_DROP_V = 5.0


@dataclass(frozen=True)
class FullBridge:
    """A full-bridge rectifier; ``v_diode`` (V) is the forward drop of one diode (0 = ideal)."""

    v_diode: float = 0.0

    def __post_init__(self) -> None:
        v = float(self.v_diode)
        if not np.isfinite(v) or v < 0.0 or v > MAX_DIODE_DROP_V:
            raise InputError(f"diode forward drop {self.v_diode!r} V outside the allowed range "
                             f"[0, {MAX_DIODE_DROP_V:g}] V")

    @property
    def ideal(self) -> bool:
        return self.v_diode == 0.0

    def output_voltage(self, v_in: float | np.ndarray) -> np.ndarray:
        """Open-circuit (no-load) output voltage (V): ``max(|v_in| - 2 V_diode, 0)``."""
        return np.maximum(np.abs(np.asarray(v_in, dtype=float)) - 2.0 * self.v_diode, 0.0)

    def charging_current(self, v_src: float | np.ndarray, r_src: float, v_oc: float | np.ndarray, r_int: float,
                         i_board: float = 0.0) -> np.ndarray:
        """Bridge output current (A) into a cell + board load (see the module docstring); ``r_src + r_int > 0``."""
        if not (r_src >= 0.0 and r_int > 0.0):
            raise InputError(f"resistances must be R_src >= 0 and R_int > 0 ohm, got R_src={r_src!r}, "
                             f"R_int={r_int!r}")
        vs, vo = np.broadcast_arrays(np.asarray(v_src, dtype=float), np.asarray(v_oc, dtype=float))
        out = np.empty(vs.shape)
        for idx in np.ndindex(vs.shape):
            out[idx] = bridge_charging_current(float(vs[idx]), float(r_src), float(vo[idx]), float(r_int),
                                               float(self.v_diode), float(i_board), False)
        return out

    def terminal_voltage(self, v_src: float | np.ndarray, r_src: float, current: float | np.ndarray) -> np.ndarray:
        """Voltage at the bridge input (V) when the source ``v_src`` behind ``r_src`` delivers ``current`` (A)."""
        vs = np.asarray(v_src, dtype=float)
        return vs - np.sign(vs) * r_src * np.asarray(current, dtype=float)

    def loss(self, current: float | np.ndarray) -> np.ndarray:
        """Power lost in the two conducting diodes (W) at output current ``current`` (A)."""
        return 2.0 * self.v_diode * np.maximum(np.asarray(current, dtype=float), 0.0)

    def mean_charging_current(self, amplitude: float, r_src: float, v_oc: float, r_int: float,
                              i_board: float = 0.0) -> float:
        """Cycle-average bridge current (A) from a sinusoidal source of ``amplitude`` (V) behind ``r_src``,
        closed form: (2/pi) (sqrt(a^2 - u^2) - u acos(u/a)) / (R_src + R_int), u = 2 V_diode + v_oc - R_int i_board.
        """
        u = 2.0 * self.v_diode + v_oc - r_int * i_board
        a = float(amplitude)
        if a <= max(u, 0.0):
            return 0.0
        if u <= 0.0:
            return float((2.0 * a / np.pi - u) / (r_src + r_int))  # conducts throughout the cycle
        return float((2.0 / np.pi) * (np.sqrt(a * a - u * u) - u * np.arccos(u / a)) / (r_src + r_int))
