"""The physical-effect seam.

The plant is a composition of *physical effects*. Each effect is a small class that declares

* ``name`` — a short identifier (``"bouc_wen"``), unique in a model;
* ``parameters`` — :class:`Parameter` objects (name, SI unit, default, bounds, description);
* ``states`` — extra states it adds (:class:`StateSpec`: name, unit, typical magnitude, initial value);
* ``outputs`` — extra output channels it adds (:class:`OutputSpec`);
* ``signals`` — bus signals it publishes for other effects (:class:`SignalSpec`; the composer allocates their
  slots), and ``reads`` — the names of other effects' signals it reads;
* its contribution to the equations, as up to four *hooks* (plain functions that numba compiles):

  ``pre(t, x, p, bus, dx, X, P, B)``
      compute derived signals from the states into the bus (e.g. the hysteretic charge ``q_h``);
  ``rates(t, x, p, bus, dx, X, P, B)``
      add forces to the bus (section forces ``bus[B.s1]``, forces on masses ``bus[B.fm3]``) and add to rates ``dx``;
  ``post(t, x, p, bus, dx, X, P, B)``
      work that needs the completed rates of other states (Bouc-Wen needs q̇, the mass chain needs
      every force);
  ``output(t, x, p, bus, y, X, P, B, Y)``
      write or modify output channels (``y``).

``x`` is the state vector, ``p`` the parameter vector, ``bus`` the signal bus (see :mod:`plant.layout`),
``dx`` the state-rate vector being assembled, ``y`` the output vector. ``X``, ``P``, ``B`` and ``Y`` are this
effect's *slot tables* (:mod:`plant.composition`): named tuples of integer indices, constants in the compiled
kernel, that hold the core names (``X.delta1``, ``P.k3``, ``B.z3``, ``Y.z3_meas``) and the effect's own
(``P.kappa_nl``, ``X.w_creep11``, ``B.my_signal``, ``Y.my_output``) under the names the effect declared — also
when the effect is an instance with a prefix. Hooks run in model order within each phase: all ``pre``, then all
``rates``, then all ``post``. Kernels must be numba-compilable (scalars, numpy arrays, math); a kernel that does
not compile is reported with the effect's name.

The seam before the slot tables — ``rates(t, x, p, bus, dx, so, po)`` and ``output(t, x, p, bus, y, so, po, yo)``
with the effect's own states, parameters and outputs at ``x[so + k]``, ``p[po + k]``, ``y[yo + k]`` — still works
(the arity tells the two apart); such hooks cannot publish signals.

A user's own effect is loaded by dotted path, ``package.module:ClassName``, or from a file, ``path/to/file.py``
(the one effect class it defines) or ``path/to/file.py:ClassName``, through the same registry as the built-ins
(:func:`resolve_effect`). A file is imported under a module name derived from its absolute path
(:func:`load_effect_file`), so the composed kernel's cache key follows the file's content. Any of these specs
followed by ``as PREFIX`` (``"tip_mass as tip_mass_2"``) is an *instance* of the effect whose parameters, states,
outputs and signals are named ``PREFIX.name`` in the model, so two effects of one kind can coexist.

Library effects are registered by package (:func:`register_effect_package`): every effect class in every module
of ``plant/effects`` is registered on import, and those of role ``"effect"`` form the workbench's library
(:func:`library_effects`) — a new library effect is one file there.
"""

from __future__ import annotations

import dataclasses
import hashlib
import importlib
import importlib.util
import keyword
import math
import os
import pkgutil
import re
import sys
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

from board_config.parameter import FitRange
from board_config.parameter import Parameter as OneParameter
from plant.effect_declarations import (
    EffectError,
    Parameter,
    challenge_strengths,
    default_fit_names,
    legacy_table_problem,
    neutral_values,
    on_request_fit_names,
    parameter_problem,
)
from plant.effect_file_guard import guarded_import
from plant.effect_hooks import HOOKS as HOOKS
from plant.effect_hooks import Hook
from plant.effect_hooks import hook_function as hook_function
from plant.effect_hooks import hook_style as hook_style


