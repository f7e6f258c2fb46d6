"""What an effect may declare about its parameters, in one typed declaration per parameter (:class:`Parameter`): SI
unit expressions (the rule of the house: SI units inside code), finite, ordered bounds, a neutral value inside them,
where a fit searches it and at which strengths the hidden-effect challenge hides the effect (:func:`parameter_problem`);
and the readers every consumer uses (:func:`neutral_values`, :func:`default_fit_names`, :func:`on_request_fit_names`,
:func:`challenge_strengths`) — nothing reads a class table beside the parameters (:func:`legacy_table_problem`
refuses one).

A unit is ``"1"`` (dimensionless) or products and quotients of SI symbols with integer exponents: ``"N*s/m"``,
``"m^-2"``, ``"N/(m/s)^2"``, ``"1/K"``, ``"V*s"``. A generic exponent letter is allowed after ``^`` (``"C^-n"``: the
Bouc-Wen coefficient whose unit follows its exponent ``n``). Anything else — a prefixed unit (``"mm"``, ``"mN"``), a
typo (``"Ns/mm"``, ``"Nm"``, ``"kgg"``), a word — is refused by :func:`unit_problem`, so that a typo in a user's
effect is an error naming the effect and the parameter instead of a silently wrong report or saved set.
"""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

from board_config.errors import InputError
from board_config.parameter import Parameter as OneParameter


class EffectError(InputError):
    """An effect is unknown, cannot be imported, or is ill-formed."""


#: the strengths of the hidden-effect challenge, in the order of a parameter's ``challenge`` values
STRENGTH_NAMES: tuple[str, str, str] = ("weak", "medium", "strong")


@dataclass(frozen=True)
class Parameter(OneParameter):
    """A parameter of an effect: the one parameter type (:class:`board_config.parameter.Parameter`: name, SI unit,
    default, bounds, description, ``neutral`` value, ``fit`` range ...); its :meth:`check` raises
    :class:`EffectError`. ``core_index`` is set for the Table 2 parameters, which the core effects take from
    ``board_config.CORE_SCHEMA``. Two fields only an effect's own parameter has:

    ``challenge``
        (weak, medium, strong): the values at which the hidden-effect challenge hides the effect (SI, inside the
        bounds); the effect's strengths are those of every parameter that declares them;
    ``fit_by_default``
        False for a parameter with a declared ``fit`` range that the workbench frees only when asked
        (``--free NAME``) or, in ``shm diagnose``, in the effect's fuller variant (the laser's spot position).
    """

    challenge: tuple[float, float, float] | None = None
    fit_by_default: bool = True

    error: ClassVar[type[InputError]] = EffectError

    @classmethod
    def of(cls, par: OneParameter) -> Parameter:
        """``par`` as an effect parameter (the same values; its check raises :class:`EffectError`)."""
        if isinstance(par, Parameter):
            return par
        return cls(**{f.name: getattr(par, f.name) for f in dataclasses.fields(par)})

#: the SI symbols an effect's unit may be built from (base and derived units; ``ohm`` spelled out)
SI_SYMBOLS: frozenset[str] = frozenset({
    "m", "kg", "s", "A", "K", "mol", "cd", "rad", "sr", "Hz", "N", "Pa", "J", "W", "C", "V", "F", "ohm", "Ω", "S",
    "Wb", "T", "H",
})
_TOKEN = re.compile(r"\s*(?:(?P<sym>[A-Za-zΩ]+)|(?P<num>\d+)|(?P<op>[*·/^()\-]))")

ALLOWED_TEXT = ("an SI unit expression: '1' (dimensionless) or products and quotients of "
                f"{', '.join(sorted(SI_SYMBOLS - {'Ω'}))} with integer exponents (e.g. 'N*s/m', 'm^-2', "
                "'N/(m/s)^2'); no prefixed units (values are SI)")


def _tokens(unit: str) -> list[tuple[str, str]] | None:
    out: list[tuple[str, str]] = []
    pos = 0
    text = unit.rstrip()
    while pos < len(text):
        m = _TOKEN.match(text, pos)
        if m is None or m.end() == pos:
            return None
        kind = m.lastgroup or ""
        out.append((kind, m.group(kind)))
        pos = m.end()
    return out


def unit_problem(unit: object) -> str | None:
    """Why ``unit`` is not an SI unit expression (None when it is): names the offending symbol."""
    if not isinstance(unit, str) or not unit.strip():
        return f"the unit must be a non-empty string, got {unit!r}"
    toks = _tokens(unit)
    if toks is None:
        return f"unit {unit!r} has a character that is not part of a unit expression"
    depth = 0
    expect_operand = True
    k = 0
    while k < len(toks):
        kind, text = toks[k]
        if expect_operand:
            if kind == "sym" and text in SI_SYMBOLS:
                expect_operand = False
            elif kind == "num" and text == "1":
                expect_operand = False
            elif (kind, text) == ("op", "("):
                depth += 1
            elif kind == "sym":
                return f"unit {unit!r}: '{text}' is not an SI symbol"
            else:
                return f"unit {unit!r}: '{text}' where a unit symbol was expected"
        elif (kind, text) == ("op", "^"):
            nxt = toks[k + 1:k + 3]
            if nxt and nxt[0] == ("op", "-"):
                nxt = nxt[1:2]
                k += 1
            if not nxt or not (nxt[0][0] == "num" or (nxt[0][0] == "sym" and len(nxt[0][1]) == 1)):
                return f"unit {unit!r}: '^' must be followed by an integer exponent"
            k += 1
        elif (kind, text) == ("op", ")"):
            depth -= 1
            if depth < 0:
                return f"unit {unit!r}: unbalanced ')'"
        elif kind == "op" and text in "*·/":
            expect_operand = True
        else:
            return f"unit {unit!r}: '{text}' after a unit symbol (write products with '*', e.g. 'N*m')"
        k += 1
    if expect_operand:
        return f"unit {unit!r} ends where a unit symbol was expected"
    if depth:
        return f"unit {unit!r}: unbalanced '('"
    return None


