"""The rechargeable cell of the harvesting terminals (seed paper Eq. 6-10), seen from Python.

The compiled terminals (:mod:`plant.effects.harvesting`) hold the cell as the state ``bat_qd`` (discharged capacity
q_d, C) and its open-circuit voltage as ``N_OCV_NODES`` parameter values on Chebyshev-spaced q_d nodes. This
module builds
those parameters from a :class:`board_config.battery.BatterySpec`, evaluates the very same curve, and gives a
board or rig a small API:

* :class:`TheveninBattery` — the cell as the plant models it: ``ocv(q_d)``, Eq. 6 ``capacitance(v)``, the paper's
  Eq. 10 denominator (for the record), energies, and ``effect_params()`` for :class:`~plant.PlantModel`;
* :class:`BatteryState` and :func:`battery_state` — what a power manager reads: voltage, charge, current, flags;
* :func:`set_board_current` — let a rig draw the board's load current from the cell (a parameter it may change
  between :meth:`~plant.PlantStepper.advance` calls).

Why the state is the charge, not the voltage: Eq. 6 defines ``C_b = -dq_d/dv_b`` (a differential capacitance),
so ``q_b' = C_b v_b'`` and, with the cell's charge as the state, ``v_b = v_oc(q_d)`` follows from the table. Eq. 9
instead writes ``q_b = C_b v_b`` (a secant capacitance) and differentiates the product; that double-counts the
curvature of the table, and its denominator ``C_b - v_b d^2q_d/dv_b^2`` changes sign over the ML2032 curve (see
:meth:`TheveninBattery.eq10_denominator`). We keep Eq. 6-8, drop Eq. 9's extra term, and report its size.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from board_config.battery import BatterySpec, load_battery
from board_config.errors import InputError
from plant.effects.harvesting import K_I_BOARD, K_Q_MAX, N_OCV_NODES, ocv_and_slope, ocv_nodes

#: charge (as a fraction of capacity) over which the charge controller tapers the current to zero at full
DEFAULT_TAPER_FRACTION = 2e-3


class TheveninBattery:
    """A cell as the harvesting terminals model it: OCV curve on the q_d nodes, internal resistance ``r_int``.

    ``spec`` is a :class:`~board_config.battery.BatterySpec` or a cell name (``"ML2032"``).
    """

    def __init__(self, spec: BatterySpec | str = "ML2032", r_int: float = 1.0,
                 taper_fraction: float = DEFAULT_TAPER_FRACTION) -> None:
        self.spec = load_battery(spec) if isinstance(spec, str) else spec
        r = float(r_int)
        if not np.isfinite(r) or r <= 0.0 or r > 1e6:
            raise InputError(f"internal resistance R_bint = {r_int!r} ohm outside the allowed range (0, {1e6:g}] ohm")
        tf = float(taper_fraction)
        if not 0.0 < tf < 0.5:
            raise InputError(f"taper_fraction {taper_fraction!r} outside (0, 0.5)")
        self.r_int = r
        self.capacity = float(self.spec.capacity)  # C
        self.taper = tf * self.capacity  # C
        self.q_nodes = ocv_nodes(self.capacity)
        self.v_nodes = np.asarray(self.spec.ocv(self.q_nodes), dtype=float)
        self._p = np.ascontiguousarray(self.v_nodes)

    @property
    def name(self) -> str:
        return self.spec.name

    def effect_params(self) -> dict[str, float]:
        """Values of the harvesting terminals' battery parameters (``R_bint``, ``bat_q_max``, ``bat_taper``,
        ``bat_ocv_00..``) for ``PlantModel(..., effect_params=...)``."""
        out = {"R_bint": self.r_int, "bat_q_max": self.capacity, "bat_taper": self.taper}
        out.update({f"bat_ocv_{k:02d}": float(v) for k, v in enumerate(self.v_nodes)})
        return out

    # --- the curve the plant uses ---------------------------------------------------------------------
    def ocv(self, q_d: float | np.ndarray) -> np.ndarray:
        """Open-circuit voltage (V) at discharged capacity ``q_d`` (C), exactly as the compiled terminal has it."""
        return self._curve(q_d, 0)

    def ocv_slope(self, q_d: float | np.ndarray) -> np.ndarray:
        """dv_oc/dq_d (V/C) of the plant's curve."""
        return self._curve(q_d, 1)

    def _curve(self, q_d: float | np.ndarray, which: int) -> np.ndarray:
        """The plant's ``ocv_and_slope`` at every ``q_d`` (C): its voltage (``which`` 0) or slope (1)."""
        q = np.asarray(q_d, dtype=float)
        out = np.empty(q.shape)
        for idx in np.ndindex(q.shape):
            out[idx] = ocv_and_slope(self._p, 0, N_OCV_NODES, self.capacity, float(q[idx]))[which]
        return out

    def discharged_capacity(self, v: float, what: str = "battery voltage") -> float:
        """``q_d`` (C) at open-circuit voltage ``v`` (V) on the plant's curve; ValueError naming the allowed range."""
        lo, hi = float(self.v_nodes[-1]), float(self.v_nodes[0])
        v = float(v)
        if not np.isfinite(v) or v < lo - 1e-12 or v > hi + 1e-12:
            raise InputError(f"{what} {v!r} V outside the {self.name} open-circuit-voltage table [{lo:g}, {hi:g}] V")
        a, b = 0.0, self.capacity
        for _ in range(80):
            mid = 0.5 * (a + b)
            if float(self.ocv(mid)) > v:
                a = mid
            else:
                b = mid
        return 0.5 * (a + b)

    def capacitance(self, v: float | np.ndarray) -> np.ndarray:
        """Eq. 6: ``C_b = -dq_d/dv_b`` (F) at open-circuit voltage ``v`` (V), on the plant's curve."""
        vs = np.atleast_1d(np.asarray(v, dtype=float))
        out = np.array([-1.0 / float(self.ocv_slope(self.discharged_capacity(x))) for x in vs])
        return out if np.ndim(v) else out.reshape(())

    def eq10_denominator(self, v: float | np.ndarray) -> np.ndarray:
        """The paper's Eq. 10 denominator ``C_b - v_b d^2q_d/dv_b^2`` (F), from the data table's curve.

        The energy-consistent value is ``C_b`` alone; the ratio of the two is what Eq. 9-10 change the charging
        speed by (negative values would drive the voltage the wrong way).
        """
        return np.asarray(self.spec.capacitance(v)) - np.asarray(v) * np.asarray(self.spec.d2qd_dv2(v))

    def chemical_energy(self, q_d_from: float, q_d_to: float) -> float:
        """Energy (J) stored into the cell going from ``q_d_from`` to ``q_d_to`` (C): ``-integral v_oc dq_d``.

        Exact for the plant's piecewise-cubic curve (Simpson's rule is exact for cubics on each segment).
        """
        a, b = float(q_d_from), float(q_d_to)
        sign = 1.0
        if b > a:
            a, b, sign = b, a, -1.0
        # integrate v_oc over [b, a] (b < a), splitting at the grid nodes and the table ends
        cuts = np.concatenate([[b], self.q_nodes[(self.q_nodes > b) & (self.q_nodes < a)], [a]])
        cuts = np.unique(np.concatenate([cuts, [c for c in (0.0, self.capacity) if b < c < a]]))
        lo, hi = cuts[:-1], cuts[1:]
        mid = 0.5 * (lo + hi)
        integral = float(np.sum((hi - lo) / 6.0 * (self.ocv(lo) + 4.0 * self.ocv(mid) + self.ocv(hi))))
        return sign * integral

    def energy_to_full(self, q_d: float) -> float:
        """Chemical energy (J) still needed to fill the cell from ``q_d`` (C)."""
        return self.chemical_energy(q_d, 0.0)

    def describe(self) -> dict[str, Any]:
        d = self.spec.describe()
        d.update({"R_bint_ohm": self.r_int, "taper_C": self.taper, "ocv_nodes": int(N_OCV_NODES)})
        return d


