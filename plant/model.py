"""The plant: a composition of physical effects compiled into one right-hand side and batch integrator."""

from __future__ import annotations

import copy
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from types import ModuleType
from typing import Any

import numpy as np

from board_config import (
    CORE_PARAMETER_NAMES,
    CORE_PARAMETERS,
    CORE_SCHEMA,
    EffectEntry,
    ParameterSet,
    ParameterVector,
    load_parameter_set,
)
from plant import layout as L
from plant.compose import KERNEL_ENTRIES, compose, uncached_entries
from plant.composition import build_composition
from plant.effect import EffectError, Parameter, PhysicalEffect, resolve_effect
from plant.effects import NOMINAL_EFFECTS
from plant.integrate import IntegrationStatus
from plant.signals import InputSignals
from plant.stepper import Integrator, default_threads, failure_of

#: typical magnitudes of the core states (set the integrator's absolute tolerances)
CORE_STATE_SCALES = np.array([1e-3] * 3 + [1e-2] * 3 + [1e-3] * 6)


#: default largest integration step (s). Outputs come from dense output, so this is not tied to the output rate;
#: the 102 Hz mode of table2 limits explicit steps to ~3 ms anyway. Inputs are sampled at the stage points of each
#: step: pass ``h_max`` = the input sample interval when the input carries content above ~1/(10 h_max).
DEFAULT_H_MAX = 0.01


@dataclass
class SimulationResult:
    """Trajectories of a batch: ``y[b, k, j]`` is output ``j`` of batch member ``b`` at time ``t[k]``."""

    t: np.ndarray
    y: np.ndarray
    output_names: tuple[str, ...]
    output_units: tuple[str, ...]
    status: np.ndarray
    n_steps: np.ndarray  # attempted integration steps per batch member (accepted + rejected)
    states: np.ndarray | None = None
    state_names: tuple[str, ...] = ()
    bus: np.ndarray | None = None
    meta: dict[str, Any] = field(default_factory=dict)
    n_rejected: np.ndarray | None = None  # of the attempted steps, how many the error control rejected

    def __getitem__(self, name: str) -> np.ndarray:
        """Output (or, if recorded, state) ``name`` as an array of shape (batch, time)."""
        if name in self.output_names:
            return self.y[:, :, self.output_names.index(name)]
        if self.states is not None and name in self.state_names:
            return self.states[:, :, self.state_names.index(name)]
        bus_names = self.meta.get("bus_names", L.BUS_NAMES)  # core signals and those the composer allocated
        if self.bus is not None and name in bus_names.values():
            idx = next(i for i, n in bus_names.items() if n == name)
            return self.bus[:, :, idx]
        raise KeyError(f"no output or recorded state named '{name}' (outputs: {', '.join(self.output_names)})")

    @property
    def ok(self) -> bool:
        return bool(np.all(self.status == 0))

    def failures(self) -> list[str]:
        return [f"batch member {b}: {IntegrationStatus(int(s)).message}"
                for b, s in enumerate(self.status) if s != 0]

    def raise_on_failure(self, prefix: str = "") -> None:
        """Raise :class:`~plant.integrate.IntegrationFailed` (a ``FloatingPointError``) for the first failed batch
        member, with the message ``prefix`` + the failures joined by ``"; "``; nothing if every member succeeded."""
        exc = failure_of(self.status, self.t, self.y, prefix + "; ".join(self.failures()))
        if exc is not None:
            raise exc


