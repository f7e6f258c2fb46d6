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

The parts: :class:`hil_stub.truth_plant.TruthPlant` (compositions, terminal switching, lookahead blocks),
:class:`hil_stub.amplifier.Amplifier` (validation, slew, watchdog), :class:`hil_stub.sensors.RigSensors` (noise,
sensor faults), :class:`hil_stub.cell.RigCell` (the cell outside the plant) and the scenario's
:class:`hil_stub.environment.Environment`; :class:`hil_stub.rig_settings.RigSettings` resolves what they are built
from. :class:`SimulatedRig` composes them behind the endpoint.

URL: ``open_link("sim")`` / ``"sim:maintenance"`` / ``"sim://?scenario=degraded&seed=3&params=table2"`` builds an
in-process link to a rig made here (registered when this module is imported).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from operator import attrgetter
from typing import Any, Generic, TypeVar, overload

import numpy as np

from board_config import MfcLimits, ParameterSet, load_mfc_limits
from board_config.scenario import Scenario, load_scenario
from drivers.link import ActuatorCommand, Link, RigSample, open_link
from drivers.quiet_span import QuietSpan
from drivers.sim_link import set_sim_rig_factory
from hil_stub.amplifier import Amplifier
from hil_stub.cell import RigCell
from hil_stub.environment import Environment, Segment
from hil_stub.rig_settings import COUPLING_TERMINALS, RigSettings
from hil_stub.sensors import RigSensors, SensorNoise
from hil_stub.sim_url import parse_sim_url
from hil_stub.truth_plant import TruthComposition, TruthPlant

__all__ = ["COUPLING_TERMINALS", "SimulatedRig", "open_sim_link"]

_T = TypeVar("_T")