@dataclass(frozen=True)
class StateSpec:
    """An extra state: name, SI unit, typical magnitude (sets the integrator's absolute tolerance), x0."""

    name: str
    unit: str
    scale: float
    initial: float = 0.0


@dataclass(frozen=True)
class OutputSpec:
    """An extra output channel with its SI unit."""

    name: str
    unit: str


@dataclass(frozen=True)
class SignalSpec:
    """A bus signal an effect publishes (the composer allocates its slot): name, SI unit, description."""

    name: str
    unit: str
    description: str = ""


def _renamed(spec: Any, name: str) -> Any:
    """A copy of a frozen declaration (parameter, state, output, signal) under another name."""
    if dataclasses.is_dataclass(spec) and not isinstance(spec, type):
        return dataclasses.replace(spec, name=name)
    import copy

    out = copy.copy(spec)
    object.__setattr__(out, "name", name)
    return out


class PhysicalEffect:
    """Base class of every physical effect (built-in or a user's own). See the module docstring."""

    name: ClassVar[str] = ""
    description: ClassVar[str] = ""
    #: "core" effects make up the nominal model; "terminal" decides the patch terminal voltage (exactly one
    #: per model); "effect" is anything added on top.
    role: ClassVar[str] = "effect"
    parameters: ClassVar[tuple[OneParameter, ...]] = ()
    states: ClassVar[tuple[StateSpec, ...]] = ()
    outputs: ClassVar[tuple[OutputSpec, ...]] = ()
    #: bus signals this effect publishes; each gets a slot from ``B_USER`` on, ``bus[B.name]`` in its hooks
    signals: ClassVar[tuple[SignalSpec, ...]] = ()
    #: names of signals other effects of the model publish that this effect reads (``bus[B.name]``; a prefixed
    #: publisher's ``prefix.name`` is ``B.prefix_name``)
    reads: ClassVar[tuple[str, ...]] = ()
    #: set on an instance made by :meth:`instance`: the prefix of its names and the class it is an instance of
    prefix: ClassVar[str] = ""
    instance_of: ClassVar[type[PhysicalEffect] | None] = None
    #: What the effect's absence leaves in residuals (used by the workbench to explain a diagnosis).
    signature: ClassVar[str] = ""
    #: Physical origin, for the effects library documentation.
    origin: ClassVar[str] = ""
    #: where the reports list a library effect (the eight of the seed study are 1..8; without one: after them)
    library_order: ClassVar[float] = math.inf
    #: a short column label for the hidden-effect challenge's confusion matrix ("": the effect's name)
    short_name: ClassVar[str] = ""

    pre: ClassVar[Hook | None] = None
    rates: ClassVar[Hook | None] = None
    post: ClassVar[Hook | None] = None
    output: ClassVar[Hook | None] = None

    @classmethod
    def guess(cls, data: Mapping[str, Any] | None = None) -> dict[str, float]:
        """A starting guess of the effect's own (non-core) parameters from data; defaults otherwise."""
        return {p.name: p.default for p in cls.parameters if p.core_index is None}

    @classmethod
    def own_parameters(cls) -> tuple[Parameter, ...]:
        return tuple(Parameter.of(p) for p in cls.parameters if p.core_index is None)

    @classmethod
    def fit_range(cls, name: str) -> FitRange:
        """The declared ``fit`` range of own parameter ``name`` (:class:`EffectError` when it declares none)."""
        par = next((p for p in cls.own_parameters() if p.name == name), None)
        if par is None or par.fit is None:
            raise EffectError(f"effect '{cls.name}': parameter '{name}' declares no fit range")
        return par.fit

    @classmethod
    def neutral_values(cls) -> dict[str, float]:
        """Own parameter values at which the effect leaves the model unchanged (their ``neutral``), by name."""
        return neutral_values(cls.own_parameters())

    @classmethod
    def default_fit_names(cls) -> tuple[str, ...]:
        """Own parameters the workbench fits by default (:func:`plant.effect_declarations.default_fit_names`)."""
        return default_fit_names(cls.own_parameters())

    @classmethod
    def on_request_fit_names(cls) -> tuple[str, ...]:
        """Own parameters with a declared fit range that are fitted only when asked (``fit_by_default=False``)."""
        return on_request_fit_names(cls.own_parameters())

    @classmethod
    def challenge_strengths(cls) -> tuple[dict[str, float], ...]:
        """(weak, medium, strong) values the hidden-effect challenge hides the effect at (its parameters'
        ``challenge``); () when it declares none."""
        return challenge_strengths(cls.own_parameters())

    @classmethod
    def declared_name(cls, name: str) -> str:
        """The name an effect declared for one of its (possibly prefixed) parameters, states, outputs, signals."""
        head = f"{cls.prefix}." if cls.prefix else ""
        return name[len(head):] if head and name.startswith(head) else name

    @classmethod
    def instance(cls, prefix: str) -> type[PhysicalEffect]:
        """This effect under the name ``prefix`` with its parameters, states, outputs and signals named
        ``prefix.name`` (the hooks keep using the declared names), so that two of a kind can coexist in a model."""
        base = cls.instance_of or cls
        if not isinstance(prefix, str) or not prefix.isidentifier() or keyword.iskeyword(prefix):
            raise EffectError(f"effect '{base.name}': instance prefix must be a Python identifier, got {prefix!r}")
        if prefix == base.name:
            return base
        key = (base, prefix)
        if key in _INSTANCES:
            return _INSTANCES[key]

        def pre(names: Mapping[str, Any]) -> dict[str, Any]:
            return {f"{prefix}.{k}": v for k, v in names.items()}

        def guess(sub: type[PhysicalEffect], data: Mapping[str, Any] | None = None) -> dict[str, float]:
            if data and isinstance(data.get("params"), Mapping):
                params = dict(data["params"])
                for par in base.own_parameters():
                    if f"{prefix}.{par.name}" in params:
                        params[par.name] = params[f"{prefix}.{par.name}"]
                data = {**data, "params": params}
            return pre(base.guess(data))

        attrs: dict[str, Any] = {
            "name": prefix, "prefix": prefix, "instance_of": base, "__module__": base.__module__,
            "description": f"{base.description} (instance '{prefix}' of '{base.name}')",
            "parameters": tuple(p if getattr(p, "core_index", None) is not None else _renamed(p, f"{prefix}.{p.name}")
                                for p in base.parameters),
            "states": tuple(_renamed(st, f"{prefix}.{st.name}") for st in base.states),
            "outputs": tuple(_renamed(o, f"{prefix}.{o.name}") for o in base.outputs),
            "signals": tuple(_renamed(sg, f"{prefix}.{sg.name}") for sg in base.signals),
            "guess": classmethod(guess),
        }
        sub: type[PhysicalEffect] = type(f"{base.__name__}_{prefix}", (base,), attrs)
        sub.__qualname__ = f"{base.__qualname__}_{prefix}"
        sub.validate_class()
        _INSTANCES[key] = sub
        return sub

    @classmethod
    def validate_class(cls) -> None:
        """Raise :class:`EffectError` when the class is ill-formed (checked at registration and load)."""
        source = effect_source_file(cls)
        label = f"effect '{cls.name}' in {source}" if source else f"effect {cls.__module__}.{cls.__qualname__}"
        if not isinstance(cls.name, str) or not cls.name.isidentifier():
            raise EffectError(f"{label}: 'name' must be a Python identifier, got {cls.name!r}")
        if cls.role not in ("core", "terminal", "effect"):
            raise EffectError(f"{label}: role must be core, terminal or effect, got {cls.role!r}")
        if (why := legacy_table_problem(cls)) is not None:
            raise EffectError(f"{label}: {why}")
        if all(getattr(cls, h) is None for h in HOOKS):
            raise EffectError(f"{label}: defines none of the hooks pre, rates, post, output")
        styles = {hook_style(cls, h) for h in HOOKS if getattr(cls, h) is not None}
        if (cls.signals or cls.reads) and styles != {"named"}:
            raise EffectError(f"{label}: declares signals or reads, so every hook must take the slot tables "
                              "(rates(t, x, p, bus, dx, X, P, B), output(t, x, p, bus, y, X, P, B, Y)) to find them "
                              "by name; the offsets form (so, po) has no way to reach an allocated signal")
        for sg in cls.signals:
            if not isinstance(sg, SignalSpec):
                raise EffectError(f"{label}: signals must be SignalSpec objects, got {sg!r}")
        for name in cls.reads:
            if not isinstance(name, str) or not name:
                raise EffectError(f"{label}: reads must be signal names, got {name!r}")
        seen: set[str] = set()
        for par in cls.parameters:
            if not isinstance(par, OneParameter):
                raise EffectError(f"{label}: parameters must be Parameter objects, got {par!r}")
            if par.name in seen:
                raise EffectError(f"{label}: parameter '{par.name}' declared twice")
            seen.add(par.name)
            if par.core_index is None:
                if (why := parameter_problem(par)) is not None:
                    raise EffectError(f"{label}: parameter '{par.name}': {why}")
                par.check(par.default, label)
        for st in cls.states:
            if not isinstance(st, StateSpec) or not st.scale > 0:
                raise EffectError(f"{label}: states must be StateSpec objects with a positive scale, got {st!r}")