class PlantModel:
    """The plant composed of effects.

    Parameters
    ----------
    params:
        A :class:`~board_config.ParameterSet` or the name/path of one (``"table2"``). Effects listed in the
        set (``[[effects]]``) are added automatically.
    effects:
        Further effects to add: registered names, dotted paths ``package.module:ClassName`` or classes.
    terminal:
        What sets the patch terminal voltage: ``"amplifier"`` (actuation; default) or ``"open_circuit"``
        (sensing), or any registered terminal effect (e.g. the harvesting circuit).
    core:
        The core effects (default: the nominal model of the seed paper). Leaving out ``"bouc_wen"`` gives
        the linear model.
    effect_params:
        Values for added effects' parameters by name (overrides the set and the defaults).
    """

    def __init__(
        self,
        params: ParameterSet | str = "table2",
        effects: Sequence[str | type[PhysicalEffect]] = (),
        terminal: str | type[PhysicalEffect] = "amplifier",
        core: Sequence[str | type[PhysicalEffect]] = NOMINAL_EFFECTS,
        effect_params: Mapping[str, float] | None = None,
    ) -> None:
        self.params = load_parameter_set(params)
        entries: list[EffectEntry] = list(self.params.effects)
        set_values: dict[str, float] = {}
        set_units: dict[str, str] = {}
        from_set = [resolve_effect(e.name) for e in entries]
        for e, cls in zip(entries, from_set):
            # an instance's entry may name its parameters as declared ("m") or as in the model ("tip_2.m")
            own = {cls.declared_name(q.name): q.name for q in cls.own_parameters()} if cls.prefix else {}
            set_values.update({own.get(k, k): v for k, v in e.parameters.items()})
            set_units.update({own.get(k, k): v for k, v in e.units.items()})
        added = from_set + [resolve_effect(e) for e in effects]
        core_cls = [resolve_effect(c) for c in core]
        term_cls = resolve_effect(terminal)
        if term_cls.role != "terminal":
            raise EffectError(f"terminal '{term_cls.name}' is not a terminal effect (role {term_cls.role!r})")
        for c in added:
            if c.role == "terminal":
                raise EffectError(f"effect '{c.name}' is a terminal; pass it as terminal=, not as an added effect")
        classes: list[type[PhysicalEffect]] = []
        for c in [*core_cls, term_cls, *added]:
            if c in classes:
                continue  # the same effect listed twice (e.g. in the set and on the command line)
            if any(o.name == c.name for o in classes):
                raise EffectError(f"two different effects share the name '{c.name}'")
            classes.append(c)
        self.effects: tuple[type[PhysicalEffect], ...] = tuple(classes)

        # layout of extra states / parameters / outputs, slot tables and allocated signals (plant.composition)
        self.composition = build_composition(self.effects)
        state_specs = self.composition.states
        own_params = list(self.composition.parameters)
        out_specs = self.composition.outputs
        owner = self.composition.owner
        self._offsets = self.composition.offsets
        self.state_names = L.CORE_STATE_NAMES + tuple(s.name for s in state_specs)
        self.state_units = L.CORE_STATE_UNITS + tuple(s.unit for s in state_specs)
        self.state_scales = np.concatenate([CORE_STATE_SCALES, [s.scale for s in state_specs]])
        self.x0_nominal = np.concatenate([np.zeros(L.N_CORE_STATES), [s.initial for s in state_specs]])
        self.param_names = CORE_PARAMETER_NAMES + tuple(p.name for p in own_params)
        self.param_units = tuple(CORE_SCHEMA[n].unit for n in CORE_PARAMETER_NAMES) + tuple(
            p.unit for p in own_params)
        self.own_parameters: tuple[Parameter, ...] = tuple(own_params)
        self.output_names = L.CORE_OUTPUT_NAMES + tuple(o.name for o in out_specs)
        self.output_units = L.CORE_OUTPUT_UNITS + tuple(o.unit for o in out_specs)
        if len(set(self.state_names)) != len(self.state_names):
            raise EffectError(f"duplicate state names in the composed model: {self.state_names}")
        if len(set(self.output_names)) != len(self.output_names):
            raise EffectError(f"duplicate output names in the composed model: {self.output_names}")

        # nominal parameter vector
        p0 = np.empty(len(self.param_names))
        for i, n in enumerate(CORE_PARAMETER_NAMES):
            p0[i] = self.params.values[n]
        overrides = dict(effect_params or {})
        known_own = {p.name for p in own_params}
        for name in list(set_values) + list(overrides):
            if name not in known_own:
                raise EffectError(f"{self.params.source}: value given for '{name}', which no effect of the model "
                                  f"declares (effects: {', '.join(c.name for c in classes)})")
        for i, par in enumerate(own_params):
            if name_unit := set_units.get(par.name):
                if name_unit != par.unit:
                    raise EffectError(f"{self.params.source}: parameter '{par.name}' has unit '{name_unit}', "
                                      f"effect '{owner[par.name]}' expects '{par.unit}'")
            value = overrides.get(par.name, set_values.get(par.name, par.default))
            p0[L.N_CORE_PARAMS + i] = par.check(value, f"effect '{owner[par.name]}'")
        self.p_nominal = p0
        self.n_states = len(self.state_names)
        self.n_outputs = len(self.output_names)
        self._kernel_module: ModuleType | None = None
        self._integrator_source: str | None = None

    # --- composition ------------------------------------------------------------------------------
    def kernels(self) -> ModuleType:
        """The compiled kernel module (``rhs``, ``out``, ``run_chunk``); built or loaded on first use."""
        if self._kernel_module is None:
            s_off, p_off, y_off = self._offsets
            if self._integrator_source is None:
                self._kernel_module = compose(self.effects, s_off, p_off, y_off, self.n_states,
                                              composition=self.composition)
            else:
                self._kernel_module = compose(self.effects, s_off, p_off, y_off, self.n_states,
                                              integrator_source=self._integrator_source,
                                              composition=self.composition)
        return self._kernel_module

    def uncached_kernels(self, entries: tuple[str, ...] = KERNEL_ENTRIES) -> list[str]:
        """Which compiled entry points of this composition a first call would compile (not in numba's on-disk
        cache): :func:`plant.compose.uncached_entries`; compiles nothing."""
        s_off, p_off, y_off = self._offsets
        return uncached_entries(self.effects, s_off, p_off, y_off, self.n_states, entries,
                                composition=self.composition)

    def with_integrator_source(self, source: str) -> PlantModel:
        """The same model with another batch-integrator source (same ``run_chunk``/``run_chunk_stats``
        signatures as :data:`plant.integrate.INTEGRATOR_SOURCE`); the benchmark uses it to time the previous
        integrator against the current one in the same run."""
        other = copy.copy(self)
        other._integrator_source = source
        other._kernel_module = None
        return other

    @property
    def effect_names(self) -> tuple[str, ...]:
        return tuple(c.name for c in self.effects)

    def param_index(self, name: str) -> int:
        try:
            return self.param_names.index(name)
        except ValueError:
            raise KeyError(f"unknown parameter '{name}' (model parameters: {', '.join(self.param_names)})"
                           ) from None

    def param_value(self, name: str) -> float:
        return float(self.p_nominal[self.param_index(name)])

    @property
    def nominal(self) -> ParameterVector:
        """The model's parameters (core, then the effects' own) with their nominal values, by name."""
        return ParameterVector.of(CORE_PARAMETERS + self.own_parameters, self.p_nominal)

    def param_batch(self, n: int | None = None, **columns: Any) -> np.ndarray:
        """A (batch, n_params) parameter array: nominal values with named columns replaced.

        ``model.param_batch(k3=k3_values, beta_h=beta_values)``; scalars broadcast.
        """
        sizes = {np.size(v) for v in columns.values() if np.ndim(v) > 0}
        if n is None:
            n = max(sizes) if sizes else 1
        if any(s not in (1, n) for s in sizes):
            raise ValueError(f"parameter columns have inconsistent lengths {sorted(sizes)} (batch {n})")
        p = np.tile(self.p_nominal, (n, 1))
        for name, value in columns.items():
            p[:, self.param_index(name)] = value
        return p

    def rhs(self, t: float, x: np.ndarray, u: np.ndarray | None = None, p: np.ndarray | None = None,
            return_bus: bool = False):
        """Evaluate the composed right-hand side once (Python-callable; for linearisation and baselines)."""
        rhs_fn = self.kernels().rhs
        dx = np.zeros(self.n_states)
        bus = np.zeros(L.N_BUS)
        u = np.zeros(L.N_INPUTS) if u is None else np.array(u, dtype=float, order="C")
        p = np.array(self.p_nominal if p is None else p, dtype=float, order="C")
        rhs_fn(float(t), np.array(x, dtype=float, order="C"), p, u, bus, dx)
        return (dx, bus) if return_bus else dx

    def outputs(self, t: float, x: np.ndarray, u: np.ndarray | None = None, p: np.ndarray | None = None
                ) -> np.ndarray:
        """The output vector for one state (Python-callable)."""
        out_fn = self.kernels().out
        y = np.zeros(self.n_outputs)
        u = np.zeros(L.N_INPUTS) if u is None else np.array(u, dtype=float, order="C")
        p = np.array(self.p_nominal if p is None else p, dtype=float, order="C")
        out_fn(float(t), np.array(x, dtype=float, order="C"), p, u, np.zeros(L.N_BUS), np.zeros(self.n_states), y)
        return y

    # --- simulation -------------------------------------------------------------------------------
    def simulate(
        self,
        inputs: InputSignals,
        t_end: float | None = None,
        dt_out: float = 1e-3,
        params: np.ndarray | None = None,
        x0: np.ndarray | None = None,
        rtol: float = 1e-6,
        atol: np.ndarray | None = None,
        h_max: float | None = None,
        record_states: bool = False,
        record_bus: bool = False,
        t_out: np.ndarray | None = None,
        max_steps: int = 50_000_000,
        threads: int | None = None,
        lanes: bool | None = None,
    ) -> SimulationResult:
        """Integrate a batch. ``params`` is (batch, n_params) or (n_params,); ``x0`` likewise for states.

        The batch size is the largest of the parameter, initial-state and input batches (each 1 or B).
        Outputs are sampled every ``dt_out`` seconds from ``inputs.t0`` to ``t_end`` (default: the end of
        the inputs), or at the given uniform-or-not ``t_out`` times. ``lanes``: the lane integrator on/off
        (default: for batches of ``plant.stepper.LANE_MIN_BATCH`` members or more; see
        :meth:`plant.stepper.Integrator.batch`).
        """
        p = self.p_nominal[None] if params is None else np.atleast_2d(np.asarray(params, dtype=float))
        if p.shape[1] != len(self.param_names):
            raise ValueError(f"params must have {len(self.param_names)} columns ({', '.join(self.param_names)}),"
                             f" got shape {p.shape}")
        if not np.all(np.isfinite(p)):
            raise ValueError("params contains a non-finite value at (row, column) "
                             f"{tuple(np.argwhere(~np.isfinite(p))[0])}")
        xs0 = self.x0_nominal[None] if x0 is None else np.atleast_2d(np.asarray(x0, dtype=float))
        if xs0.shape[1] != self.n_states:
            raise ValueError(f"x0 must have {self.n_states} columns ({', '.join(self.state_names)}), "
                             f"got shape {xs0.shape}")
        batch = max(p.shape[0], xs0.shape[0], inputs.batch)
        for label, arr in (("params", p), ("x0", xs0), ("inputs", inputs.values)):
            if arr.shape[0] not in (1, batch):
                raise ValueError(f"{label} has batch size {arr.shape[0]}, expected 1 or {batch}")
        p = np.array(np.broadcast_to(p, (batch, p.shape[1])), dtype=float, order="C")
        xs0 = np.array(np.broadcast_to(xs0, (batch, self.n_states)), dtype=float, order="C")
        if t_out is None:
            t_end = inputs.t[-1] if t_end is None else float(t_end)
            if not t_end > inputs.t0:
                raise ValueError(f"t_end ({t_end}) must be after the inputs' start ({inputs.t0})")
            n_out = int(np.floor((t_end - inputs.t0) / dt_out + 1e-9)) + 1
            t_out = inputs.t0 + dt_out * np.arange(n_out)
        t_out = np.ascontiguousarray(t_out, dtype=float)
        if t_out.ndim != 1 or t_out.size < 1 or np.any(np.diff(t_out) <= 0):
            raise ValueError("t_out must be a strictly increasing 1-D array")
        if h_max is None:
            h_max = DEFAULT_H_MAX
        u = np.array(inputs.values, dtype=float, order="C")
        run = Integrator(self, rtol, atol, max_steps=max_steps).batch(
            xs0, p, u, inputs.t0, inputs.dt, t_out, h_max, record_states=record_states, record_bus=record_bus,
            threads=threads or default_threads(), lanes=lanes)
        return SimulationResult(
            t=t_out, y=run.y, output_names=self.output_names, output_units=self.output_units, status=run.status,
            n_steps=run.n_steps, states=run.states, state_names=self.state_names, bus=run.bus,
            meta={"effects": self.effect_names, "params": self.params.name,
                  "bus_names": self.composition.bus_names}, n_rejected=run.n_rejected,
        )

    def describe(self) -> dict[str, Any]:
        """Composition summary: effects, states, parameters with units (for reports and --json)."""
        return {
            "parameter_set": self.params.name,
            "effects": [{"name": c.name, "role": c.role, "description": c.description} for c in self.effects],
            "states": [{"name": n, "unit": u} for n, u in zip(self.state_names, self.state_units)],
            "parameters": [{"name": n, "unit": u, "value": float(v)}
                           for n, u, v in zip(self.param_names, self.param_units, self.p_nominal)],
            "outputs": [{"name": n, "unit": u} for n, u in zip(self.output_names, self.output_units)],
        }
