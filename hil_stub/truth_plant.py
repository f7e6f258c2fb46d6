"""The rig's truth plant: the laminate + MFC model of ``plant`` with the rig's deviations and added effects, one
composition per terminal, stepped on the rig's tick grid in lookahead blocks.

* :class:`TruthComposition` — one terminal's composition with its (deviated) parameter vector and its
  :class:`plant.Integrator`.
* :class:`TruthPlant` — the compositions the rig switches between (the amplifier while HV equipment is connected,
  the flight terminal otherwise, and the open circuit standing in for the harvesting terminal while its bridge
  cannot conduct), the state carried over by name on every switch, and the lookahead blocks: while the amplifier
  output, the terminal and the load stay the same, ``lookahead_ticks`` ticks are integrated at once with an output
  (and a saved state) at every tick boundary; any change restarts from the saved state of the current tick.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from board_config import ConfigError, ParameterError, ParameterSet
from hil_stub.cell import RigCell
from hil_stub.environment import Environment
from hil_stub.sensors import TruthReading
from plant import Integrator, PlantModel
from plant import layout as L

#: largest integration step of the truth plant (s); the 102 Hz mode limits explicit steps to ~3 ms anyway
TRUTH_H_MAX = 5e-3


def deviated_parameters(model: PlantModel, deviations: Mapping[str, float], where: str) -> np.ndarray:
    """``model``'s nominal parameter vector with the relative ``deviations`` applied (``nominal × (1 + d)``); a
    :class:`ConfigError` naming ``where`` and ``rig.deviations.NAME`` for an unknown parameter, a deviation outside
    the accepted range or a deviated value outside its bounds (:meth:`board_config.ParameterVector.with_deviations`)."""
    try:
        return model.nominal.with_deviations(deviations, "rig.deviations").array()
    except ParameterError as exc:  # the one check of a deviation (range, name, bounds), reported as the file's key
        raise ConfigError(where, f"rig.deviations.{exc.name}", exc.reason) from None


class TruthComposition:
    """One composition (terminal) of the truth plant with its parameter vector and fast stepping.

    ``deviations`` are relative (``truth = nominal × (1 + d)``); a core parameter's result is checked against its
    schema bounds. The output, state and parameter columns the rig reads are named attributes (-1: absent).
    """

    def __init__(self, params: ParameterSet, effects: Sequence[str], terminal: str,
                 effect_params: Mapping[str, float], deviations: Mapping[str, float], rtol: float,
                 where: str) -> None:
        self.model = PlantModel(params, effects=list(effects), terminal=terminal, effect_params=dict(effect_params))
        self.terminal = terminal
        self.p = np.ascontiguousarray(deviated_parameters(self.model, deviations, where)[None, :])
        self.rtol = rtol
        self.integrator = Integrator(self.model, rtol)
        names = self.model.output_names
        self.i_z3 = names.index("z3_meas")
        self.i_vterm = names.index("v_stored")
        self.i_z3_true = names.index("z3")
        self.i_vbat = names.index("v_bat_term") if "v_bat_term" in names else -1
        self.i_ocv = names.index("v_bat") if "v_bat" in names else -1
        self.i_irect = names.index("i_rect") if "i_rect" in names else -1
        self.has_battery = "bat_qd" in self.model.state_names
        self.s_qd = self.model.state_names.index("bat_qd") if self.has_battery else -1
        self.p_iboard = self._param("i_board")
        self.p_reverse = self._param("eq8_reverse")
        self.p_vdiode = self._param("V_diode")
        self.p_rbint = self._param("R_bint")
        self.steps = 0
        self.seconds = 0.0  # wall time spent integrating (s)

    def _param(self, name: str) -> int:
        return self.model.param_index(name) if name in self.model.param_names else -1

    def param(self, index: int, default: float) -> float:
        """The value of parameter column ``index`` (``default`` if the composition lacks it: ``index < 0``)."""
        return float(self.p[0, index]) if index >= 0 else default

    def set_load(self, i_load: float) -> None:
        """The current (A) the board draws from the cell of a harvesting terminal (no-op for other terminals)."""
        if self.p_iboard >= 0:
            self.p[0, self.p_iboard] = i_load

    def integrate(self, x0: np.ndarray, t0: float, u: np.ndarray, u_dt: float, t_out: np.ndarray,
                  h_max: float) -> tuple[np.ndarray, np.ndarray]:
        """Outputs and states at ``t_out`` (``t_out[0] == t0``) from state ``x0`` under inputs ``u`` (samples, 3).

        Raises :class:`plant.IntegrationFailed` (a ``FloatingPointError``) if the integration fails."""
        t_start = time.perf_counter()
        n = t_out.size
        y = np.empty((1, n, self.model.n_outputs))
        xs = np.empty((1, n, self.model.n_states))
        self.steps += self.integrator.interval(np.ascontiguousarray(x0[None, :]), self.p,
                                               np.ascontiguousarray(u[None]), t0, u_dt, t_out, h_max, y, xs,
                                               what="truth plant")
        self.seconds += time.perf_counter() - t_start
        return y[0], xs[0]


@dataclass
class TruthBlock:
    """Outputs and states of the truth plant at ``n + 1`` tick boundaries from ``t0``, for one composition,
    amplifier output (V) and load (A); ``j`` is the row of the current tick."""

    composition: TruthComposition
    v_ch1: float
    v_ch2: float
    i_load: float
    t0: float
    y: np.ndarray  # (n+1, n_outputs)
    x: np.ndarray  # (n+1, n_states)
    n: int
    j: int
    # sensor columns at the tick boundaries, as Python floats (fast per-tick reads)
    z3: list[float]
    v_terminal: list[float]
    v_battery: list[float] | None
    z0dd: list[float]


class TruthPlant:
    """The truth plant the rig serves (see the module docstring): ``advance`` one interval under the amplifier
    output and the board's load; ``outputs`` / ``reading`` now. Amplifier channel voltages are passed as floats (V):
    the rig calls ``advance`` every tick."""

    def __init__(self, params: ParameterSet, effects: Sequence[str], effect_params: Mapping[str, float],
                 deviations: Mapping[str, float], flight_terminal: str, *, env: Environment, tick: float,
                 lookahead_ticks: int, rtol: float, flight_rtol: float, reduce_idle_bridge: bool,
                 where: str) -> None:
        self._params = params
        self._effects = tuple(effects)
        self._effect_params = dict(effect_params)
        self._deviations = dict(deviations)
        self._where = where
        self._rtol = {"amplifier": float(rtol)}
        self._flight_rtol = float(flight_rtol)
        self.env = env
        self.tick = tick
        self.lookahead_ticks = lookahead_ticks
        self._env_per_tick = env.rate * tick
        self._aligned_env = abs(self._env_per_tick - round(self._env_per_tick)) < 1e-9
        self.compositions: dict[str, TruthComposition] = {}
        self._parked: dict[str, np.ndarray] = {}
        self.flight = self.composition(flight_terminal)
        self.amplifier = self.composition("amplifier")  # built (compiled or loaded) now, not at the first HV contact
        # exact reduction while the bridge cannot conduct: the harvesting terminal then *is* the open circuit
        self.idle: TruthComposition | None = None
        f = self.flight
        if reduce_idle_bridge and f.has_battery and (f.p_reverse < 0 or f.p[0, f.p_reverse] < 0.5):
            self.idle = self.composition("open_circuit")
        self.cell: RigCell | None = None
        self.active = self.flight
        self.t = 0.0
        self._x = f.model.x0_nominal.copy()
        self._y_rows = np.zeros((1, f.model.n_outputs))  # the outputs now are row ``_y_row`` of this array
        self._y_row = 0
        #: what the sensors see now (noise-free; one object, updated in place as the plant advances)
        self.reading = TruthReading(0.0, 0.0, math.nan, 0.0)
        self._k = 0  # whole ticks advanced (for the aligned fast path)
        self._offgrid = False  # advanced by a non-tick dt at some point
        self._block: TruthBlock | None = None
        self.blocks = 0
        self.reduced_blocks = 0

    def composition(self, terminal: str) -> TruthComposition:
        """The composition with ``terminal`` (built, or its compiled kernels loaded, on first use)."""
        if terminal not in self.compositions:
            rtol = self._rtol.get(terminal, self._flight_rtol)
            self.compositions[terminal] = TruthComposition(self._params, self._effects, terminal,
                                                           self._effect_params, self._deviations, rtol, self._where)
        return self.compositions[terminal]

    def start(self, cell: RigCell) -> None:
        """Put the plant at rest at t = 0 with the cell's charge (the cell stays the rig's outside the plant)."""
        self.cell = cell
        f = self.flight
        if f.has_battery:
            self._x[f.s_qd] = cell.qd
        self._y_rows = self._outputs_at_rest()[None, :]
        self._y_row = 0
        y = self.outputs
        r = self.reading
        r.z3 = float(y[f.i_z3])
        r.v_patch = float(y[f.i_vterm])
        r.v_battery = float(y[f.i_vbat]) if f.i_vbat >= 0 else math.nan
        r.z0dd = float(self._u_now()[2])

    # --- now ----------------------------------------------------------------------------------------------
    @property
    def outputs(self) -> np.ndarray:
        """Outputs now (SI units, the active composition's output order)."""
        return self._y_rows[self._y_row]

    def state(self) -> np.ndarray:
        """The active composition's state now."""
        b = self._block
        return b.x[b.j] if b is not None else self._x

    @property
    def battery_discharged(self) -> float:
        """Discharged capacity of the board cell (C; 0 = full), in the plant or outside it."""
        if self.active.has_battery:
            return float(self.state()[self.active.s_qd])
        assert self.cell is not None
        return self.cell.qd

    @property
    def steps(self) -> int:
        return sum(m.steps for m in self.compositions.values())

    @property
    def seconds(self) -> float:
        return sum(m.seconds for m in self.compositions.values())

    def _outputs_at_rest(self) -> np.ndarray:
        return self.active.model.outputs(self.t, self._x, self._u_now(), self.active.p[0])

    def _u_now(self) -> np.ndarray:
        return np.array([0.0, 0.0, float(self.env.base_acceleration(np.array([self.t]))[0])])

    # --- stepping -----------------------------------------------------------------------------------------
    def advance(self, dt: float, hv_connected: bool, start_ch1: float, start_ch2: float, v_ch1: float, v_ch2: float,
                i_load: float) -> None:
        """Move the plant ``dt`` seconds on: the amplifier terminal if ``hv_connected`` (its channels slewing from
        ``start_ch1/2`` to ``v_ch1/2`` (V) over the first tick), else the flight terminal; the board cell loaded by
        ``i_load`` (A)."""
        want = self.amplifier if hv_connected else self.flight
        aligned = (dt == self.tick or abs(dt - self.tick) <= 1e-9 * self.tick) and not self._offgrid
        if want is not self.active and not (aligned and want is self.flight and self.active is self.idle):
            self._switch(want)
        if aligned:
            self._advance_tick(start_ch1, start_ch2, v_ch1, v_ch2, i_load, want)
        else:
            self._offgrid = True
            self._block = None
            self._integrate_direct(dt, start_ch1, start_ch2, v_ch1, v_ch2, i_load)

    def _switch(self, new: TruthComposition) -> None:
        """Change terminal: carry the core and shared extra states over by name; keep the battery state."""
        assert self.cell is not None
        old = self.active
        x_old = self.state().copy()
        self._parked[old.terminal] = x_old  # its own extra states (e.g. the power-audit integrals) wait for it
        if old.has_battery:
            self.cell.qd = float(x_old[old.s_qd])
        parked = self._parked.get(new.terminal)
        x_new = parked.copy() if parked is not None else new.model.x0_nominal.copy()
        x_new[: L.N_CORE_STATES] = x_old[: L.N_CORE_STATES]
        old_names = old.model.state_names
        for k, name in enumerate(new.model.state_names[L.N_CORE_STATES:], start=L.N_CORE_STATES):
            if name in old_names:
                x_new[k] = x_old[old_names.index(name)]
        if new.has_battery:
            x_new[new.s_qd] = self.cell.qd
        self.active = new
        self._x = x_new
        self._block = None

    def _inputs(self, t0: float, n_ticks: int, s1: float, s2: float, v1: float, v2: float
                ) -> tuple[np.ndarray, float]:
        """Input samples over ``n_ticks`` ticks from ``t0`` (rig grid) with a linear slew over the first tick, and
        their spacing (s)."""
        if self._aligned_env:
            m = round(self._env_per_tick)
            i0 = round(t0 * self.env.rate)
            z = self.env.grid_slice(i0, i0 + n_ticks * m)
            u_dt = 1.0 / self.env.rate
        else:
            z = self.env.base_acceleration(t0 + np.arange(n_ticks * 10 + 1) * (self.tick / 10))
            m = 10
            u_dt = self.tick / 10
        u = np.empty((z.size, 3))
        u[:, 2] = z
        u[:, 0] = v1
        u[:, 1] = v2
        if s1 != v1 or s2 != v2:
            frac = np.arange(m + 1) / m
            u[: m + 1, 0] = s1 + (v1 - s1) * frac
            u[: m + 1, 1] = s2 + (v2 - s2) * frac
        return u, u_dt

    def _advance_tick(self, s1: float, s2: float, v1: float, v2: float, i_load: float,
                      want: TruthComposition) -> None:
        cell = self.cell
        assert cell is not None
        b = self._block
        steady = v1 == s1 and v2 == s2
        if not (b is not None and steady and b.j < b.n and b.composition is self.active and b.v_ch1 == v1
                and b.v_ch2 == v2 and b.i_load == i_load):
            b = self._start_block(s1, s2, v1, v2, i_load, want, self.lookahead_ticks if steady else 1)
        self._serve(b, 1)
        if not self.active.has_battery:
            cell.discharge(i_load, self.tick)

    def _serve(self, b: TruthBlock, m: int) -> None:
        """Move ``m`` ticks on inside block ``b``: time, the outputs now and what the sensors see."""
        b.j += m
        self._k += m
        self.t = self._k * self.tick
        j = b.j
        self._y_rows = b.y  # the outputs now are row j of the block (no view made per tick; see ``outputs``)
        self._y_row = j
        r = self.reading
        r.z3 = b.z3[j]
        r.v_patch = b.v_terminal[j]
        vb = b.v_battery
        r.v_battery = vb[j] if vb is not None else math.nan
        r.z0dd = b.z0dd[j]

    def _start_block(self, s1: float, s2: float, v1: float, v2: float, i_load: float, want: TruthComposition,
                     n: int) -> TruthBlock:
        """Integrate the next ``n`` ticks from the current tick (the block's row 0) and make it the current block."""
        t0 = self._k * self.tick
        u, u_dt = self._inputs(t0, n, s1, s2, v1, v2)
        t_out = t0 + self.tick * np.arange(n + 1)
        h_max = min(TRUTH_H_MAX, self.tick)
        b = None
        idle = self.idle
        if want is self.flight and idle is not None:
            # try the reduced model (bridge off); keep it only if the bridge stays far from conducting
            if self.active is not idle:
                self._switch(idle)
            y, xs = idle.integrate(self.state().copy(), t0, u, u_dt, t_out, h_max)
            if float(np.max(np.abs(y[:, idle.i_vterm]))) < 0.5 * self._bridge_threshold(i_load):
                b = self._new_block(idle, v1, v2, i_load, t0, y, xs, n, u)
                self.reduced_blocks += 1
            else:
                self._switch(self.flight)
        if b is None:
            model = self.active
            x0 = self.state().copy()
            model.set_load(i_load)
            y, xs = model.integrate(x0, t0, u, u_dt, t_out, h_max)
            b = self._new_block(model, v1, v2, i_load, t0, y, xs, n, u)
        self._block = b
        self.blocks += 1
        return b

    # --- quiet spans (drivers.quiet_span) -------------------------------------------------------------------
    def peek_quiet(self, hv_connected: bool, i_load: float, max_ticks: int
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray] | None:
        """Noise-free z3 as the laser sees it (m), terminal voltage (V), cell terminal voltage (V; None when the cell
        is outside the plant) and base acceleration (m/s^2) at the next ``n <= max_ticks`` tick boundaries, if the next
        ``n`` aligned advances with zero amplifier output (connected or not), no slew and load ``i_load`` (A) would
        each just serve the next row of the current lookahead block; None otherwise. Nothing advances."""
        b = self._block
        active = self.active
        if hv_connected:
            want, serves = self.amplifier, active is self.amplifier
        else:
            want, serves = self.flight, active is self.flight or active is self.idle
        if (not serves or b is None or self._offgrid or b.composition is not active or b.v_ch1 != 0.0
                or b.v_ch2 != 0.0 or b.i_load != i_load):
            return None
        if b.j >= b.n:  # used up: the next advance would integrate the next block from here; do it now
            b = self._start_block(0.0, 0.0, 0.0, 0.0, i_load, want, self.lookahead_ticks)
        n = min(max_ticks, b.n - b.j)
        m = b.composition
        rows = slice(b.j + 1, b.j + 1 + n)
        y = b.y
        return (y[rows, m.i_z3], y[rows, m.i_vterm], y[rows, m.i_vbat] if m.i_vbat >= 0 else None,
                np.array(b.z0dd[rows]))

    def commit_quiet(self, m: int, qd_after: float | None) -> None:
        """Advance ``m`` ticks as :meth:`peek_quiet` described them; ``qd_after`` is the cell's discharged capacity
        (C) after them when the cell is outside the plant (the caller summed the per-tick discharges)."""
        b = self._block
        assert b is not None and 1 <= m <= b.n - b.j
        self._serve(b, m)
        if not self.active.has_battery:
            assert self.cell is not None and qd_after is not None
            self.cell.qd = qd_after

    @staticmethod
    def _new_block(model: TruthComposition, v1: float, v2: float, i_load: float, t0: float, y: np.ndarray,
                   xs: np.ndarray, n: int, u: np.ndarray) -> TruthBlock:
        m = (u.shape[0] - 1) // n
        return TruthBlock(model, v1, v2, i_load, t0, y, xs, n, 0, y[:, model.i_z3].tolist(),
                          y[:, model.i_vterm].tolist(), y[:, model.i_vbat].tolist() if model.i_vbat >= 0 else None,
                          u[::m, 2].tolist())

    def _bridge_threshold(self, i_load: float) -> float:
        """|v_s| (V) above which the harvesting bridge would conduct (plant.effects.harvesting closed form)."""
        assert self.cell is not None
        v_d = self.flight.param(self.flight.p_vdiode, 0.0)
        return self.cell.ocv(self.cell.qd) + 2.0 * v_d - self.cell.r_int * i_load

    def _integrate_direct(self, dt: float, s1: float, s2: float, v1: float, v2: float, i_load: float) -> None:
        assert self.cell is not None
        model = self.active
        model.set_load(i_load)
        n = max(2, math.ceil(dt * self.env.rate) + 1)
        times = self.t + np.linspace(0.0, dt, n)
        u = np.empty((n, 3))
        u[:, 2] = self.env.base_acceleration(times)
        frac = np.minimum(1.0, (times - self.t) / min(dt, self.tick))
        u[:, 0] = s1 + (v1 - s1) * frac
        u[:, 1] = s2 + (v2 - s2) * frac
        t_out = np.array([self.t, self.t + dt])
        y, xs = model.integrate(self._x, self.t, u, dt / (n - 1), t_out, min(TRUTH_H_MAX, dt))
        self._x = xs[-1].copy()
        self._y_rows = y
        self._y_row = y.shape[0] - 1
        self.t += dt
        r = self.reading
        r.z3 = float(y[-1, model.i_z3])
        r.v_patch = float(y[-1, model.i_vterm])
        r.v_battery = float(y[-1, model.i_vbat]) if model.i_vbat >= 0 else math.nan
        r.z0dd = float(u[-1, 2])
        if not model.has_battery:
            self.cell.discharge(i_load, dt)
