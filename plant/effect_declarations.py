"""What an effect may declare: SI unit expressions (the rule of the house: SI units inside code) and finite, ordered
bounds and neutral values of its parameters (:func:`parameter_problem`).

A unit is ``"1"`` (dimensionless) or products and quotients of SI symbols with integer exponents: ``"N*s/m"``,
``"m^-2"``, ``"N/(m/s)^2"``, ``"1/K"``, ``"V*s"``. A generic exponent letter is allowed after ``^`` (``"C^-n"``: the
Bouc-Wen coefficient whose unit follows its exponent ``n``). Anything else — a prefixed unit (``"mm"``, ``"mN"``), a
typo (``"Ns/mm"``, ``"Nm"``, ``"kgg"``), a word — is refused by :func:`unit_problem`, so that a typo in a user's
effect is an error naming the effect and the parameter instead of a silently wrong report or saved set.
"""

from __future__ import annotations

import math
import re
from typing import Any

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
    return None
