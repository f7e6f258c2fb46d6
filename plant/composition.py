"""The layout of a composed model: where each effect's states, parameters, outputs and signals live.

:func:`build_composition` lays the effects out in model order — the core blocks of :mod:`plant.layout` first, then
each effect's own states, parameters and outputs in declaration order — and allocates a bus slot from
``B_USER`` on to every signal an effect publishes. Each effect gets four *slot tables* (named tuples of integer
indices, compiled into the kernel as constants): ``X`` (states), ``P`` (parameters), ``B`` (bus signals) and ``Y``
(outputs), holding the core names and the effect's own under the names it declared, so a hook reads
``p[P.kappa_nl]`` and ``bus[B.fm3]`` instead of ``p[po + 0]`` and ``bus[B_FM + 2]``.
"""

from __future__ import annotations

import inspect
import keyword
from collections import namedtuple
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from board_config import CORE_PARAMETER_NAMES
from plant import layout as L
from plant.effect import OutputSpec, PhysicalEffect, SignalSpec, StateSpec
from plant.effect_declarations import EffectError, Parameter
from plant.effect_hooks import HOOKS, hook_function, hook_style

_TABLE_TYPES: dict[tuple[str, tuple[str, ...]], type] = {}


def slot_table(kind: str, names: Sequence[str], values: Sequence[int]) -> Any:
    """A named tuple ``kind(name=index, ...)`` (one class per kind and field names)."""
    fields = tuple(names)
    table_type = _TABLE_TYPES.get((kind, fields))
    if table_type is None:
        make: Any = namedtuple  # a named tuple class made at run time (numba types it as a tuple of ints)
        table_type = make(kind, fields)
        _TABLE_TYPES[(kind, fields)] = table_type
    return table_type(*(int(v) for v in values))


@dataclass(frozen=True)
class EffectSlots:
    """Where one effect's own blocks start, and its slot tables (None when no hook uses them)."""

    state_offset: int
    param_offset: int
    output_offset: int
    tables: dict[str, dict[str, int]] | None  # kind ("X", "P", "B", "Y") -> name -> index
    styles: dict[str, str]  # hook -> "named" | "offsets"

    def table(self, kind: str) -> Any:
        assert self.tables is not None
        names = self.tables[kind]
        return slot_table(kind, tuple(names), tuple(names.values()))

    def hook_args(self, hook: str) -> tuple[Any, ...]:
        """The arguments after ``(t, x, p, bus, dx|y)`` this effect's ``hook`` takes."""
        if self.styles[hook] == "offsets":
            head = (self.state_offset, self.param_offset)
            return (*head, self.output_offset) if hook == "output" else head
        kinds = ("X", "P", "B", "Y") if hook == "output" else ("X", "P", "B")
        return tuple(self.table(k) for k in kinds)


@dataclass(frozen=True)
class Composition:
    """Effects in model order with their slots; the model's extra states, parameters, outputs and signals."""

    effects: tuple[type[PhysicalEffect], ...]
    slots: tuple[EffectSlots, ...]
    states: tuple[StateSpec, ...]
    parameters: tuple[Parameter, ...]
    outputs: tuple[OutputSpec, ...]
    signals: dict[str, int]  # model-level signal name -> bus slot
    owner: dict[str, str]  # parameter name -> effect name ("core" for the core parameters)

    @property
    def offsets(self) -> tuple[tuple[int, ...], tuple[int, ...], tuple[int, ...]]:
        return (tuple(s.state_offset for s in self.slots), tuple(s.param_offset for s in self.slots),
                tuple(s.output_offset for s in self.slots))

    def hook_args(self, k: int, hook: str) -> tuple[Any, ...]:
        return self.slots[k].hook_args(hook)

    @property
    def bus_names(self) -> dict[int, str]:
        """Bus slot -> name: the core signals and the allocated ones."""
        return {**L.BUS_NAMES, **{i: n for n, i in self.signals.items()}}


def _field(name: str) -> str:
    return name.replace(".", "_")


def _check_field(cls: type[PhysicalEffect], kind: str, name: str, table: dict[str, int], what: str) -> None:
    if not name.isidentifier() or keyword.iskeyword(name) or name.startswith("_"):
        raise EffectError(f"effect '{cls.name}': {what} '{name}' cannot be used as a slot name ({kind}.{name}): "
                          "use an identifier that does not start with '_' and is not a Python keyword")
    if name in table:
        raise EffectError(f"effect '{cls.name}': {what} '{name}' has the name of another entry of its slot table "
                          f"{kind} (core names: {kind}.{name} is taken); rename it")


def _uses_user_slots_by_hand(cls: type[PhysicalEffect]) -> bool:
    for hook in HOOKS:
        fn = hook_function(cls, hook)
        if fn is None:
            continue
        try:
            if "B_USER" in inspect.getsource(fn):
                return True
        except (OSError, TypeError):
            continue
    return False


