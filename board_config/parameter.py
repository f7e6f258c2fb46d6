"""The one parameter type, its fit range, and a named parameter vector with relative deviations.

A :class:`Parameter` keeps in one object what lmfit's ``Parameter`` keeps: a name, its SI unit, a value (``default``),
physical bounds (``lower``/``upper``, strict with ``lower_open``/``upper_open``), the value at which an added effect
leaves the model unchanged (``neutral``), where a fit searches it (``fit``, a :class:`FitRange`) and whether a fit
varies it (``vary``), with a description and, for the seventeen Table 2 parameters, their index in the core
parameter block (``core_index``). The same type serves the configuration (the core schema of
:mod:`board_config.parameter_sets`), the plant's effects (``plant.effect.Parameter``), the workbench's fits (a
freed parameter, :meth:`Parameter.free`) and truth deviations.

A :class:`ParameterVector` is a model's parameters with their current values, by name. Its
:meth:`~ParameterVector.with_deviations` is the one place a relative deviation (``truth = nominal × (1 + d)``) is
applied and validated: the deviation must be a finite number in :data:`DEVIATION_RANGE` (:func:`deviation_problem`,
which parsers of scenario files and command-line flags call to refuse a bad deviation early) and the deviated value
must stay inside the parameter's bounds.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass
from typing import Any, ClassVar, cast

import numpy as np

from board_config.errors import InputError
from board_config.quantities import QuantitySpec

#: accepted relative deviations d (truth = nominal × (1 + d)), closed interval
DEVIATION_RANGE: tuple[float, float] = (-0.95, 5.0)


class ParameterError(InputError):
    """A parameter's value, bounds, fit range or deviation is wrong; the message names the parameter and where the
    value came from. ``where``, ``name`` and ``reason`` are kept apart for callers that report in their own terms
    (a configuration file's key)."""

    def __init__(self, message: str, *, where: str = "", name: str = "", reason: str = "") -> None:
        super().__init__(message)
        self.where, self.name, self.reason = where, name, reason or message

    @classmethod
    def at(cls, where: str, name: str, reason: str) -> ParameterError:
        return cls(f"{where}: {reason}", where=where, name=name, reason=reason)


def deviation_problem(name: str, deviation: Any) -> str | None:
    """Why ``deviation`` is not an acceptable relative deviation of parameter ``name`` (None when it is).

    The one rule for relative deviations: a finite number in :data:`DEVIATION_RANGE`."""
    if isinstance(deviation, bool) or not isinstance(deviation, (int, float, np.floating, np.integer)):
        return f"relative deviation of '{name}' must be a number, got {deviation!r}"
    d = float(deviation)
    lo, hi = DEVIATION_RANGE
    if not math.isfinite(d) or not lo <= d <= hi:
        return (f"relative deviation {d:g} of '{name}' (truth {name} × {1.0 + d:g}) outside the allowed range "
                f"[{lo:g}, {hi:g}]")
    return None


@dataclass(frozen=True)
class FitRange:
    """Where a fit searches a parameter: ``[lower, upper]`` in SI units, and how it scales the search.

    The optimiser works in the unit box: ``u = 0`` at ``lower``, ``u = 1`` at ``upper``; linear in the value by
    default, in log10 of the value (``log``: scale parameters that span decades; the interval must be positive), or
    in asinh(value/linthresh) (``linthresh``: symmetric-log, for a parameter whose neutral value is 0 and whose
    plausible magnitudes span decades: linear within ±linthresh, logarithmic beyond, either sign).
    """

    lower: float
    upper: float
    log: bool = False
    linthresh: float | None = None

    def __post_init__(self) -> None:
        if not (math.isfinite(self.lower) and math.isfinite(self.upper) and self.lower < self.upper):
            raise ParameterError(f"FitRange needs finite lower < upper, got [{self.lower}, {self.upper}]")
        if self.log and self.lower <= 0:
            raise ParameterError(f"a logarithmic FitRange needs a positive lower bound, got {self.lower}")
        if self.linthresh is not None and (self.log or not self.linthresh > 0):
            raise ParameterError(f"a symmetric-log FitRange needs linthresh > 0 and log=False, got {self.linthresh}")

    def clip(self, value: float) -> float:
        return float(min(max(value, self.lower), self.upper))

    def _ends(self) -> tuple[float, float]:
        if self.log:
            return math.log10(self.lower), math.log10(self.upper)
        if self.linthresh is not None:
            return math.asinh(self.lower / self.linthresh), math.asinh(self.upper / self.linthresh)
        return self.lower, self.upper

    def to_unit(self, value: float | np.ndarray) -> np.ndarray:
        """The unit-box coordinate of ``value`` (clipped into the range)."""
        v = np.clip(np.asarray(value, float), self.lower, self.upper)
        a, b = self._ends()
        if self.log:
            s = np.log10(v)
        elif self.linthresh is not None:
            s = np.arcsinh(v / self.linthresh)
        else:
            s = v
        # clipped again: on a narrow log range the rounding of log10 alone can land 1e-10 outside [0, 1], which an
        # optimiser bounded to the unit box refuses as an infeasible start
        return cast(np.ndarray, np.clip((s - a) / (b - a), 0.0, 1.0))

    def from_unit(self, u: float | np.ndarray) -> np.ndarray:
        """The value at unit-box coordinate ``u`` (clipped into [0, 1])."""
        a, b = self._ends()
        s = a + np.clip(np.asarray(u, float), 0.0, 1.0) * (b - a)
        if self.log:
            return cast(np.ndarray, np.clip(10.0 ** s, self.lower, self.upper))
        if self.linthresh is not None:
            return cast(np.ndarray, np.clip(self.linthresh * np.sinh(s), self.lower, self.upper))
        return cast(np.ndarray, s)

    def dvalue_du(self, value: float) -> float:
        """d(value)/du at ``value`` (for turning Jacobians in the unit box into SI)."""
        a, b = self._ends()
        if self.log:
            return float(value) * math.log(10.0) * (b - a)
        if self.linthresh is not None:
            return self.linthresh * math.cosh(math.asinh(float(value) / self.linthresh)) * (b - a)
        return b - a

    def describe_scale(self) -> str:
        return " (log)" if self.log else (f" (symlog, linear within ±{self.linthresh:g})" if self.linthresh else "")


@dataclass(frozen=True)
class Parameter:
    """One model parameter (see the module docstring). Positional order ``name, unit, default, lower, upper,
    description, core_index`` is the effect seam's; the rest are keywords.

    ``default`` is NaN for the Table 2 parameters: their values come from a parameter set (``table2.toml``)."""

    name: str
    unit: str
    default: float = math.nan
    lower: float = -math.inf
    upper: float = math.inf
    description: str = ""
    core_index: int | None = None
    lower_open: bool = False
    upper_open: bool = False
    neutral: float | None = None
    fit: FitRange | None = None
    vary: bool = False
    owner: str = "core"

    #: the error :meth:`check` raises (the plant's effect seam raises its ``EffectError``)
    error: ClassVar[type[InputError]] = ParameterError

    # --- values and bounds ---------------------------------------------------------------------------------------
    @property
    def value(self) -> float:
        """The parameter's value (lmfit's name for ``default``)."""
        return self.default

    def describe_range(self) -> str:
        lo = "(-inf" if self.lower == -math.inf else ("(" if self.lower_open else "[") + f"{self.lower:g}"
        hi = "+inf)" if self.upper == math.inf else f"{self.upper:g}" + (")" if self.upper_open else "]")
        return f"{lo}, {hi}"

    def in_bounds(self, value: float) -> bool:
        if not math.isfinite(value):
            return False
        if value < self.lower or (self.lower_open and value == self.lower):
            return False
        return not (value > self.upper or (self.upper_open and value == self.upper))

    def check(self, value: float, where: str) -> float:
        """``value`` as a float when it is finite and inside the bounds, else :attr:`error` naming ``where``."""
        value = float(value)
        if not math.isfinite(value):
            raise self.error(f"{where}: parameter '{self.name}' must be finite, got {value!r}")
        if not self.in_bounds(value):
            raise self.error(f"{where}: parameter '{self.name}' = {value!r} {self.unit} outside its bounds "
                             f"{self.describe_range()} {self.unit}")
        return value

    @property
    def quantity(self) -> QuantitySpec:
        """What a TOML quantity table of this parameter must hold (unit and bounds)."""
        return QuantitySpec(self.unit, lower=None if self.lower == -math.inf else self.lower,
                            upper=None if self.upper == math.inf else self.upper,
                            lower_open=self.lower_open, upper_open=self.upper_open)

    def with_value(self, value: float) -> Parameter:
        return dataclasses.replace(self, default=float(value))

    # --- fitting ---------------------------------------------------------------------------------------------------
    def auto_range(self) -> FitRange:
        """A search range from the bounds when no ``fit`` range is declared: infinite bounds are replaced by ten
        times max(|default|, 1) around the default; logarithmic when the bounds span more than three decades on the
        positive side."""
        default = 0.0 if math.isnan(self.default) else self.default
        lo, hi = self.lower, self.upper
        scale = max(abs(default), 1.0)
        if not math.isfinite(lo):
            lo = default - 10.0 * scale
        if not math.isfinite(hi):
            hi = default + 10.0 * scale
        return FitRange(lo, hi, lo > 0 and hi / lo > 1e3)

    def free(self, lower: float | None = None, upper: float | None = None, *, log: bool | None = None,
             linthresh: float | None = None, owner: str | None = None) -> Parameter:
        """This parameter varied by a fit over ``[lower, upper]`` (default: its declared ``fit`` range, else
        :meth:`auto_range`). As in lmfit, a varied parameter's ``lower``/``upper`` are the bounds the fit
        respects: its search range (closed)."""
        base = self.fit if self.fit is not None else self.auto_range()
        if lower is None and upper is None and log is None and linthresh is None:
            rng = base
        else:
            lo = base.lower if lower is None else float(lower)
            hi = base.upper if upper is None else float(upper)
            if log is None and linthresh is None:  # a new interval, the declared scaling
                log, linthresh = base.log, base.linthresh
            try:
                rng = FitRange(lo, hi, bool(log), linthresh)
            except ParameterError as exc:
                raise ParameterError(f"parameter '{self.name}' ({self.unit}): {exc}", name=self.name,
                                     reason=str(exc)) from None
        return dataclasses.replace(self, lower=rng.lower, upper=rng.upper, lower_open=False, upper_open=False,
                                   fit=rng, vary=True, owner=self.owner if owner is None else owner)

    def fixed(self) -> Parameter:
        return dataclasses.replace(self, vary=False)

    @property
    def fit_range(self) -> FitRange:
        """The declared or freed search range (a :class:`ParameterError` when there is none)."""
        if self.fit is None:
            raise ParameterError(f"parameter '{self.name}' has no fit range (free it first)", name=self.name)
        return self.fit

    @property
    def log(self) -> bool:
        """Whether a fit searches this parameter in log10 of its value."""
        return self.fit is not None and self.fit.log

    @property
    def linthresh(self) -> float | None:
        """The linear threshold of a symmetric-log search (None: not symmetric-log)."""
        return None if self.fit is None else self.fit.linthresh

    def to_unit(self, value: float | np.ndarray) -> np.ndarray:
        return self.fit_range.to_unit(value)

    def from_unit(self, u: float | np.ndarray) -> np.ndarray:
        return self.fit_range.from_unit(u)

    def dvalue_du(self, value: float) -> float:
        return self.fit_range.dvalue_du(value)

    def describe(self) -> str:
        """``k3 in [7, 64] N/m (log)`` for a parameter with a fit range, ``k3 = 21.28 N/m`` otherwise."""
        if self.fit is None:
            return f"{self.name} = {self.default:g} {self.unit}"
        return f"{self.name} in [{self.fit.lower:g}, {self.fit.upper:g}] {self.unit}{self.fit.describe_scale()}"


def freed(name: str, unit: str, lower: float, upper: float, log: bool = False, owner: str = "core",
          linthresh: float | None = None) -> Parameter:
    """A parameter known only by name and unit, varied by a fit over ``[lower, upper]`` (the workbench's discovery
    terms and explicit ``--free NAME:LOWER:UPPER`` ranges)."""
    return Parameter(name, unit, owner=owner).free(lower, upper, log=log, linthresh=linthresh)


@dataclass(frozen=True)
class ParameterVector:
    """A model's parameters and their values, by name (the order is the model's parameter vector)."""

    parameters: tuple[Parameter, ...]
    values: tuple[float, ...]
    _index: dict[str, int] = dataclasses.field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if len(self.parameters) != len(self.values):
            raise ParameterError(f"{len(self.parameters)} parameters but {len(self.values)} values")
        object.__setattr__(self, "_index", {p.name: i for i, p in enumerate(self.parameters)})

    @classmethod
    def of(cls, parameters: Iterable[Parameter], values: Iterable[float] | None = None) -> ParameterVector:
        """From parameters and their values (default: each parameter's own ``default``)."""
        pars = tuple(parameters)
        vals = tuple(float(v) for v in (values if values is not None else (p.default for p in pars)))
        return cls(pars, vals)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.parameters)

    def index(self, name: str) -> int:
        try:
            return self._index[name]
        except KeyError:
            raise KeyError(f"no such model parameter '{name}' (known: {', '.join(self.names)})") from None

    def parameter(self, name: str) -> Parameter:
        return self.parameters[self.index(name)]

    def __getitem__(self, name: str) -> float:
        return self.values[self.index(name)]

    def __contains__(self, name: object) -> bool:
        return name in self._index

    def __iter__(self) -> Iterator[str]:
        return iter(self.names)

    def __len__(self) -> int:
        return len(self.parameters)

    def as_dict(self) -> dict[str, float]:
        return dict(zip(self.names, self.values))

    def array(self) -> np.ndarray:
        return np.array(self.values, dtype=float)

    def with_values(self, values: Mapping[str, float], where: str) -> ParameterVector:
        """A copy with some values replaced, each checked against its parameter's bounds."""
        new = list(self.values)
        for name, value in values.items():
            i = self._lookup(name, where)
            new[i] = self.parameters[i].check(value, where)
        return ParameterVector(self.parameters, tuple(new))

    def with_deviations(self, deviations: Mapping[str, float], where: str) -> ParameterVector:
        """A copy with ``value × (1 + d)`` for each relative deviation ``d`` — the one place a deviation is
        validated. ``where`` says where the deviations came from (``scenario.toml: rig.deviations``,
        ``--deviation``); a :class:`ParameterError` names it, the parameter and the reason: an unknown parameter, a
        deviation outside :data:`DEVIATION_RANGE`, or a deviated value outside the parameter's bounds."""
        new = list(self.values)
        for name, d in deviations.items():
            i = self._lookup(name, where)
            reason = deviation_problem(name, d)
            if reason is not None:
                raise ParameterError.at(where, name, reason)
            par, value = self.parameters[i], new[i] * (1.0 + float(d))
            if not par.in_bounds(value):
                raise ParameterError.at(where, name, f"relative deviation {float(d):g} of '{name}' gives {name} = "
                                        f"{value:g} {par.unit}, outside its bounds {par.describe_range()} {par.unit}")
            new[i] = value
        return ParameterVector(self.parameters, tuple(new))

    def free(self, *names: str, ranges: Mapping[str, FitRange] | None = None) -> tuple[Parameter, ...]:
        """The named parameters (default: those marked ``vary``) freed for a fit, each around its current value:
        over ``ranges[name]`` when given, else its declared fit range, else :meth:`Parameter.auto_range`."""
        chosen = names or tuple(p.name for p in self.parameters if p.vary)
        out = []
        for name in chosen:
            i = self._lookup(name, "free")
            par = self.parameters[i].with_value(self.values[i])
            rng = (ranges or {}).get(name)
            out.append(par.free(rng.lower, rng.upper, log=rng.log, linthresh=rng.linthresh) if rng else par.free())
        return tuple(out)

    def _lookup(self, name: str, where: str) -> int:
        i = self._index.get(name)
        if i is None:
            raise ParameterError.at(where, name, f"no such model parameter '{name}' (known: {', '.join(self.names)})")
        return int(i)
