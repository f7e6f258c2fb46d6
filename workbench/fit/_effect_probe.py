"""A short probe simulation of a user's effect, when a command loads it (issue 33).

A user's effect (a file ``FILE.py[:Class]`` or a dotted path ``pkg.mod:Class``; registered library effects are
trusted) that produces NaN or infinity when simulated would otherwise surface late and mute: a rig served with it
answers nothing useful, a synthetic record is written full of NaN. :func:`probe_effects` runs the nominal model with
the effect at its default parameter values for :data:`PROBE_S` under a 100 V step on the patches and turns
non-finite values, a failed integration or a hook that indexes outside its slots into one :class:`EffectError`
naming the effect, where it came from and what went wrong. Each effect class is probed once per process.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from board_config.parameter_sets import ParameterSet
from plant.effect import (
    EffectError,
    PhysicalEffect,
    effect_source_file,
    is_file_spec,
    resolve_effect,
    split_instance_spec,
)

#: probe length (s) and the step on the patches (V, differential)
PROBE_S = 0.1
PROBE_STEP_V = 100.0

_PROBED: set[type] = set()


def is_user_spec(spec: str | type[PhysicalEffect]) -> bool:
    """A spec that names the user's own code: a file or a dotted ``pkg.mod:Class`` (not a registered name)."""
    if isinstance(spec, type):
        return True
    inner, _ = split_instance_spec(spec)
    return is_file_spec(inner) or ":" in inner


def probe_effects(specs: Sequence[str | type[PhysicalEffect]], params: ParameterSet | str = "table2",
                  option: str = "--effect") -> None:
    """Probe every user effect among ``specs`` (see the module docstring); ``option`` names where it was given."""
    user = [(spec, resolve_effect(spec)) for spec in specs if is_user_spec(spec)]  # every one loads first
    names: dict[str, type[PhysicalEffect]] = {}
    for spec, cls in user:
        if names.setdefault(cls.name, cls) is not cls:
            raise EffectError(f"{option} {spec}: two different effects share the name '{cls.name}' (the other from "
                              f"{effect_source_file(names[cls.name]) or names[cls.name].__module__}); rename one")
    for spec, cls in user:
        if cls.role == "effect" and cls not in _PROBED:
            _probe(cls, spec, params, option)
            _PROBED.add(cls)


def _probe(cls: type[PhysicalEffect], spec: str | type[PhysicalEffect], params: ParameterSet | str,
           option: str) -> None:
    from plant.model import PlantModel
    from plant.signals import step_drive

    where = effect_source_file(cls) or (spec if isinstance(spec, str) else f"{cls.__module__}:{cls.__qualname__}")
    label = f"{option} {spec if isinstance(spec, str) else cls.__qualname__}: effect '{cls.name}' ({where})"
    model = PlantModel(params, effects=[cls])
    inputs = step_drive(PROBE_STEP_V, PROBE_S, dt=1e-3)
    try:
        res = model.simulate(inputs, t_end=PROBE_S, dt_out=PROBE_S / 50, record_states=True)
    except (IndexError, ValueError, ZeroDivisionError) as exc:
        raise EffectError(f"{label} fails in a {PROBE_S:g} s probe simulation: {type(exc).__name__}: {exc} — check "
                          "that its hooks only index its own slots (p[P.name], x[X.name], y[Y.name])") from None
    bad = [n for j, n in enumerate(res.output_names) if not np.all(np.isfinite(res.y[0, :, j]))]
    if res.ok and not bad:
        return
    from workbench.simulation import blame_non_finite

    blame = blame_non_finite(model, res, inputs.values[0], inputs.dt)
    why = blame or ("; ".join(res.failures()) or f"non-finite outputs {', '.join(bad[:4])}") + (
        " — check its hooks (a division by a zero parameter or state? a square root or log of a negative number?)")
    raise EffectError(f"{label} produces NaN or infinity in a {PROBE_S:g} s probe simulation (nominal model + the "
                      f"effect at its default values, a {PROBE_STEP_V:g} V step on the patches): {why}")