@dataclass(frozen=True)
class BatteryState:
    """The cell at one instant, as a board's power manager sees it (SI units)."""

    t: float  # s
    q_d: float  # discharged capacity, C (0 = full)
    capacity: float  # C
    v_oc: float  # open-circuit voltage, V
    v_terminal: float  # terminal voltage v_oc + R_bint i_bat, V
    i_bat: float  # current into the cell (charging > 0), A
    i_board: float  # board load current drawn from the cell, A
    q_below_cutoff: float  # charge drawn while below the cut-off, C
    taper: float  # C

    @property
    def charge(self) -> float:
        """Charge in the cell q_b = q_max - q_d (Eq. 7), C."""
        return self.capacity - self.q_d

    @property
    def soc(self) -> float:
        """State of charge (1 full, 0 at the cut-off)."""
        return 1.0 - self.q_d / self.capacity

    @property
    def full(self) -> bool:
        """The charge controller has started to cut the charging current."""
        return self.q_d <= self.taper

    @property
    def below_cutoff(self) -> bool:
        return self.q_d > self.capacity

    def as_dict(self) -> dict[str, float | bool]:
        d: dict[str, float | bool] = dict(asdict(self))
        d.update({"charge": self.charge, "soc": self.soc, "full": self.full, "below_cutoff": self.below_cutoff})
        return d