def parameter_problem(par: Any) -> str | None:
    """Why an effect's own parameter declaration is unusable (None when it is fine): its unit (:func:`unit_problem`),
    a NaN bound, bounds out of order, a neutral value that is not finite or outside the bounds. (Its default is
    checked against the bounds by :meth:`board_config.parameter.Parameter.check`.)"""
    why = unit_problem(par.unit)
    if why is not None:
        return f"{why}; allowed: {ALLOWED_TEXT}"
    lo, hi = float(par.lower), float(par.upper)
    if math.isnan(lo) or math.isnan(hi):
        return f"bounds [{lo!r}, {hi!r}] hold NaN; give numbers (or -math.inf / math.inf for no bound)"
    if not lo < hi or lo == math.inf or hi == -math.inf:
        return f"bounds [{lo!r}, {hi!r}] are not an interval: need lower < upper"
    if par.neutral is not None:
        neutral = float(par.neutral)
        if not math.isfinite(neutral) or not lo <= neutral <= hi:
            return f"neutral value {neutral!r} must be a finite number inside the bounds [{lo!r}, {hi!r}]"
    return _challenge_problem(par, lo, hi)


def _challenge_problem(par: Any, lo: float, hi: float) -> str | None:
    if not getattr(par, "fit_by_default", True) and par.fit is None:
        return "fit_by_default=False needs a declared fit range (fit=FitRange(LOWER, UPPER))"
    values = getattr(par, "challenge", None)
    if values is None:
        return None
    try:
        strengths = [float(v) for v in values]
    except (TypeError, ValueError):
        strengths = []
    if len(strengths) != len(STRENGTH_NAMES) or not all(math.isfinite(v) and lo <= v <= hi for v in strengths):
        return (f"challenge {values!r} must be {len(STRENGTH_NAMES)} finite numbers ({', '.join(STRENGTH_NAMES)}) "
                f"inside the bounds [{lo!r}, {hi!r}]")
    return None


def neutral_values(parameters: Iterable[Parameter]) -> dict[str, float]:
    """The values at which the effect with these (own) parameters leaves the model unchanged, by name."""
    return {p.name: float(p.neutral) for p in parameters if p.neutral is not None}


def default_fit_names(parameters: Iterable[Parameter]) -> tuple[str, ...]:
    """The parameters the workbench fits by default: those with a declared ``fit`` range (or ``vary``) and
    ``fit_by_default``; when none declares a range, every one (each searched over its bounds)."""
    pars = tuple(parameters)
    declared = [p for p in pars if p.fit is not None or p.vary]
    return tuple(p.name for p in (declared or pars) if p.fit_by_default)


def on_request_fit_names(parameters: Iterable[Parameter]) -> tuple[str, ...]:
    """The parameters with a declared ``fit`` range that are fitted only when asked (``fit_by_default=False``)."""
    return tuple(p.name for p in parameters if p.fit is not None and not p.fit_by_default)


def challenge_strengths(parameters: Iterable[Parameter]) -> tuple[dict[str, float], ...]:
    """(weak, medium, strong) parameter values of the hidden-effect challenge, from every parameter that declares
    its ``challenge``; () when none does."""
    hidden = [(p.name, p.challenge) for p in parameters if p.challenge is not None]
    if not hidden:
        return ()
    return tuple({name: float(values[k]) for name, values in hidden} for k in range(len(STRENGTH_NAMES)))


#: class tables older effects declared beside their parameters, and the parameter declaration that replaces each
LEGACY_TABLES: dict[str, str] = {
    "neutral": "Parameter(..., neutral=VALUE)",
    "fit_ranges": "Parameter(..., fit=FitRange(LOWER, UPPER))",
    "extra_ranges": "Parameter(..., fit=FitRange(LOWER, UPPER), fit_by_default=False)",
    "challenge_strengths": "Parameter(..., challenge=(WEAK, MEDIUM, STRONG))",
}


def legacy_table_problem(cls: type) -> str | None:
    """Why ``cls`` is refused for declaring one of :data:`LEGACY_TABLES` as a class attribute (None when it does
    not): the values belong to the parameter's own declaration, and a table nobody reads would be silently lost."""
    for klass in cls.__mro__:
        for table, instead in LEGACY_TABLES.items():
            if isinstance(vars(klass).get(table), Mapping | tuple | list):  # a table, not the reader method
                return (f"declares '{table}' as a class table; declare it on its parameter instead: {instead} "
                        "(docs/effects.md)")
    return None