def importable_by_path(cls: type) -> bool:
    """True when ``cls`` can be found again as ``package.module:QualName`` (not in ``__main__`` or a function)."""
    if cls.__module__ == "__main__" or "<locals>" in cls.__qualname__:
        return False
    try:
        obj: Any = importlib.import_module(cls.__module__)
        for part in cls.__qualname__.split("."):
            obj = getattr(obj, part)
    except Exception:  # any import-time failure means: not importable
        return False
    return obj is cls


_REGISTRY: dict[str, type[PhysicalEffect]] = {}
#: registered names that belong to the library (registered from a library package), in registration order
_LIBRARY: list[str] = []
_INSTANCES: dict[tuple[type, str], type[PhysicalEffect]] = {}


def register_effect(cls: type[PhysicalEffect]) -> type[PhysicalEffect]:
    """Class decorator: make an effect available by its short name."""
    cls.validate_class()
    if cls.name in _REGISTRY and _REGISTRY[cls.name] is not cls:
        raise EffectError(f"an effect named '{cls.name}' is already registered "
                          f"({_REGISTRY[cls.name].__module__}.{_REGISTRY[cls.name].__qualname__})")
    _REGISTRY[cls.name] = cls
    return cls


def registered_effects() -> dict[str, type[PhysicalEffect]]:
    """Short name -> class, for every registered effect (built-ins are registered on import of plant)."""
    return dict(_REGISTRY)


