"""The candidate effects the workbench tries, and which of an effect's parameters it fits, over which range.

The library is the registry's (:func:`plant.effect.library_effects`: every effect of role ``"effect"`` in a file
of ``plant/effects``, ordered by ``library_order``); :data:`LIBRARY` reads it each time it is used, so there is no
list to edit here when an effect joins.

An effect gives a parameter its ``fit`` range (and ``neutral`` value) where the parameter is declared
(:class:`plant.effect.Parameter`); those with a range are fitted by default unless ``fit_by_default=False``
(:meth:`~plant.effect.PhysicalEffect.default_fit_names`). A user's own effect usually declares none: then every own
parameter is free over its declared bounds (infinite bounds are replaced by a range around the default), linear,
unless the bounds span more than three decades on the positive side (log).
Core parameters (Table 2) can be freed too (``--free k3`` or ``--free k3:10:40``): default range a factor of
three around the current value (log), or ±1 around a value of zero (linear).

A freed parameter is the one parameter type (:class:`board_config.parameter.Parameter`) with ``vary`` set: its
``lower``/``upper`` are the search range and its ``fit`` the scaling (:meth:`~board_config.parameter.Parameter.free`).
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping, Sequence
from typing import overload

import numpy as np

from board_config import CORE_PARAMETER_NAMES
from board_config.parameter import Parameter, freed
from plant import PhysicalEffect, PlantModel, resolve_effect
from plant.effect import EffectError, library_effects


class LibraryNames(Sequence[str]):
    """The names of the library effects, in the order the reports list them, read from the registry on every
    use (an effect registered later is in it)."""

    def _names(self) -> tuple[str, ...]:
        return library_effects()

    @overload
    def __getitem__(self, index: int) -> str: ...

    @overload
    def __getitem__(self, index: slice) -> tuple[str, ...]: ...

    def __getitem__(self, index: int | slice) -> str | tuple[str, ...]:
        return self._names()[index]

    def __len__(self) -> int:
        return len(self._names())

    def __iter__(self) -> Iterator[str]:
        return iter(self._names())

    def __contains__(self, name: object) -> bool:
        return name in self._names()

    def __repr__(self) -> str:
        return f"LibraryNames{self._names()!r}"


#: the effects library, in the order the reports list them (live view of the registry)
LIBRARY: Sequence[str] = LibraryNames()


def resolve_candidates(specs: Sequence[str | type[PhysicalEffect]]) -> list[type[PhysicalEffect]]:
    """Effect classes from names / dotted paths; the errors name the offending entry."""
    out: list[type[PhysicalEffect]] = []
    for spec in specs:
        cls = resolve_effect(spec)
        if cls.role != "effect":
            raise EffectError(f"'{cls.name}' is a {cls.role} effect, not a candidate that can be added "
                              "(terminals are chosen by the record's 'terminal' metadata)")
        if not cls.own_parameters():
            raise EffectError(f"effect '{cls.name}' has no parameters of its own: nothing to fit")
        if cls not in out:
            out.append(cls)
    return out


def effect_free_parameters(cls: type[PhysicalEffect], names: Sequence[str] | None = None) -> list[Parameter]:
    """The parameters of ``cls`` the workbench fits by default (or ``names``), with their ranges."""
    own = {p.name: p for p in cls.own_parameters()}
    chosen = list(names) if names is not None else list(cls.default_fit_names())
    out = []
    for n in chosen:
        par = own.get(n)
        if par is None:
            raise EffectError(f"effect '{cls.name}' has no parameter '{n}' (parameters: {', '.join(own)})")
        out.append(par.free(owner=cls.name))  # its declared fit range, else one from its bounds
    return out


def core_free_parameter(model: PlantModel, spec: str) -> Parameter:
    """A freed core (or any model) parameter from ``name`` or ``name:lower:upper`` (SI)."""
    name, _, rest = spec.partition(":")
    try:
        idx = model.param_index(name)
    except KeyError as exc:
        raise EffectError(str(exc.args[0])) from None
    unit = model.param_units[idx]
    value = float(model.p_nominal[idx])
    owner = "core" if name in CORE_PARAMETER_NAMES else next(
        (c.name for c in model.effects if any(p.name == name for p in c.own_parameters())), "core")
    if rest:
        parts = rest.split(":")
        try:
            lo, hi = float(parts[0]), float(parts[1])
            if len(parts) != 2:
                raise ValueError
        except (ValueError, IndexError):
            raise EffectError(f"--free '{spec}': expected NAME or NAME:LOWER:UPPER (SI units, {unit})") from None
        log = lo > 0 and hi / lo > 1e2
        return freed(name, unit, lo, hi, log, owner)
    if owner != "core":
        cls = next(c for c in model.effects if c.name == owner)
        fp = effect_free_parameters(cls, [name])[0]
        return fp
    if value > 0:
        return freed(name, unit, value / 3.0, value * 3.0, True, owner)
    if value < 0:
        return freed(name, unit, value * 3.0, value / 3.0, False, owner)
    return freed(name, unit, -1.0, 1.0, False, owner)


def guess_values(cls: type[PhysicalEffect], data: Mapping | None, free: Sequence[Parameter]) -> dict[str, float]:
    """The effect's ``guess(data)`` restricted to ``free`` and clipped into their ranges (a parameter the guess
    leaves out starts mid-range). A guess that raises, returns something other than a mapping, or gives a
    parameter a value that is not one finite number is an :class:`EffectError` naming the effect and the key."""
    try:
        raw = cls.guess(data)
    except Exception as exc:
        raise EffectError(f"effect '{cls.name}': guess() raised {type(exc).__name__}: {exc}") from exc
    if not isinstance(raw, Mapping):
        raise EffectError(f"effect '{cls.name}': guess() must return a mapping parameter name -> value, got "
                          f"{type(raw).__name__}")
    own = {p.name for p in cls.own_parameters()}
    unknown = sorted(set(raw) - own)
    if unknown:
        raise EffectError(f"effect '{cls.name}': guess() returned '{unknown[0]}', which is not one of its parameters "
                          f"({', '.join(sorted(own))})")
    out = {}
    for fp in free:
        if fp.name not in raw:
            out[fp.name] = float(fp.from_unit(0.5))
            continue
        v = raw[fp.name]
        if np.ndim(v) != 0:
            raise EffectError(f"effect '{cls.name}': guess() gave '{fp.name}' a value of shape {np.shape(v)}; "
                              "expected one number")
        try:
            v = float(v)
        except (TypeError, ValueError):
            raise EffectError(f"effect '{cls.name}': guess() gave '{fp.name}' = {v!r}; expected a number") from None
        if not math.isfinite(v):
            raise EffectError(f"effect '{cls.name}': guess() gave '{fp.name}' = {v!r}; expected a finite number")
        out[fp.name] = float(np.clip(v, fp.lower, fp.upper))
    return out
