"""Units in column names: ``<quantity>_<unit>`` (``time_s``, ``z3_mm``, ``z0dd_m_s2``, ``z3_amp_m_per_V``).

A column name carries its unit as a suffix of underscore-joined tokens. Values are converted to SI once, at
load time (``value_SI = factor * value + offset``). Frequency-response columns use ratio units
``<num>_per_<den>`` (``m_per_V``, ``V_per_g``). An unknown unit is an error, never a silent guess.
"""

from __future__ import annotations

from dataclasses import dataclass

from board_config.physical_constants import G0


@dataclass(frozen=True)
class Unit:
    """A unit token as written in a column name, and how to turn it into SI."""

    token: str  # as written: "mm", "m_s2", "g"
    si: str  # the SI unit it converts to: "m", "m/s^2"
    factor: float  # value_SI = factor * value + offset
    offset: float = 0.0

    def to_si(self, values):
        return values * self.factor + self.offset if self.offset else values * self.factor

    def from_si(self, values):
        return (values - self.offset) / self.factor


_TABLE: tuple[Unit, ...] = (
    Unit("s", "s", 1.0), Unit("ms", "s", 1e-3), Unit("us", "s", 1e-6),
    Unit("m", "m", 1.0), Unit("mm", "m", 1e-3), Unit("um", "m", 1e-6), Unit("nm", "m", 1e-9),
    Unit("m_s", "m/s", 1.0), Unit("mm_s", "m/s", 1e-3),
    Unit("m_s2", "m/s^2", 1.0), Unit("mm_s2", "m/s^2", 1e-3), Unit("g", "m/s^2", G0),
    Unit("V", "V", 1.0), Unit("kV", "V", 1e3), Unit("mV", "V", 1e-3),
    Unit("C", "C", 1.0), Unit("mC", "C", 1e-3), Unit("uC", "C", 1e-6), Unit("nC", "C", 1e-9),
    Unit("A", "A", 1.0), Unit("mA", "A", 1e-3), Unit("uA", "A", 1e-6),
    Unit("N", "N", 1.0), Unit("Hz", "Hz", 1.0), Unit("kHz", "Hz", 1e3),
    Unit("rad", "rad", 1.0), Unit("deg", "rad", 3.141592653589793 / 180.0),
    Unit("K", "K", 1.0), Unit("degC", "K", 1.0, 273.15),
    Unit("W", "W", 1.0), Unit("mW", "W", 1e-3), Unit("J", "J", 1.0),
    Unit("1", "1", 1.0), Unit("pct", "1", 1e-2),
)
UNITS: dict[str, Unit] = {u.token: u for u in _TABLE}
#: spellings seen in LabVIEW/TDMS ``unit_string`` properties, mapped to our tokens
UNIT_STRING_ALIASES: dict[str, str] = {
    "m/s^2": "m_s2", "m/s²": "m_s2", "m/s2": "m_s2", "mm/s^2": "mm_s2", "m/s": "m_s", "mm/s": "mm_s",
    "µm": "um", "μm": "um", "µs": "us", "μs": "us", "µC": "uC", "μC": "uC", "µA": "uA", "μA": "uA",
    "°": "deg", "degrees": "deg", "°C": "degC", "C°": "degC", "Volts": "V", "volts": "V", "Volt": "V",
    "%": "pct", "": "1", "-": "1", "Seconds": "s", "sec": "s",
}


def known_units() -> str:
    return ", ".join(sorted(UNITS))


def lookup_unit(token: str) -> Unit | None:
    """A plain unit token (``mm``) or a ratio ``num_per_den`` (``m_per_V``); None when unknown."""
    if token in UNITS:
        return UNITS[token]
    if "_per_" in token:
        num, _, den = token.partition("_per_")
        un, ud = UNITS.get(num), UNITS.get(den)
        if un is not None and ud is not None and not un.offset and not ud.offset:
            return Unit(token, f"{un.si}/({ud.si})" if "/" in ud.si else f"{un.si}/{ud.si}",
                        un.factor / ud.factor)
    return None


def split_column(column: str) -> tuple[str, Unit] | tuple[str, None]:
    """``"z0dd_m_s2" -> ("z0dd", Unit(m_s2))``: the longest trailing run of tokens that is a known unit.

    Returns ``(column, None)`` when no suffix is a known unit.
    """
    parts = column.split("_")
    for k in range(1, len(parts)):  # quantity = parts[:k] (at least one token), unit = the rest (longest first)
        unit = lookup_unit("_".join(parts[k:]))
        if unit is not None:
            return "_".join(parts[:k]), unit
    return column, None


def unit_from_string(unit_string: str) -> Unit | None:
    """A LabVIEW-style unit string (``"mm"``, ``"m/s^2"``, ``"µm"``) as one of our units."""
    s = unit_string.strip()
    return lookup_unit(UNIT_STRING_ALIASES.get(s, s))
