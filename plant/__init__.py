"""Physics of the MFC-laminate SHM system: the twelve-state nominal model composed of physical effects,
its linearisation and frequency responses, and batched compiled integration.

Public surface (import from here): :class:`PlantModel`, :class:`InputSignals`, :class:`PhysicalEffect`,
:class:`Parameter`, :class:`StateSpec`, :class:`OutputSpec`, :func:`register_effect`,
:func:`resolve_effect`, :func:`registered_effects`.
"""

from plant import kernel_cache as _kernel_cache  # noqa: F401, I001  (first: numba's cache directory, kernel_cache)
# the seam's names are bound before the built-in effects are imported: a file in plant/effects may write
# `from plant import Parameter, PhysicalEffect` (docs/architecture.md, the library-effect recipe)
from plant.effect import (
    EffectError,
    OutputSpec,
    Parameter,
    PhysicalEffect,
    SignalSpec,
    StateSpec,
    register_effect,
    registered_effects,
    resolve_effect,
)
from plant import effects as _builtin_effects  # noqa: F401  (registers the built-in effects)
from plant.effects import NOMINAL_EFFECTS
from plant.integrate import IntegrationFailed, IntegrationStatus
from plant.model import PlantModel, SimulationResult
from plant.signals import G0, InputSignals, base_sine, sine_drive, step_drive

__all__ = [
    "G0",
    "NOMINAL_EFFECTS",
    "EffectError",
    "InputSignals",
    "IntegrationFailed",
    "IntegrationStatus",
    "OutputSpec",
    "Parameter",
    "PhysicalEffect",
    "PlantModel",
    "SignalSpec",
    "SimulationResult",
    "StateSpec",
    "base_sine",
    "register_effect",
    "registered_effects",
    "resolve_effect",
    "sine_drive",
    "step_drive",
]

from plant.stepper import Integrator, PlantStepper

__all__ += ["Integrator", "PlantStepper"]
