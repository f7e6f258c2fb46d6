"""The simulated rig: a truth plant in a scenario-driven environment, behind the ``drivers.RigEndpoint`` seam.

What it models (SI units throughout):

* **Truth plant.** The laminate + MFC model of ``plant`` built from a parameter set, with *deviations* (relative:
  ``truth = nominal × (1 + d)``, on any core or effect parameter — a degraded laminate) and *added physical effects*
  (names or dotted paths). Two terminals share the same core state: while the external high-voltage equipment is
  connected (``hv_present``, maintenance phases) the patches hang on the amplifier (``v_a = (v_ch1 − v_ch2)/2``);
  otherwise they feed the board's harvesting circuit (``harvest_coupled`` by default: full bridge into the cell, the
  charging current loads the patches; ``harvest_paper``: the paper's Eq. 8; ``none``: an open-circuit voltmeter,
  no harvesting). On every switch the core states (and the added effects' states) carry over by name.
* **Board battery.** The cell on the board is rig hardware: in flight it is a state of the harvesting terminal
  (charged by the bridge, discharged by the board); while the amplifier terminal is active it is integrated here
  from the same open-circuit-voltage table (the patches do not harvest then). The board's current draw comes with
  every command (``ActuatorCommand.board_current``); a scenario can add a failing component's load.
* **Amplifier.** A command is validated (finite, inside Table 1's −500…+1500 V per channel, board current ≥ 0); an
  invalid one is refused — the last valid output is kept and the next samples carry ``FLAG_LIMIT_REFUSED``. Between
  two ticks the output slews linearly from the previous to the new demand (a first-order hold; the board's nominal
  model reproduces exactly this). No valid command for ``watchdog`` seconds → the demand drops to 0 V.
* **Sensors.** Laser tip displacement (``z3_meas`` + Gaussian noise), patch terminal voltage, base accelerometer,
  battery terminal voltage; scheduled sensor faults (NaN, a fault flag, a frozen sample counter, an out-of-range
  value). Noise is drawn from the rig's seeded generator when time advances, so ``sample()`` is repeatable.

Speed: while the demand, the terminal and the load stay the same (the board asleep or sensing), the plant is
integrated ``lookahead_ticks`` ticks at a time with an output (and a saved state) at every tick; samples are then
served from that block. Any change (a new demand, HV connected, a regime change of the board's current) restarts
integration from the saved state of the current tick, so the result does not depend on the block length beyond the
integrator's tolerance. ``advance(dt)`` with any other ``dt`` integrates exactly ``dt``. In flight the truth plant
runs at ``flight_rtol`` (1e-5) and, while the harvesting bridge cannot conduct, as the equivalent open-circuit
terminal with the cell discharged by the load in closed form (``reduce_idle_bridge``; with ``table2`` the patches make
millivolts against a 2.9 V cell, so this is the whole flight). The MBITs run at ``rtol`` (1e-6), tick by tick.

URL: ``open_link("sim")`` / ``"sim:maintenance"`` / ``"sim://?scenario=degraded&seed=3&params=table2"`` builds an
in-process link to a rig made here (registered when this module is imported).
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any
from urllib.parse import parse_qs, urlparse

import numpy as np

from board_config import CORE_SCHEMA, ConfigError, MfcLimits, ParameterSet, load_mfc_limits, load_parameter_set
from board_config.errors import InputError
from board_config.scenario import Scenario, load_scenario
from drivers.link import FLAG_LIMIT_REFUSED, FLAG_SENSOR_FAULT, ActuatorCommand, RigSample
from drivers.sim_link import InProcessLink, set_sim_rig_factory
from hil_stub.environment import Environment
from plant import PlantModel
from plant import layout as L

COUPLING_TERMINALS = {"coupled": "harvest_coupled", "paper": "harvest_paper", "none": "open_circuit"}


@dataclass
class _Block:
    """Outputs and states of the truth plant at ``n + 1`` tick boundaries from ``t0``, for one input key."""

    key: tuple
    t0: float
    y: np.ndarray  # (n+1, n_outputs)
    x: np.ndarray  # (n+1, n_states)
    n: int
    j: int = 0
    z3: list[float] | None = None  # sensor columns at the tick boundaries, as Python floats (fast per-tick reads)
    vt: list[float] | None = None
    vb: list[float] | None = None
    zdd: list[float] | None = None


class _TruthModel:
    """One composition (terminal) of the truth plant with its parameter vector and fast stepping."""

    def __init__(self, params: ParameterSet, effects: Sequence[str], terminal: str,
                 effect_params: Mapping[str, float], deviations: Mapping[str, float], rtol: float,
                 where: str) -> None:
        self.model = PlantModel(params, effects=list(effects), terminal=terminal, effect_params=dict(effect_params))
        self.terminal = terminal
        p = self.model.p_nominal.copy()
        for name, d in deviations.items():
            try:
                idx = self.model.param_index(name)
            except KeyError:
                raise ConfigError(where, f"rig.deviations.{name}",
                                  f"no such model parameter (known: {', '.join(self.model.param_names)})") from None
            value = p[idx] * (1.0 + d)
            if name in CORE_SCHEMA:
                CORE_SCHEMA[name].check(where, f"rig.deviations.{name} (gives {name} = {value:g})", value)
            p[idx] = value
        self.p = np.ascontiguousarray(p[None, :])
        self.rtol = rtol
        self.atol = np.ascontiguousarray(self.model.state_scales * rtol)
        self.run = self.model.kernels().run_chunk
        names = self.model.output_names
        self.i_z3 = names.index("z3_meas")
        self.i_vterm = names.index("v_stored")
        self.i_z3_true = names.index("z3")
        self.i_vbat = names.index("v_bat_term") if "v_bat_term" in names else -1
        self.i_ocv = names.index("v_bat") if "v_bat" in names else -1
        self.i_irect = names.index("i_rect") if "i_rect" in names else -1
        self.has_battery = "bat_qd" in self.model.state_names
        self.s_qd = self.model.state_names.index("bat_qd") if self.has_battery else -1
        self.p_iboard = self.model.param_index("i_board") if "i_board" in self.model.param_names else -1
        self.p_reverse = self.model.param_index("eq8_reverse") if "eq8_reverse" in self.model.param_names else -1
        self.p_vdiode = self.model.param_index("V_diode") if "V_diode" in self.model.param_names else -1
        self.p_rbint = self.model.param_index("R_bint") if "R_bint" in self.model.param_names else -1
        self._status = np.zeros(1, dtype=np.int64)
        self._nsteps = np.zeros(1, dtype=np.int64)
        self._bus = np.zeros((1, 1, 1))
        self.steps = 0
        self.seconds = 0.0  # wall time spent integrating (s)

    def integrate(self, x0: np.ndarray, t0: float, u: np.ndarray, u_dt: float, t_out: np.ndarray,
                  h_max: float) -> tuple[np.ndarray, np.ndarray]:
        """Outputs and states at ``t_out`` (``t_out[0] == t0``) from state ``x0`` under inputs ``u`` (samples, 3)."""
        t_start = time.perf_counter()
        n = t_out.size
        y = np.empty((1, n, self.model.n_outputs))
        xs = np.empty((1, n, self.model.n_states))
        self.run(0, 1, np.ascontiguousarray(x0[None, :]), self.p, np.ascontiguousarray(u[None]), t0, u_dt, t_out,
                 self.rtol, self.atol, h_max, 1e-14, 50_000_000, y, xs, self._bus, True, False, self._status,
                 self._nsteps)
        if self._status[0] != 0:
            raise FloatingPointError(f"truth plant integration failed at t={t0:.6g} s (status {int(self._status[0])})")
        self.steps += int(self._nsteps[0])
        self.seconds += time.perf_counter() - t_start
        return y[0], xs[0]


class SimulatedRig:
    """A seedable simulated rig implementing :class:`drivers.RigEndpoint` (``apply``, ``advance``, ``sample``).

    Parameters
    ----------
    scenario:
        The scenario whose environment (vibration, gusts, landing, HV presence, rig-side incidents) and rig spec
        (parameter set, deviations, effects, battery, sensor noise) the rig plays. ``None``: a quiet parked rig.
    seed:
        Seeds the environment and the sensor noise (default: the scenario's seed).
    params, deviations, effects, effect_params, coupling, battery_initial_voltage:
        Override the scenario's ``[rig]`` values (``deviations`` relative, ``truth = nominal × (1 + d)``).
    tick:
        The board tick the lookahead blocks are aligned to (s).
    lookahead_ticks:
        Ticks integrated at once while nothing changes (1 = plain tick-by-tick stepping).
    rtol, flight_rtol:
        Relative tolerance of the truth plant with the amplifier connected (the MBITs: 1e-6) and in flight (the
        harvesting or open-circuit terminal: 1e-5 — its error is orders of magnitude below the sensor noise).
    reduce_idle_bridge:
        While the harvesting bridge cannot conduct (the largest patch voltage of a block stays below half the
        conduction threshold ``v_oc + 2 V_diode − R_bint i_board``), integrate the equivalent open-circuit terminal
        and the cell's discharge by the load in closed form — the same equations without the bridge and audit
        terms. ``False`` always integrates the full harvesting terminal.
    hv_present:
        Force the HV-equipment presence (``None``: follow the scenario). ``set_hv_present`` changes it later.
    """

    def __init__(self, scenario: Scenario | None = None, *, seed: int | None = None,
                 params: str | ParameterSet | None = None, deviations: Mapping[str, float] | None = None,
                 effects: Sequence[str] | None = None, effect_params: Mapping[str, float] | None = None,
                 coupling: str | None = None, battery_initial_voltage: float | None = None,
                 tick: float = 0.01, lookahead_ticks: int = 50, rtol: float = 1e-6, flight_rtol: float = 1e-5,
                 reduce_idle_bridge: bool = True, limits: MfcLimits | None = None,
                 hv_present: bool | None = None) -> None:
        spec = scenario.rig if scenario is not None else None
        where = scenario.source if scenario is not None else "<rig>"
        self.scenario = scenario
        self.seed = int(seed if seed is not None else (scenario.seed if scenario is not None else 0))
        pset = params if params is not None else (spec.params if spec else "table2")
        self.params = pset if isinstance(pset, ParameterSet) else load_parameter_set(pset)
        self.deviations = dict(deviations if deviations is not None else (spec.deviations if spec else {}))
        self.effects = tuple(effects if effects is not None else (spec.effects if spec else ()))
        self.effect_params = dict(effect_params if effect_params is not None else (spec.effect_params if spec else {}))
        self.coupling = coupling if coupling is not None else (spec.coupling if spec else "coupled")
        if self.coupling not in COUPLING_TERMINALS:
            raise InputError(f"rig coupling {self.coupling!r} unknown (allowed: {', '.join(COUPLING_TERMINALS)})")
        flight_terminal = COUPLING_TERMINALS[self.coupling]
        self.limits = limits if limits is not None else load_mfc_limits()
        self._v_range = (self.limits.voltage_min, self.limits.voltage_max)
        if not (tick > 0 and math.isfinite(tick)):
            raise ValueError(f"rig tick must be positive, got {tick!r}")
        self.tick = float(tick)
        self.lookahead_ticks = max(1, int(lookahead_ticks))
        self.z3_noise = spec.z3_noise if spec else 2e-6
        self.accel_noise = spec.accel_noise if spec else 0.02
        self.v_patch_noise = spec.v_patch_noise if spec else 1e-4
        self.watchdog = spec.watchdog if spec else 0.1
        env_rate = spec.env_rate if spec else 1000.0
        self.env = Environment(scenario, self.seed, env_rate)
        self._env_per_tick = env_rate * self.tick
        self._aligned_env = abs(self._env_per_tick - round(self._env_per_tick)) < 1e-9
        self._hv_override = hv_present
        self._seg_until = -math.inf  # the cached environment segment holds until this time (s)
        self._seg: tuple[bool, str | None, bool, float, float] = (False, None, False, 0.0, -math.inf)

        # truth plant, one composition per terminal
        self._models: dict[str, _TruthModel] = {}
        self._parked: dict[int, np.ndarray] = {}
        self._args = (self.params, self.effects, self.effect_params, self.deviations, where)
        self._rtol = {"amplifier": float(rtol)}
        self._flight_rtol = float(flight_rtol)
        self._flight = self._model(flight_terminal)
        self._amp = self._model("amplifier")  # built (compiled or loaded) now, not at the first HV connection
        # exact reduction while the bridge cannot conduct: the harvesting terminal then *is* the open circuit
        self._idle: _TruthModel | None = None
        f = self._flight
        if reduce_idle_bridge and f.has_battery and (f.p_reverse < 0 or f.p[0, f.p_reverse] < 0.5):
            self._idle = self._model("open_circuit")
        self.reduced_blocks = 0
        # internal resistance of the cell (ohm), as the harvesting terminal has it (1 ohm without one)
        self._r_int = float(f.p[0, f.p_rbint]) if f.p_rbint >= 0 else 1.0
        self._battery_spec = _load_cell()
        v0 = battery_initial_voltage if battery_initial_voltage is not None else (
            spec.battery_initial_voltage if spec else 3.0)
        lo, hi = self._battery_spec.voltage_range
        if not lo <= v0 <= hi:
            raise ConfigError(where, "rig.battery_initial_voltage",
                              f"{v0:g} V is outside the cell's open-circuit-voltage table [{lo:g}, {hi:g}] V")
        self._qd = float(self._battery_spec.discharged_capacity(v0))  # discharged capacity when not in the plant, C
        # the cell curve tabulated finely for per-tick use (linear between 2049 points of the PCHIP curve)
        ocv_q = np.linspace(-0.05, 1.05, 2049) * self._battery_spec.capacity
        self._ocv_q0 = float(ocv_q[0])
        self._ocv_h = float(ocv_q[1] - ocv_q[0])
        self._ocv_list = np.asarray(self._battery_spec.ocv(ocv_q), dtype=float).tolist()
        self._active = self._flight
        self.t = 0.0
        self._x = self._flight.model.x0_nominal.copy()
        if self._flight.has_battery:
            self._x[self._flight.s_qd] = self._qd
        self._yb = self._outputs_now()[None, :]
        self._yj = 0
        f0 = self._flight
        self._row = (float(self._y[f0.i_z3]), float(self._y[f0.i_vterm]),
                     float(self._y[f0.i_vbat]) if f0.i_vbat >= 0 else math.nan, float(self._u_now()[2]))

        # amplifier and board load
        self._v = (0.0, 0.0)  # demand in force (V)
        self._v_prev = (0.0, 0.0)  # demand at the start of the current tick (V)
        self._i_board = 0.0  # A
        self._last_cmd_t = 0.0
        self.refused_commands = 0
        self.watchdog_trips = 0
        self._refused_flag = False
        self._watchdog_open = False

        # time, sequence, noise, sample
        self._k = 0  # whole ticks advanced (for the aligned fast path)
        self._offgrid = False  # advanced by a non-tick dt at some point
        self.seq = 0
        self._rng = np.random.default_rng([self.seed, 104729])
        self._noise: list[list[float]] = []
        self._noise_i = 0
        self._block: _Block | None = None
        self.blocks = 0
        self.ticks = 0
        self._sample = self._make_sample()

    # --- construction helpers ---------------------------------------------------------------------
    @classmethod
    def from_url(cls, url: str) -> SimulatedRig:
        """``sim``, ``sim:NAME`` or ``sim://?scenario=NAME|PATH&seed=S&params=P&coupling=C`` (query keys optional)."""
        rest = url[3:] if url.startswith("sim") else url
        query: dict[str, str] = {}
        name: str | None = None
        if rest.startswith(":") and not rest.startswith("://"):
            name = rest[1:].split("?", 1)[0] or None
            rest = "?" + rest.split("?", 1)[1] if "?" in rest else ""
        parsed = urlparse("sim" + rest if rest.startswith("://") else "sim://" + rest)
        for key, values in parse_qs(parsed.query, keep_blank_values=False).items():
            query[key] = values[-1]
        unknown = set(query) - {"scenario", "seed", "params", "coupling"}
        if unknown:
            raise InputError(f"sim link URL {url!r}: unknown option {sorted(unknown)[0]!r} "
                             "(known: scenario, seed, params, coupling)")
        scen_name = query.get("scenario", name)
        scenario = load_scenario(scen_name) if scen_name else None
        seed = None
        if "seed" in query:
            try:
                seed = int(query["seed"])
            except ValueError:
                raise InputError(f"sim link URL {url!r}: seed must be an integer, got {query['seed']!r}") from None
        return cls(scenario, seed=seed, params=query.get("params"), coupling=query.get("coupling"))

    def _model(self, terminal: str) -> _TruthModel:
        if terminal not in self._models:
            params, effects, effect_params, deviations, where = self._args
            rtol = self._rtol.get(terminal, self._flight_rtol)
            self._models[terminal] = _TruthModel(params, effects, terminal, effect_params, deviations, rtol, where)
        return self._models[terminal]

    # --- RigEndpoint ------------------------------------------------------------------------------
    def apply(self, command: ActuatorCommand) -> None:
        """Take the board's command for the coming interval (refused, keeping the last valid output, if invalid)."""
        v1, v2, i = command.v_ch1, command.v_ch2, command.board_current
        lo, hi = self._v_range
        if not (lo <= v1 <= hi and lo <= v2 <= hi and 0.0 <= i < 10.0):  # NaN fails every comparison
            self.refused_commands += 1
            self._refused_flag = True
            return
        self._refused_flag = False
        self._v = (float(v1), float(v2))
        self._i_board = float(i)
        self._last_cmd_t = self.t
        self._watchdog_open = False

    def advance(self, dt: float) -> None:
        """Move rig time forward by ``dt`` seconds (the caller owns the clock)."""
        if not (dt > 0 and math.isfinite(dt)):
            raise ValueError(f"rig advance needs a positive finite dt, got {dt!r}")
        if self.t - self._last_cmd_t > self.watchdog + 1e-12 and not self._watchdog_open:
            self._watchdog_open = True
            self.watchdog_trips += 1
            self._v = (0.0, 0.0)
        seg = self._seg if self.t < self._seg_until else self._segment()
        hv = self._hv_override if self._hv_override is not None else seg[0]
        want = self._amp if hv else self._flight
        aligned = (dt == self.tick or abs(dt - self.tick) <= 1e-9 * self.tick) and not self._offgrid
        if want is not self._active and not (aligned and want is self._flight and self._active is self._idle):
            self._switch(want)
        v = self._v if hv else (0.0, 0.0)
        i_load = self._i_board + seg[3]
        if aligned:
            self._advance_tick(v, i_load, want)
        else:
            self._offgrid = True
            self._block = None
            self._integrate_direct(dt, v, i_load)
        self._v_prev = v
        self.ticks += 1
        seg = self._seg if self.t < self._seg_until else self._segment()
        if seg[1] != "frozen_seq":
            self.seq = (self.seq + 1) & 0xFFFFFFFF
            self._sample = self._make_sample(seg)

    def sample(self) -> RigSample:
        """The latest snapshot (repeatable: nothing advances)."""
        return self._sample

    # --- extras for operators, the HIL server and reports -------------------------------------------
    def _segment(self) -> tuple[bool, str | None, bool, float, float]:
        """The scheduled environment state now (cached until its next change)."""
        if self.t >= self._seg_until:
            self._seg = self.env.segment(self.t)
            self._seg_until = self._seg[4]
        return self._seg

    @property
    def hv_present(self) -> bool:
        if self._hv_override is not None:
            return self._hv_override
        return self._segment()[0]

    def set_hv_present(self, present: bool | None) -> None:
        """Force the HV-equipment presence (``None``: follow the scenario again)."""
        self._hv_override = present

    def link_down(self, t: float | None = None) -> bool:
        """Whether the scenario schedules a link outage at ``t`` (default: now); used by the in-process link."""
        if t is None:
            return (self._seg if self.t < self._seg_until else self._segment())[2]
        return self.env.link_down(t)

    @property
    def battery_discharged(self) -> float:
        """Discharged capacity of the board cell (C; 0 = full)."""
        if self._active.has_battery:
            return float(self._state_now()[self._active.s_qd])
        return self._qd

    def truth(self) -> dict[str, Any]:
        """True (noise-free) rig quantities now, SI units with unit-suffixed keys."""
        y = self._y
        qd = self.battery_discharged
        cell = self._battery_spec
        return {
            "time_s": self.t, "z3_m": float(y[self._active.i_z3_true]),
            "v_terminal_V": float(y[self._active.i_vterm]),
            "battery_ocv_V": float(cell.ocv(qd)), "battery_soc": float(1.0 - qd / cell.capacity),
            "battery_discharged_C": qd, "terminal": self._active.terminal, "hv_present": self.hv_present,
            "v_ch1_V": self._v[0], "v_ch2_V": self._v[1], "board_current_A": self._i_board,
            "refused_commands": self.refused_commands, "watchdog_trips": self.watchdog_trips,
            "plant_steps": sum(m.steps for m in self._models.values()), "plant_blocks": self.blocks,
            "plant_reduced_blocks": self.reduced_blocks,
            "plant_seconds": sum(m.seconds for m in self._models.values()),
        }

    def describe(self) -> dict[str, Any]:
        return {
            "params": self.params.name, "deviations": dict(self.deviations), "effects": list(self.effects),
            "coupling": self.coupling, "flight_terminal": self._flight.terminal, "seed": self.seed,
            "tick_s": self.tick, "lookahead_ticks": self.lookahead_ticks, "z3_noise_m": self.z3_noise,
            "accel_noise_m_s2": self.accel_noise, "v_patch_noise_V": self.v_patch_noise, "watchdog_s": self.watchdog,
            "battery": self._battery_spec.name, "scenario": self.scenario.name if self.scenario else None,
        }

    # --- internals ----------------------------------------------------------------------------------
    @property
    def _y(self) -> np.ndarray:
        """Outputs of the truth plant now (SI units, the active composition's output order)."""
        return self._yb[self._yj]

    def _state_now(self) -> np.ndarray:
        b = self._block
        return b.x[b.j] if b is not None else self._x

    def _outputs_now(self) -> np.ndarray:
        return self._active.model.outputs(self.t, self._x, self._u_now(), self._active.p[0])

    def _u_now(self) -> np.ndarray:
        return np.array([0.0, 0.0, float(self.env.base_acceleration(np.array([self.t]))[0])])

    def _switch(self, new: _TruthModel) -> None:
        """Change terminal: carry the core and shared extra states over by name; keep the battery state."""
        old = self._active
        x_old = self._state_now().copy()
        self._parked[id(old)] = x_old  # its own extra states (e.g. the power-audit integrals) wait for its return
        if old.has_battery:
            self._qd = float(x_old[old.s_qd])
        parked = self._parked.get(id(new))
        x_new = parked.copy() if parked is not None else new.model.x0_nominal.copy()
        x_new[: L.N_CORE_STATES] = x_old[: L.N_CORE_STATES]
        old_names = old.model.state_names
        for k, name in enumerate(new.model.state_names[L.N_CORE_STATES:], start=L.N_CORE_STATES):
            if name in old_names:
                x_new[k] = x_old[old_names.index(name)]
        if new.has_battery:
            x_new[new.s_qd] = self._qd
        self._active = new
        self._x = x_new
        self._block = None

    def _inputs(self, t0: float, n_ticks: int, v_start: tuple[float, float], v_end: tuple[float, float]
                ) -> tuple[np.ndarray, float]:
        """Input samples over ``n_ticks`` ticks from ``t0`` (rig grid) with a linear slew over the first tick."""
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
        u[:, 0] = v_end[0]
        u[:, 1] = v_end[1]
        if v_start != v_end:
            frac = np.arange(m + 1) / m
            u[: m + 1, 0] = v_start[0] + (v_end[0] - v_start[0]) * frac
            u[: m + 1, 1] = v_start[1] + (v_end[1] - v_start[1]) * frac
        return u, u_dt

    def _set_load(self, model: _TruthModel, i_load: float) -> None:
        if model.p_iboard >= 0:
            model.p[0, model.p_iboard] = i_load

    def _advance_tick(self, v: tuple[float, float], i_load: float, want: _TruthModel) -> None:
        b = self._block
        if b is not None and b.j < b.n and v == self._v_prev and b.key == (id(self._active), v, i_load):
            b.j += 1
        else:
            ramp = v != self._v_prev
            n = 1 if ramp else self.lookahead_ticks
            t0 = self._k * self.tick
            u, u_dt = self._inputs(t0, n, self._v_prev, v)
            t_out = t0 + self.tick * np.arange(n + 1)
            b = None
            if want is self._flight and self._idle is not None:
                # try the reduced model (bridge off); keep it only if the bridge stays far from conducting
                if self._active is not self._idle:
                    self._switch(self._idle)
                x0 = self._state_now().copy()
                y, xs = self._idle.integrate(x0, t0, u, u_dt, t_out, min(5e-3, self.tick))
                if float(np.max(np.abs(y[:, self._idle.i_vterm]))) < 0.5 * self._bridge_threshold(i_load):
                    b = self._new_block(self._idle, (id(self._idle), v, i_load), t0, y, xs, n, u)
                    self.reduced_blocks += 1
                else:
                    self._switch(self._flight)
            if b is None:
                model = self._active
                x0 = self._state_now().copy()
                self._set_load(model, i_load)
                y, xs = model.integrate(x0, t0, u, u_dt, t_out, min(5e-3, self.tick))
                b = self._new_block(model, (id(model), v, i_load), t0, y, xs, n, u)
            self._block = b
            self.blocks += 1
        self._k += 1
        self.t = self._k * self.tick
        j = b.j
        self._yb = b.y  # the outputs now are row j of the block (no view made per tick; see ``_y``)
        self._yj = j
        self._row = (b.z3[j], b.vt[j], b.vb[j] if b.vb is not None else math.nan, b.zdd[j])  # type: ignore[index]
        if not self._active.has_battery:
            self._qd += i_load * self.tick

    def _new_block(self, model: _TruthModel, key: tuple, t0: float, y: np.ndarray, xs: np.ndarray, n: int,
                   u: np.ndarray) -> _Block:
        m = (u.shape[0] - 1) // n
        return _Block(key, t0, y, xs, n, 1, y[:, model.i_z3].tolist(), y[:, model.i_vterm].tolist(),
                      y[:, model.i_vbat].tolist() if model.i_vbat >= 0 else None, u[::m, 2].tolist())

    def _bridge_threshold(self, i_load: float) -> float:
        """|v_s| (V) above which the harvesting bridge would conduct (plant.effects.harvesting closed form)."""
        f = self._flight
        v_d = float(f.p[0, f.p_vdiode]) if f.p_vdiode >= 0 else 0.0
        return self._ocv(self._qd) + 2.0 * v_d - self._r_int * i_load

    def _integrate_direct(self, dt: float, v: tuple[float, float], i_load: float) -> None:
        model = self._active
        self._set_load(model, i_load)
        n = max(2, math.ceil(dt * self.env.rate) + 1)
        times = self.t + np.linspace(0.0, dt, n)
        u = np.empty((n, 3))
        u[:, 2] = self.env.base_acceleration(times)
        frac = np.minimum(1.0, (times - self.t) / min(dt, self.tick))
        u[:, 0] = self._v_prev[0] + (v[0] - self._v_prev[0]) * frac
        u[:, 1] = self._v_prev[1] + (v[1] - self._v_prev[1]) * frac
        t_out = np.array([self.t, self.t + dt])
        y, xs = model.integrate(self._x, self.t, u, dt / (n - 1), t_out, min(5e-3, dt))
        self._x = xs[-1].copy()
        self._yb = y
        self._yj = y.shape[0] - 1
        self.t += dt
        self._row = (float(y[-1, model.i_z3]), float(y[-1, model.i_vterm]),
                     float(y[-1, model.i_vbat]) if model.i_vbat >= 0 else math.nan, float(u[-1, 2]))
        if not model.has_battery:
            self._qd += i_load * dt

    def _ocv(self, qd: float) -> float:
        """Open-circuit voltage (V) at discharged capacity ``qd`` (C): linear on a fine table of the cell curve."""
        q0, h, v = self._ocv_q0, self._ocv_h, self._ocv_list
        i = int((qd - q0) / h)
        if i < 0 or i >= len(v) - 1:
            return float(self._battery_spec.ocv(qd))
        f = (qd - q0) / h - i
        return v[i] + (v[i + 1] - v[i]) * f

    def _draw_noise(self) -> list[float]:
        if self._noise_i >= len(self._noise):
            self._noise = self._rng.standard_normal((1000, 3)).tolist()
            self._noise_i = 0
        row = self._noise[self._noise_i]
        self._noise_i += 1
        return row

    def _make_sample(self, seg: tuple[bool, str | None, bool, float, float] | None = None) -> RigSample:
        z3, vp, vb, zdd = self._row
        if self._noise_i < len(self._noise):
            nz = self._noise[self._noise_i]
            self._noise_i += 1
        else:
            nz = self._draw_noise()
        if seg is None:
            seg = self._segment()
        if vb != vb:  # the cell is not part of the active plant: integrated here
            vb = self._ocv(self._qd) - self._r_int * (self._i_board + seg[3])
        z3 += self.z3_noise * nz[0]
        vp += self.v_patch_noise * nz[1]
        zdd += self.accel_noise * nz[2]
        flags = FLAG_LIMIT_REFUSED if self._refused_flag else 0
        fault = seg[1]
        if fault is not None:
            if fault == "nan":
                z3 = math.nan
            elif fault == "flag":
                flags |= FLAG_SENSOR_FAULT
            elif fault == "out_of_range":
                z3 = 1.0
        hv = self._hv_override if self._hv_override is not None else seg[0]
        return RigSample(self.seq, self.t, z3, vp, zdd, vb, hv, flags)


def _load_cell():
    """The board cell's open-circuit-voltage curve (ML2032) from board_config (the harvesting issue's table)."""
    from board_config.battery import load_battery

    return load_battery("ML2032")


def open_sim_link(url: str) -> InProcessLink:
    """The in-process link to a :class:`SimulatedRig` built from a ``sim...`` URL."""
    return InProcessLink(SimulatedRig.from_url(url), url=url)


set_sim_rig_factory(SimulatedRig.from_url)