def unregister_effect(name: str) -> None:
    """Forget a registered effect (tests that register one of their own clean up with this)."""
    _REGISTRY.pop(name, None)
    if name in _LIBRARY:
        _LIBRARY.remove(name)


def register_effect_package(package: str, library: bool = False) -> list[type[PhysicalEffect]]:
    """Import every module of ``package`` (its ``__path__``, modules in name order, ``_private`` ones skipped) and
    register every effect class defined there; with ``library`` the registered ones of role ``"effect"`` join the
    library (:func:`library_effects`). Called again, it picks up modules added since (e.g. to ``__path__``)."""
    try:
        pkg = importlib.import_module(package)
    except Exception as exc:
        raise EffectError(f"cannot import effect package '{package}': {type(exc).__name__}: {exc}") from exc
    found: list[type[PhysicalEffect]] = []
    for info in sorted(pkgutil.iter_modules(getattr(pkg, "__path__", [])), key=lambda m: m.name):
        if info.name.startswith("_"):
            continue
        mod_name = f"{package}.{info.name}"
        try:
            module = importlib.import_module(mod_name)
        except Exception as exc:
            raise EffectError(f"cannot import effect module '{mod_name}': {type(exc).__name__}: {exc}") from exc
        for obj in vars(module).values():
            if (isinstance(obj, type) and issubclass(obj, PhysicalEffect) and obj.__module__ == mod_name
                    and obj.name and obj.instance_of is None):
                register_effect(obj)
                found.append(obj)
                if library and obj.role == "effect" and obj.name not in _LIBRARY:
                    _LIBRARY.append(obj.name)
    return found


