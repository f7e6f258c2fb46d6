"""The physical-effect seam.

The plant is a composition of *physical effects*. Each effect is a small class that declares

* ``name`` — a short identifier (``"bouc_wen"``), unique in a model;
* ``parameters`` — :class:`Parameter` objects (name, SI unit, default, bounds, description);
* ``states`` — extra states it adds (:class:`StateSpec`: name, unit, typical magnitude, initial value);
* ``outputs`` — extra output channels it adds (:class:`OutputSpec`);
* its contribution to the equations, as up to four *hooks* (plain functions that numba compiles):

  ``pre(t, x, p, bus, dx, so, po)``
      compute derived signals from the states into the bus (e.g. the hysteretic charge ``q_h``);
  ``rates(t, x, p, bus, dx, so, po)``
      add forces to the bus (``B_S`` section forces, ``B_FM`` forces on masses) and add to rates ``dx``;
  ``post(t, x, p, bus, dx, so, po)``
      work that needs the completed rates of other states (Bouc-Wen needs q̇, the mass chain needs
      every force);
  ``output(t, x, p, bus, y, so, po, yo)``
      write or modify output channels (``y``).

``x`` is the state vector, ``p`` the parameter vector, ``bus`` the signal bus (see :mod:`plant.layout`),
``dx`` the state-rate vector being assembled. ``so``/``po``/``yo`` are the offsets of *this effect's*
extra states, parameters and outputs. Core states, core parameters and bus slots have fixed indices
(:mod:`plant.layout`). Hooks run in model order within each phase: all ``pre``, then all ``rates``, then
all ``post``. Kernels must be numba-compilable (scalars, numpy arrays, math); a kernel that does not
compile is reported with the effect's name.

A user's own effect is loaded by dotted path, ``package.module:ClassName``, or from a file, ``path/to/file.py``
(the one effect class it defines) or ``path/to/file.py:ClassName``, through the same registry as the built-ins
(:func:`resolve_effect`). A file is imported under a module name derived from its absolute path
(:func:`load_effect_file`), so the composed kernel's cache key follows the file's content.
"""

from __future__ import annotations

import dataclasses
import hashlib
import importlib
import importlib.util
import os
import sys
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

from board_config.errors import InputError
from board_config.parameter import Parameter as OneParameter


class EffectError(InputError):
    """An effect is unknown, cannot be imported, or is ill-formed."""


@dataclass(frozen=True)
class Parameter(OneParameter):
    """A parameter of an effect: the one parameter type (:class:`board_config.parameter.Parameter`: name, SI unit,
    default, bounds, description, neutral value, fit range ...); its :meth:`check` raises :class:`EffectError`.
    ``core_index`` is set for the Table 2 parameters, which the core effects take from
    ``board_config.CORE_SCHEMA``."""

    error: ClassVar[type[InputError]] = EffectError

    @classmethod
    def of(cls, par: OneParameter) -> Parameter:
        """``par`` as an effect parameter (the same values; its check raises :class:`EffectError`)."""
        if isinstance(par, Parameter):
            return par
        return cls(**{f.name: getattr(par, f.name) for f in dataclasses.fields(par)})


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


Hook = Callable[..., None]


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
    #: What the effect's absence leaves in residuals (used by the workbench to explain a diagnosis).
    signature: ClassVar[str] = ""
    #: Physical origin, for the effects library documentation.
    origin: ClassVar[str] = ""

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
    def validate_class(cls) -> None:
        """Raise :class:`EffectError` when the class is ill-formed (checked at registration and load)."""
        label = f"effect {cls.__module__}.{cls.__qualname__}"
        if not isinstance(cls.name, str) or not cls.name.isidentifier():
            raise EffectError(f"{label}: 'name' must be a Python identifier, got {cls.name!r}")
        if cls.role not in ("core", "terminal", "effect"):
            raise EffectError(f"{label}: role must be core, terminal or effect, got {cls.role!r}")
        if all(getattr(cls, h) is None for h in ("pre", "rates", "post", "output")):
            raise EffectError(f"{label}: defines none of the hooks pre, rates, post, output")
        seen: set[str] = set()
        for par in cls.parameters:
            if not isinstance(par, OneParameter):
                raise EffectError(f"{label}: parameters must be Parameter objects, got {par!r}")
            if par.name in seen:
                raise EffectError(f"{label}: parameter '{par.name}' declared twice")
            seen.add(par.name)
            if par.core_index is None:
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


#: module attribute set on a module loaded from a file: the file's absolute path (how a parameter set refers to it)
SOURCE_FILE_ATTR = "__mfc_shm_effect_file__"


def is_file_spec(spec: str) -> bool:
    """True when ``spec`` names a Python file (``x.py``, ``dir/x.py:Class``) rather than a registered name or a
    dotted path."""
    path = spec.rsplit(":", 1)[0] if spec.count(":") and not spec.endswith(".py") else spec
    return path.endswith(".py") or os.sep in path or "/" in path


def load_effect_file(path: str | os.PathLike) -> Any:
    """Import the Python file ``path`` as a module (once per path and content; errors as :class:`EffectError`).

    The module name is ``_mfc_shm_effect_file_<stem>_<hash of the absolute path>`` and it is kept in
    ``sys.modules``, so effects defined there are importable by module path (the kernel generator imports them
    that way); a file whose content changed since it was loaded is imported afresh."""
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
    if old is not None and getattr(old, "__mfc_shm_digest__", None) == digest:
        return old
    spec = importlib.util.spec_from_file_location(name, p)
    if spec is None or spec.loader is None:
        raise EffectError(f"effect file '{path}' cannot be imported as a Python module")
    module = importlib.util.module_from_spec(spec)
    setattr(module, SOURCE_FILE_ATTR, p)
    module.__mfc_shm_digest__ = digest  # type: ignore[attr-defined]
    sys.modules[name] = module
    try:
        spec.loader.exec_module(module)
    except Exception as exc:
        sys.modules.pop(name, None)
        raise EffectError(f"cannot import effect file '{path}': {type(exc).__name__}: {exc}") from exc
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


def resolve_effect(spec: str | type[PhysicalEffect]) -> type[PhysicalEffect]:
    """An effect class from a registered name, a dotted path ``package.module:ClassName``, or a file
    ``path/to/file.py`` / ``path/to/file.py:ClassName``."""
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