class _Forward(Generic[_T]):
    """A read-only attribute of the rig that is an attribute of one of its parts (``"settings.seed"``:
    ``rig.settings.seed``), for operators, the HIL server and reports."""

    def __init__(self, path: str, doc: str = "") -> None:
        self._get = attrgetter(path)
        self.__doc__ = doc or f"The rig's {path}."

    @overload
    def __get__(self, rig: None, owner: type) -> _Forward[_T]: ...

    @overload
    def __get__(self, rig: object, owner: type | None = None) -> _T: ...

    def __get__(self, rig: object | None, owner: type | None = None) -> _T | _Forward[_T]:
        return self if rig is None else self._get(rig)


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
        harvesting or open-circuit terminal: 1e-5 — in the default flight its z3 differs from the same plant at 1e-6
        by ~1 µm at most, below the 2 µm laser noise).
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
                 tick: float = 0.01, lookahead_ticks: int = 200, rtol: float = 1e-6, flight_rtol: float = 1e-5,
                 reduce_idle_bridge: bool = True, limits: MfcLimits | None = None,
                 hv_present: bool | None = None) -> None:
        s = RigSettings.resolve(scenario, seed=seed, params=params, deviations=deviations, effects=effects,
                                effect_params=effect_params, coupling=coupling,
                                battery_initial_voltage=battery_initial_voltage)
        self.settings = s
        self.scenario = scenario
        if not (tick > 0 and math.isfinite(tick)):
            raise ValueError(f"rig tick must be positive, got {tick!r}")
        self.tick = float(tick)
        self.lookahead_ticks = max(1, int(lookahead_ticks))
        self.env = Environment(scenario, s.seed, s.env_rate)
        self._hv_override = hv_present
        self._seg = Segment(False, None, False, 0.0, -math.inf)  # the cached environment segment
        self.plant = TruthPlant(s.params, s.effects, s.effect_params, s.deviations, s.flight_terminal, env=self.env,
                                tick=self.tick, lookahead_ticks=self.lookahead_ticks, rtol=rtol,
                                flight_rtol=flight_rtol, reduce_idle_bridge=reduce_idle_bridge, where=s.where)
        flight = self.plant.flight
        # the cell's internal resistance as the harvesting terminal has it (1 ohm without one)
        self.cell = RigCell(flight.param(flight.p_rbint, 1.0), s.battery_initial_voltage, s.where)
        self.plant.start(self.cell)
        self.amplifier = Amplifier(limits if limits is not None else load_mfc_limits(), s.watchdog)
        self.sensors = RigSensors(SensorNoise(z3=s.z3_noise, v_patch=s.v_patch_noise, accel=s.accel_noise), s.seed)
        self.seq = 0
        self.ticks = 0
        self._sample = self._make_sample(self._segment())

    # --- construction helpers ---------------------------------------------------------------------
    @classmethod
    def from_url(cls, url: str, *, scenario: Scenario | None = None, seed: int | None = None,
                 params: str | ParameterSet | None = None, tick: float = 0.01) -> SimulatedRig:
        """``sim``, ``sim:NAME`` or ``sim://?scenario=NAME|PATH&seed=S&params=P&coupling=C`` (query keys optional).

        What the URL leaves out comes from the keyword defaults, which ``drivers.open_link(url, **defaults)`` passes
        on (``shm run`` gives its scenario, ``--seed``, ``--params`` and board tick), and otherwise from the scenario.
        """
        opts = parse_sim_url(url)
        if opts.scenario:
            scenario = load_scenario(opts.scenario)
        return cls(scenario, seed=opts.seed if opts.seed is not None else seed, params=opts.params or params,
                   coupling=opts.coupling, tick=tick)

    def _model(self, terminal: str) -> TruthComposition:
        """The truth plant's composition with ``terminal``, built (its compiled kernels loaded) now if it was not:
        :func:`hil_stub.truth.build_truth_rig` preloads the amplifier terminal through it."""
        return self.plant.composition(terminal)

    # --- RigEndpoint ------------------------------------------------------------------------------
    def apply(self, command: ActuatorCommand) -> None:
        """Take the board's command for the coming interval (refused, keeping the last valid output, if invalid)."""
        self.amplifier.apply(command, self.plant.t)

    def advance(self, dt: float) -> None:
        """Move rig time forward by ``dt`` seconds (the caller owns the clock)."""
        if not (dt > 0 and math.isfinite(dt)):
            raise ValueError(f"rig advance needs a positive finite dt, got {dt!r}")
        amp = self.amplifier
        plant = self.plant
        amp.check_watchdog(plant.t)
        seg = self._seg if plant.t < self._seg.until else self._segment()
        hv = self._hv(seg)
        if hv:
            v1, v2 = amp.v_ch1, amp.v_ch2
        else:
            v1 = v2 = 0.0
        plant.advance(dt, hv, amp.last_ch1, amp.last_ch2, v1, v2, amp.board_current + seg.extra_load)
        amp.last_ch1, amp.last_ch2 = v1, v2
        self.ticks += 1
        seg = self._seg if plant.t < self._seg.until else self._segment()
        if seg.sensor_fault != "frozen_seq":
            self.seq = (self.seq + 1) & 0xFFFFFFFF
            self._sample = self._make_sample(seg)

    def sample(self) -> RigSample:
        """The latest snapshot (repeatable: nothing advances)."""
        return self._sample

    # --- quiet spans (drivers.quiet_span): stand-by stretches in one call -----------------------------------
    def peek_quiet(self, command: ActuatorCommand, max_ticks: int, dt: float) -> QuietSpan | None:
        """The samples the next exchanges (``apply(command)``, ``advance(dt)``, ``sample()``; 1 to ``max_ticks`` of
        them) would return, if ``command`` is a zero demand at the board current already in force, ``dt`` is the rig
        tick and nothing is scheduled to change (HV presence, a sensor fault, an outage or a load; the plant inside
        its current lookahead block; the sensor noise drawn ahead): bit-identical to the single exchanges. Nothing
        advances; None when any condition fails."""
        cls = type(self)
        if cls.peek_quiet is SimulatedRig.peek_quiet and (
                cls.apply is not SimulatedRig.apply or cls.advance is not SimulatedRig.advance
                or cls.sample is not SimulatedRig.sample):
            return None  # a subclass that changes a tick's exchange sees every tick
        amp = self.amplifier
        plant = self.plant
        if (max_ticks < 1 or dt != self.tick or command.v_ch1 != 0.0 or command.v_ch2 != 0.0
                or float(command.board_current) != amp.board_current or amp.refused_flag or amp.v_ch1 != 0.0
                or amp.v_ch2 != 0.0 or amp.last_ch1 != 0.0 or amp.last_ch2 != 0.0):
            return None
        seg = self._seg if plant.t < self._seg.until else self._segment()
        hv = self._hv(seg)
        if seg.sensor_fault is not None or seg.link_down:
            return None
        i_load = amp.board_current + seg.extra_load
        truth = plant.peek_quiet(hv, i_load, max_ticks)
        if truth is None:
            return None
        z3, v_patch, v_battery, z0dd = truth
        k0 = plant._k
        t = np.arange(k0 + 1, k0 + 1 + z3.shape[0]) * plant.tick  # as plant.t = k * tick after each advance
        n = int(np.searchsorted(t, seg.until, side="left"))  # every sample strictly before the segment's end
        z3n, vpn, zddn = self.sensors.peek_noisy(z3[:n], v_patch[:n], z0dd[:n])
        n = z3n.shape[0]
        if n < 1:
            return None
        qd_after: np.ndarray | None = None
        if v_battery is None:  # the cell outside the plant: discharged by the load tick by tick, read from its table
            cell = self.cell
            steps = np.full(n + 1, i_load * self.tick)
            steps[0] = cell.qd
            qd_after = np.add.accumulate(steps)[1:]  # sequential sums, as n calls of RigCell.discharge
            ocv = cell.ocv_many(qd_after)
            if ocv is None:
                return None
            vb = ocv - cell.r_int * i_load
        else:
            vb = v_battery[:n]
        return QuietSpan((self.seq + 1) & 0xFFFFFFFF, t[:n], z3n, vpn, zddn, vb, hv, qd_after)

    def commit_quiet(self, span: QuietSpan, m: int) -> None:
        """Advance as ``m`` exchanges of the span's command would have (``1 <= m <= span.n``)."""
        if not 1 <= m <= span.n:
            raise ValueError(f"commit_quiet: {m} ticks of a span of {span.n}")
        amp = self.amplifier
        amp._last_command_t = float(span.t[m - 2]) if m >= 2 else self.plant.t  # the last apply's time
        amp._watchdog_open = False
        qd = span.rig_state
        self.plant.commit_quiet(m, float(qd[m - 1]) if qd is not None else None)
        self.sensors.skip(m)
        self.ticks += m
        self.seq = (self.seq + m) & 0xFFFFFFFF
        self._sample = span.sample(m - 1)

    # --- extras for operators, the HIL server and reports -------------------------------------------
    t = _Forward[float]("plant.t", "Rig time (s).")
    seed = _Forward[int]("settings.seed")
    params = _Forward[ParameterSet]("settings.params")
    deviations = _Forward[dict[str, float]]("settings.deviations")
    effects = _Forward[tuple[str, ...]]("settings.effects")
    effect_params = _Forward[dict[str, float]]("settings.effect_params")
    coupling = _Forward[str]("settings.coupling")
    limits = _Forward[MfcLimits]("amplifier.limits")
    watchdog = _Forward[float]("amplifier.watchdog")
    z3_noise = _Forward[float]("sensors.noise.z3")
    accel_noise = _Forward[float]("sensors.noise.accel")
    v_patch_noise = _Forward[float]("sensors.noise.v_patch")
    refused_commands = _Forward[int]("amplifier.refused_commands")
    watchdog_trips = _Forward[int]("amplifier.watchdog_trips")
    blocks = _Forward[int]("plant.blocks")
    reduced_blocks = _Forward[int]("plant.reduced_blocks")

    def _segment(self) -> Segment:
        """The scheduled environment state now (cached until its next change)."""
        t = self.plant.t
        if t >= self._seg.until:
            self._seg = self.env.segment(t)
        return self._seg

    @property
    def hv_present(self) -> bool:
        return self._hv(self._segment())

    def _hv(self, seg: Segment) -> bool:
        """HV equipment present in segment ``seg``: the forced value if one is set, else the scenario's."""
        return bool(self._hv_override) if self._hv_override is not None else seg.hv_present

    def set_hv_present(self, present: bool | None) -> None:
        """Force the HV-equipment presence (``None``: follow the scenario again)."""
        self._hv_override = present

    def link_down(self, t: float | None = None) -> bool:
        """Whether the scenario schedules a link outage at ``t`` (default: now); used by the in-process link."""
        if t is None:
            return (self._seg if self.plant.t < self._seg.until else self._segment()).link_down
        return self.env.link_down(t)

    @property
    def battery_discharged(self) -> float:
        """Discharged capacity of the board cell (C; 0 = full)."""
        return self.plant.battery_discharged

    def truth(self) -> dict[str, Any]:
        """True (noise-free) rig quantities now, SI units with unit-suffixed keys."""
        plant = self.plant
        y = plant.outputs
        qd = self.battery_discharged
        spec = self.cell.spec
        amp = self.amplifier
        return {
            "time_s": plant.t, "z3_m": float(y[plant.active.i_z3_true]),
            "v_terminal_V": float(y[plant.active.i_vterm]),
            "battery_ocv_V": float(spec.ocv(qd)), "battery_soc": float(1.0 - qd / spec.capacity),
            "battery_discharged_C": qd, "terminal": plant.active.terminal, "hv_present": self.hv_present,
            "v_ch1_V": amp.v_ch1, "v_ch2_V": amp.v_ch2, "board_current_A": amp.board_current,
            "refused_commands": amp.refused_commands, "watchdog_trips": amp.watchdog_trips,
            "plant_steps": plant.steps, "plant_blocks": plant.blocks, "plant_reduced_blocks": plant.reduced_blocks,
            "plant_seconds": plant.seconds,
        }

    def describe(self) -> dict[str, Any]:
        s = self.settings
        return {
            "params": s.params.name, "deviations": dict(s.deviations), "effects": list(s.effects),
            "coupling": s.coupling, "flight_terminal": self.plant.flight.terminal, "seed": s.seed,
            "tick_s": self.tick, "lookahead_ticks": self.lookahead_ticks, "z3_noise_m": self.z3_noise,
            "accel_noise_m_s2": self.accel_noise, "v_patch_noise_V": self.v_patch_noise, "watchdog_s": self.watchdog,
            "battery": self.cell.name, "scenario": self.scenario.name if self.scenario else None,
        }

    # --- internals ----------------------------------------------------------------------------------
    def _make_sample(self, seg: Segment) -> RigSample:
        reading = self.plant.reading
        vb = reading.v_battery
        if vb != vb:  # the cell is not part of the active plant: the rig's own
            cell = self.cell
            vb = cell.ocv(cell.qd) - cell.r_int * (self.amplifier.board_current + seg.extra_load)
        hv = self._hv(seg)
        return self.sensors.sample(self.seq, self.plant.t, reading, vb, seg.sensor_fault, hv,
                                   self.amplifier.refused_flag)


def open_sim_link(url: str) -> Link:
    """The in-process link to a :class:`SimulatedRig` built from a ``sim...`` URL (``drivers.open_link``'s ``sim``
    scheme, kept under this name for callers of the rig module)."""
    return open_link(url)


set_sim_rig_factory(SimulatedRig.from_url)
