"""A measured value and its uncertainty as text, with the digits the uncertainty supports (pure, no I/O).

The uncertainty is rounded to ``sig`` significant digits (default 2, the usual metrology convention), and the value
is rounded to the same decimal place: ``9.740123 ± 0.000471`` prints ``9.74012 ± 0.00047``, ``-18.1321 ± 0.3589``
prints ``-18.13 ± 0.36``, ``12345 ± 234`` prints ``12350 ± 230``. An uncertainty never prints as zero when it is
not (the report's old ``± 0.00 %`` for α_h). Very small or very large uncertainties (beyond 1e-6 … 1e6 of the unit)
share one power of ten: ``(1.234 ± 0.012)e-09``.
"""

from __future__ import annotations

import math
from decimal import ROUND_HALF_UP, Decimal

#: decimal exponents of the uncertainty outside which the text switches to a shared power of ten
_FIXED_EXPONENTS = (-6, 6)


def _round_at(x: float | Decimal, place: int) -> Decimal:
    """``x`` rounded half away from zero at the decimal exponent ``place`` (exact: decimal arithmetic)."""
    exact = Decimal(repr(float(x)) if isinstance(x, float) else x)  # float(): numpy's repr is 'np.float64(...)'
    return exact.quantize(Decimal(1).scaleb(place), rounding=ROUND_HALF_UP)


def _last_place(uncertainty: float, sig: int) -> tuple[int, Decimal]:
    """(decimal exponent of the last printed digit, the uncertainty rounded there)."""
    place = math.floor(math.log10(uncertainty)) - (sig - 1)
    rounded = _round_at(uncertainty, place)
    if rounded >= Decimal(1).scaleb(place + sig):  # 0.0996 -> 0.10: one digit more, move the place up
        place += 1
        rounded = _round_at(uncertainty, place)
    return place, rounded


def _fixed(x: float | Decimal, place: int, sign: bool) -> str:
    q = _round_at(x, place)
    if q == 0:
        q = abs(q)  # no "-0.00"
    text = f"{q:f}" if place <= 0 else f"{q.quantize(Decimal(1)):f}"
    return ("+" + text if sign and not text.startswith("-") else text)


def format_uncertain(value: float, uncertainty: float | None, *, sig: int = 2, sign: bool = False,
                     unit: str = "") -> str:
    """``value ± uncertainty`` with ``sig`` significant digits on the uncertainty and the value rounded to the same
    decimal place; ``sign`` prints the value's sign always (a change: ``+9.74012 ± 0.00047``); ``unit`` is appended
    after a space. A missing, non-finite or non-positive uncertainty prints the value to 4 significant digits with
    ``± ?`` (unknown) or ``± 0`` (exactly zero)."""
    if sig < 1:
        raise ValueError(f"sig must be >= 1, got {sig}")
    tail = f" {unit}" if unit else ""
    if not math.isfinite(value):
        return f"{value}{tail}"
    if uncertainty is None or not math.isfinite(uncertainty) or uncertainty <= 0:
        v = f"{value:+.4g}" if sign else f"{value:.4g}"
        mark = "0" if uncertainty == 0 else "?"
        return f"{v} ± {mark}{tail}"
    place, u = _last_place(uncertainty, sig)
    exp_u = place + sig - 1
    if _FIXED_EXPONENTS[0] <= exp_u <= _FIXED_EXPONENTS[1]:
        return f"{_fixed(value, place, sign)} ± {_fixed(u, place, False)}{tail}"
    shared = max(exp_u, math.floor(math.log10(abs(value))) if value != 0 else exp_u)
    v_s = Decimal(repr(value)).scaleb(-shared)
    return (f"({_fixed(v_s, place - shared, sign)} ± {_fixed(u.scaleb(-shared), place - shared, False)})"
            f"e{shared:+03d}{tail}")


def format_percent_change(relative: float, relative_uncertainty: float | None, *, sig: int = 2) -> str:
    """A relative change (fraction) and its uncertainty as signed per cent: ``+9.74012 ± 0.00047 %``."""
    u = None if relative_uncertainty is None else 100.0 * relative_uncertainty
    return format_uncertain(100.0 * relative, u, sig=sig, sign=True, unit="%")