def _harvest_offsets(model: Any) -> tuple[int, int]:
    try:
        so = model.state_names.index("bat_qd")
        po = model.param_names.index("R_bint")
    except ValueError:
        raise InputError(f"the model has no harvesting terminal (effects: {', '.join(model.effect_names)}); build "
                         "it with terminal='harvest_coupled' or 'harvest_paper'") from None
    return so, po


def battery_state(model: Any, x: np.ndarray, p: np.ndarray | None = None, t: float = 0.0) -> BatteryState:
    """The cell's state from a state vector ``x`` (and parameter vector ``p``) of a harvesting model."""
    so, po = _harvest_offsets(model)
    x = np.asarray(x, dtype=float)
    p = np.ascontiguousarray(model.p_nominal if p is None else p, dtype=float)
    y = model.outputs(t, x, None, p)
    names = model.output_names
    return BatteryState(
        t=float(t), q_d=float(x[so]), capacity=float(p[po + K_Q_MAX]),
        v_oc=float(y[names.index("v_bat")]), v_terminal=float(y[names.index("v_bat_term")]),
        i_bat=float(y[names.index("i_bat")]), i_board=float(p[po + K_I_BOARD]),
        q_below_cutoff=float(x[so + 1]), taper=float(p[model.param_names.index("bat_taper")]),
    )


def set_board_current(stepper: Any, amps: float | np.ndarray) -> None:
    """Make the board draw ``amps`` (A, >= 0; scalar or one per batch member) from the cell from now on.

    ``stepper`` is a :class:`~plant.PlantStepper` of a harvesting model; the change applies to the next
    :meth:`advance`. Raises ValueError naming the value and the allowed range.
    """
    _, po = _harvest_offsets(stepper.model)
    a = np.broadcast_to(np.asarray(amps, dtype=float), (stepper.p.shape[0],))
    par = next(pp for pp in stepper.model.own_parameters if pp.name == "i_board")
    bad = ~np.isfinite(a) | (a < par.lower) | (a > par.upper)
    if np.any(bad):
        raise InputError(f"board load current {float(a[np.argmax(bad)])!r} A outside the allowed range "
                         f"[{par.lower:g}, {par.upper:g}] A")
    stepper.p[:, po + K_I_BOARD] = a


def initial_state(model: Any, battery: TheveninBattery, v_start: float) -> np.ndarray:
    """The model's nominal initial state with the cell at open-circuit voltage ``v_start`` (V)."""
    so, _ = _harvest_offsets(model)
    x0 = np.array(model.x0_nominal, dtype=float)
    x0[so] = battery.discharged_capacity(v_start, "start voltage")
    return x0


__all__ = [
    "DEFAULT_TAPER_FRACTION",
    "BatteryState",
    "TheveninBattery",
    "battery_state",
    "initial_state",
    "set_board_current",
]