def library_effects() -> tuple[str, ...]:
    """Names of the library effects (the workbench's default candidates), ordered by their ``library_order``
    (a typed class attribute of the effect; those without one last), then by registration."""
    names = [n for n in _LIBRARY if n in _REGISTRY]
    rank = {n: i for i, n in enumerate(names)}
    return tuple(sorted(names, key=lambda n: (_REGISTRY[n].library_order, rank[n])))


#: module attribute set on a module loaded from a file: the file's absolute path (how a parameter set refers to it)
SOURCE_FILE_ATTR = "__mfc_shm_effect_file__"
#: module attribute set on a module loaded from a file: the digest of its source (the kernel cache key reads it)
DIGEST_ATTR = "__mfc_shm_digest__"


def is_file_spec(spec: str) -> bool:
    """True when ``spec`` names a Python file (``x.py``, ``dir/x.py:Class``) rather than a registered name or a
    dotted path."""
    path = spec.rsplit(":", 1)[0] if spec.count(":") and not spec.endswith(".py") else spec
    return path.endswith(".py") or os.sep in path or "/" in path


def load_effect_file(path: str | os.PathLike) -> Any:
    """Import the Python file ``path`` as a module (once per path and content; errors, an exit or a print at import
    as :class:`EffectError`: :mod:`plant.effect_file_guard`). The module, ``_mfc_shm_effect_file_<stem>_<hash of
    the absolute path>``, is kept in ``sys.modules``, so effects defined there are importable by module path (the
    kernel generator imports them that way); a file whose content changed since it was loaded is imported afresh."""
    p = os.path.abspath(os.fspath(path))
    if not os.path.isfile(p):
        raise EffectError(f"effect file '{path}' does not exist (or is not a file)")
    try:
        with open(p, "rb") as fh:
            content = fh.read()
    except OSError as exc:
        raise EffectError(f"effect file '{path}' cannot be read: {exc}") from exc
    stem = "".join(c if c.isalnum() else "_" for c in os.path.splitext(os.path.basename(p))[0])
    name = f"_mfc_shm_effect_file_{stem}_{hashlib.sha256(p.encode()).hexdigest()[:10]}"
    digest = hashlib.sha256(content).hexdigest()
    old = sys.modules.get(name)
    if old is not None and getattr(old, DIGEST_ATTR, None) == digest:
        return old
    spec = importlib.util.spec_from_file_location(name, p)
    if spec is None or spec.loader is None:
        raise EffectError(f"effect file '{path}' cannot be imported as a Python module")
    module = importlib.util.module_from_spec(spec)
    vars(module).update({SOURCE_FILE_ATTR: p, DIGEST_ATTR: digest})
    sys.modules[name] = module
    loader = spec.loader
    try:  # sys.exit(), a BaseException or a print at import: one EffectError naming the file (issue 33)
        guarded_import(lambda: loader.exec_module(module), str(path), EffectError)
    except BaseException:
        sys.modules.pop(name, None)
        raise
    return module