def build_composition(classes: Sequence[type[PhysicalEffect]]) -> Composition:
    """Lay out ``classes`` (model order) and allocate their signals; errors name the effects involved."""
    states: list[StateSpec] = []
    params: list[Parameter] = []
    outputs: list[OutputSpec] = []
    owner: dict[str, str] = {n: "core" for n in CORE_PARAMETER_NAMES}
    offsets = []
    for c in classes:
        offsets.append((L.N_CORE_STATES + len(states), L.N_CORE_PARAMS + len(params),
                        L.N_CORE_OUTPUTS + len(outputs)))
        states.extend(c.states)
        for par in c.own_parameters():
            if par.name in owner:
                raise EffectError(f"parameter '{par.name}' of effect '{c.name}' clashes with one of "
                                  f"'{owner[par.name]}'")
            owner[par.name] = c.name
            params.append(par)
        outputs.extend(c.outputs)

    # signals: one bus slot each, from B_USER on
    signals: dict[str, int] = {}
    publisher: dict[str, str] = {}
    core_bus = set(L.BUS_NAMES.values())
    for c in classes:
        for sg in c.signals:
            if sg.name in core_bus or sg.name in signals:
                raise EffectError(f"effect '{c.name}' publishes signal '{sg.name}', which "
                                  + ("is a core bus signal" if sg.name in core_bus else
                                     f"effect '{publisher[sg.name]}' publishes too") + "; rename it")
            signals[sg.name] = L.B_USER + len(signals)
            publisher[sg.name] = c.name
    if len(signals) > L.N_BUS - L.B_USER:
        per_effect = "; ".join(f"{c.name}: {', '.join(sg.name for sg in c.signals)}" for c in classes if c.signals)
        raise EffectError(f"the effects publish {len(signals)} bus signals ({per_effect}) but the bus has "
                          f"{L.N_BUS - L.B_USER} slots for them (plant.layout B_USER..N_BUS-1); drop an effect or "
                          "publish fewer signals")
    if signals:
        by_hand = [c.name for c in classes if _uses_user_slots_by_hand(c)]
        if by_hand:
            raise EffectError(f"effect(s) {', '.join(by_hand)} write bus slots from B_USER by hand, which the "
                              f"composer now allocates to the signals of {', '.join(sorted(set(publisher.values())))};"
                              " declare the signal instead (signals = (SignalSpec('name', 'unit'),)) and use "
                              "bus[B.name] in hooks written as rates(t, x, p, bus, dx, X, P, B) (docs/effects.md)")

    slots = []
    for c, (so, po, yo) in zip(classes, offsets):
        styles = {h: hook_style(c, h) for h in HOOKS if getattr(c, h) is not None}
        tables = None
        if "named" in styles.values():
            tables = _tables(c, so, po, yo, signals)
        slots.append(EffectSlots(so, po, yo, tables, styles))
    return Composition(tuple(classes), tuple(slots), tuple(states), tuple(params), tuple(outputs), signals, owner)


def _tables(c: type[PhysicalEffect], so: int, po: int, yo: int, signals: dict[str, int]
            ) -> dict[str, dict[str, int]]:
    x = dict(zip(L.CORE_STATE_NAMES, range(L.N_CORE_STATES)))
    p = dict(zip(CORE_PARAMETER_NAMES, range(L.N_CORE_PARAMS)))
    b = {n: i for i, n in L.BUS_NAMES.items()}
    y = dict(zip(L.CORE_OUTPUT_NAMES, range(L.N_CORE_OUTPUTS)))
    for j, st in enumerate(c.states):
        name = c.declared_name(st.name)
        _check_field(c, "X", name, x, "state")
        x[name] = so + j
    for j, par in enumerate(c.own_parameters()):
        name = c.declared_name(par.name)
        _check_field(c, "P", name, p, "parameter")
        p[name] = po + j
    for j, out in enumerate(c.outputs):
        name = c.declared_name(out.name)
        _check_field(c, "Y", name, y, "output")
        y[name] = yo + j
    for sg in c.signals:
        name = c.declared_name(sg.name)
        _check_field(c, "B", name, b, "signal")
        b[name] = signals[sg.name]
    for name in c.reads:
        if name not in signals:
            known = ", ".join(signals) or "none"
            raise EffectError(f"effect '{c.name}' reads signal '{name}', which no effect of the model publishes "
                              f"(published: {known})")
        field = _field(name)
        if field not in b:
            _check_field(c, "B", field, b, "read signal")
            b[field] = signals[name]
    return {"X": x, "P": p, "B": b, "Y": y}


__all__ = ["Composition", "EffectSlots", "SignalSpec", "build_composition", "slot_table"]
