"""The fitted parameter set: fitted core values and every added effect as ``[[effects]]``."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from board_config import CORE_PARAMETER_NAMES, EffectEntry, ParameterSet
from plant import PhysicalEffect, PlantModel
from plant.effect import EffectError, effect_source_file, importable_by_path, resolve_effect
from workbench.fit._targets import FitError


def effect_entry_name(cls: type[PhysicalEffect]) -> str:
    """How a parameter set refers to an effect: its registered name, else its dotted path (or file); an instance
    with a prefix as ``"<how its class is referred to> as <prefix>"``."""
    if cls.instance_of is not None:
        return f"{effect_entry_name(cls.instance_of)} as {cls.prefix}"
    try:
        if resolve_effect(cls.name) is cls:
            return cls.name
    except EffectError:
        pass
    source_file = effect_source_file(cls)
    if source_file is not None:  # loaded from a file: refer to it by its absolute path
        return f"{source_file}:{cls.__qualname__}"
    if not importable_by_path(cls):
        raise FitError(f"effect '{cls.name}' ({cls.__module__}.{cls.__qualname__}) is defined in a script or inside "
                       "a function, so a parameter set cannot refer to it; put it in an importable module and add "
                       "it as 'package.module:ClassName'")
    return f"{cls.__module__}:{cls.__qualname__}"


def fitted_parameter_set(base: ParameterSet, model: PlantModel, values: Mapping[str, float], name: str,
                         meta: Mapping[str, Any] | None = None) -> ParameterSet:
    """``base`` with fitted core values and every added effect (with all its parameter values) as ``[[effects]]``;
    loadable at once by :class:`PlantModel` (``shm run``, the board monitor)."""
    p = model.p_nominal.copy()
    for n, v in values.items():
        p[model.param_index(n)] = v
    core_changes = {n: float(p[model.param_index(n)]) for n in CORE_PARAMETER_NAMES
                    if float(p[model.param_index(n)]) != float(base.values[n])}
    new = base.with_values(name=name, **core_changes) if core_changes else base
    entries = []
    for cls in model.effects:
        if cls.role != "effect":
            continue
        own = cls.own_parameters()
        # an instance's parameters under their declared names: the entry names the instance ("x as prefix")
        entries.append(EffectEntry(effect_entry_name(cls),
                                   {cls.declared_name(q.name): float(p[model.param_index(q.name)]) for q in own},
                                   {cls.declared_name(q.name): q.unit for q in own}))
    merged_meta = dict(new.meta)
    merged_meta.update(meta or {})
    merged_meta["name"] = name
    return ParameterSet(name, new.values, new.details, tuple(entries), merged_meta, new.source)