def effect_source_file(cls: type) -> str | None:
    """The absolute path of the file ``cls`` was loaded from by :func:`load_effect_file`, else None."""
    mod = sys.modules.get(getattr(cls, "__module__", ""))
    return getattr(mod, SOURCE_FILE_ATTR, None) if mod is not None else None


def _resolve_file(spec: str) -> type[PhysicalEffect]:
    path, attr = spec, ""
    if not spec.endswith(".py") and ":" in spec:
        path, _, attr = spec.rpartition(":")
    module = load_effect_file(path)
    if attr:
        obj = getattr(module, attr, None)
        if obj is None:
            raise EffectError(f"effect file '{path}' defines no '{attr}'")
        if not isinstance(obj, type) or not issubclass(obj, PhysicalEffect):
            raise EffectError(f"'{spec}' is not a PhysicalEffect subclass (got {obj!r})")
        obj.validate_class()
        return obj
    found = [o for o in vars(module).values() if isinstance(o, type) and issubclass(o, PhysicalEffect)
             and o.__module__ == module.__name__]
    if len(found) != 1:
        names = ", ".join(o.__name__ for o in found) or "none"
        raise EffectError(f"effect file '{path}' must define exactly one PhysicalEffect class to be named by its "
                          f"path alone (found: {names}); name one as '{path}:ClassName'")
    found[0].validate_class()
    return found[0]


_INSTANCE_SPEC = re.compile(r"^(?P<spec>.*\S)\s+as\s+(?P<prefix>[A-Za-z_]\w*)\s*$")


def split_instance_spec(spec: str) -> tuple[str, str]:
    """``("tip_mass", "tip_mass_2")`` from ``"tip_mass as tip_mass_2"``; ``(spec, "")`` without ``as``."""
    m = _INSTANCE_SPEC.match(spec)
    return (m.group("spec"), m.group("prefix")) if m else (spec, "")


def resolve_effect(spec: str | type[PhysicalEffect]) -> type[PhysicalEffect]:
    """An effect class from a registered name, a dotted path ``package.module:ClassName``, or a file
    ``path/to/file.py`` / ``path/to/file.py:ClassName``; any of them followed by ``as PREFIX`` gives an instance
    with prefixed names (:meth:`PhysicalEffect.instance`)."""
    if isinstance(spec, str):
        inner, prefix = split_instance_spec(spec)
        if prefix:
            return resolve_effect(inner).instance(prefix)
    if isinstance(spec, type):
        if not issubclass(spec, PhysicalEffect):
            raise EffectError(f"{spec!r} is not a PhysicalEffect subclass")
        spec.validate_class()
        return spec
    if not isinstance(spec, str) or not spec:
        raise EffectError(f"effect must be a name or 'package.module:ClassName', got {spec!r}")
    if is_file_spec(spec):
        return _resolve_file(spec)
    if ":" not in spec:
        try:
            return _REGISTRY[spec]
        except KeyError:
            known = ", ".join(sorted(_REGISTRY))
            raise EffectError(f"unknown effect '{spec}' (registered: {known}; or give a dotted path "
                              "'package.module:ClassName' or a file 'path/to/effect.py')") from None
    module_name, _, attr = spec.partition(":")
    try:
        module = importlib.import_module(module_name)
    except Exception as exc:
        raise EffectError(f"cannot import module '{module_name}' for effect '{spec}': "
                          f"{type(exc).__name__}: {exc}") from exc
    obj: Any = module
    for part in attr.split("."):
        try:
            obj = getattr(obj, part)
        except AttributeError:
            raise EffectError(f"module '{module_name}' has no attribute '{attr}' (effect '{spec}')") from None
    if not isinstance(obj, type) or not issubclass(obj, PhysicalEffect):
        raise EffectError(f"'{spec}' is not a PhysicalEffect subclass (got {obj!r})")
    obj.validate_class()
    return obj
