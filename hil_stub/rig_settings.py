"""What a simulated rig is built from: the scenario's ``[rig]`` table with the caller's overrides, resolved once."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

from board_config import ParameterSet, load_parameter_set
from board_config.errors import InputError
from board_config.scenario import RigSpec, Scenario

#: scenario ``coupling`` → the flight terminal of the truth plant
COUPLING_TERMINALS = {"coupled": "harvest_coupled", "paper": "harvest_paper", "none": "open_circuit"}


@dataclass(frozen=True)
class RigSettings:
    """The resolved rig description (SI units): an override wins over the scenario's ``[rig]`` value, which wins
    over the :class:`~board_config.scenario.RigSpec` default. ``where`` names the source for error messages."""

    where: str
    seed: int
    params: ParameterSet
    coupling: str
    battery_initial_voltage: float  # V
    z3_noise: float  # m (1 sigma)
    accel_noise: float  # m/s^2 (1 sigma)
    v_patch_noise: float  # V (1 sigma)
    watchdog: float  # s
    env_rate: float  # Hz
    deviations: dict[str, float] = field(default_factory=dict)  # relative: truth = nominal × (1 + d)
    effects: tuple[str, ...] = ()
    effect_params: dict[str, float] = field(default_factory=dict)

    @property
    def flight_terminal(self) -> str:
        """The truth plant's terminal while no HV equipment is connected."""
        return COUPLING_TERMINALS[self.coupling]

    @classmethod
    def resolve(cls, scenario: Scenario | None, *, seed: int | None = None,
                params: str | ParameterSet | None = None, deviations: Mapping[str, float] | None = None,
                effects: Sequence[str] | None = None, effect_params: Mapping[str, float] | None = None,
                coupling: str | None = None, battery_initial_voltage: float | None = None) -> RigSettings:
        """Settings for ``scenario`` (``None``: a quiet parked rig with the defaults) and the given overrides."""
        spec = scenario.rig if scenario is not None else RigSpec()
        pset = params if params is not None else spec.params
        coupling = coupling if coupling is not None else spec.coupling
        if coupling not in COUPLING_TERMINALS:
            raise InputError(f"rig coupling {coupling!r} unknown (allowed: {', '.join(COUPLING_TERMINALS)})")
        return cls(
            where=scenario.source if scenario is not None else "<rig>",
            seed=int(seed if seed is not None else (scenario.seed if scenario is not None else 0)),
            params=load_parameter_set(pset),
            coupling=coupling,
            battery_initial_voltage=(battery_initial_voltage if battery_initial_voltage is not None
                                     else spec.battery_initial_voltage),
            z3_noise=spec.z3_noise, accel_noise=spec.accel_noise, v_patch_noise=spec.v_patch_noise,
            watchdog=spec.watchdog, env_rate=spec.env_rate,
            deviations=dict(deviations if deviations is not None else spec.deviations),
            effects=tuple(effects if effects is not None else spec.effects),
            effect_params=dict(effect_params if effect_params is not None else spec.effect_params),
        )
