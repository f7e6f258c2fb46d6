"""Generic, validated loading of TOML tables of physical quantities.

Every quantity in our configuration files is written as an inline table with its value and unit::

    k3 = { value = 21.28, unit = "N/m", definition = "Stiffness related to tip section bending" }

A *schema* says, per key, which unit is expected, whether the value is an integer, and which bounds it
must satisfy. Units are checked as strings (we keep SI inside the code, so there is exactly one accepted
unit per key); a different unit is an error rather than a silent conversion.
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from board_config.errors import ConfigError

#: Extra, purely descriptive fields that a quantity table may carry.
DESCRIPTIVE_FIELDS = frozenset({"definition", "method", "printed_unit", "note", "source"})


@dataclass(frozen=True)
class QuantitySpec:
    """What one key of a quantity table must hold.

    ``lower``/``upper`` are bounds; ``lower_open``/``upper_open`` make them strict (``>`` instead of ``>=``).
    """

    unit: str
    integer: bool = False
    lower: float | None = None
    upper: float | None = None
    lower_open: bool = False
    upper_open: bool = False
    required: bool = True

    def describe_range(self) -> str:
        lo = "(-inf" if self.lower is None else ("(" if self.lower_open else "[") + f"{self.lower:g}"
        hi = "+inf)" if self.upper is None else f"{self.upper:g}" + (")" if self.upper_open else "]")
        return f"{lo}, {hi}"

    def check(self, file: str, key: str, value: Any) -> float | int:
        """Return the validated value or raise :class:`ConfigError` naming file, key and reason."""
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(file, key, f"expected a number, got {type(value).__name__} {value!r}")
        number: float | int = value
        if self.integer:
            if isinstance(number, float):
                if not number.is_integer():
                    raise ConfigError(file, key, f"expected an integer, got {number!r}")
                number = int(number)
        else:
            number = float(number)
        if isinstance(number, float) and not math.isfinite(number):
            raise ConfigError(file, key, f"value must be finite, got {number!r}")
        if self.lower is not None and (number <= self.lower if self.lower_open else number < self.lower):
            raise ConfigError(file, key, f"value {number!r} outside the allowed range {self.describe_range()}")
        if self.upper is not None and (number >= self.upper if self.upper_open else number > self.upper):
            raise ConfigError(file, key, f"value {number!r} outside the allowed range {self.describe_range()}")
        return number


def read_toml(path: str | Path) -> dict[str, Any]:
    """Read a TOML file, turning every read or syntax problem into a :class:`ConfigError`."""
    path = Path(path)
    try:
        with path.open("rb") as fh:
            return tomllib.load(fh)
    except FileNotFoundError:
        raise ConfigError(str(path), "-", "file not found") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(str(path), "-", f"not valid TOML: {exc}") from None
    except UnicodeDecodeError as exc:
        raise ConfigError(str(path), "-", f"not a UTF-8 text file, so not TOML ({exc.reason} at byte {exc.start})"
                          ) from None
    except OSError as exc:
        raise ConfigError(str(path), "-", f"cannot read: {exc}") from None


def parse_quantities(
    file: str,
    section: str,
    table: Any,
    schema: Mapping[str, QuantitySpec],
    *,
    allow_unknown: bool = False,
) -> tuple[dict[str, float | int], dict[str, dict[str, Any]]]:
    """Validate ``table`` (the contents of ``[section]``) against ``schema``.

    Returns ``(values, details)`` where ``values`` maps key to the SI value and ``details`` keeps the
    descriptive fields (definition, method, printed unit ...) for reports.
    """
    if not isinstance(table, Mapping):
        raise ConfigError(file, section, f"expected a table, got {type(table).__name__}")
    values: dict[str, float | int] = {}
    details: dict[str, dict[str, Any]] = {}
    for key in schema:
        if key not in table and schema[key].required:
            raise ConfigError(file, f"{section}.{key}", "missing required key")
    for key, entry in table.items():
        dotted = f"{section}.{key}"
        spec = schema.get(key)
        if spec is None and not allow_unknown:
            known = ", ".join(sorted(schema))
            raise ConfigError(file, dotted, f"unknown key (known keys: {known})")
        if not isinstance(entry, Mapping):
            raise ConfigError(file, dotted, "expected an inline table { value = ..., unit = \"...\" }")
        extra = set(entry) - {"value", "unit"} - DESCRIPTIVE_FIELDS
        if extra:
            raise ConfigError(file, f"{dotted}.{sorted(extra)[0]}", "unknown field in quantity table")
        if "value" not in entry:
            raise ConfigError(file, f"{dotted}.value", "missing required key")
        if "unit" not in entry:
            raise ConfigError(file, f"{dotted}.unit", "missing required key (every quantity names its unit)")
        unit = entry["unit"]
        if not isinstance(unit, str):
            raise ConfigError(file, f"{dotted}.unit", f"expected a string, got {type(unit).__name__}")
        if spec is not None:
            if unit != spec.unit:
                raise ConfigError(file, f"{dotted}.unit", f"expected unit '{spec.unit}', got '{unit}'")
            values[key] = spec.check(file, f"{dotted}.value", entry["value"])
        else:
            values[key] = QuantitySpec(unit=unit).check(file, f"{dotted}.value", entry["value"])
        details[key] = {"unit": unit, **{f: entry[f] for f in entry if f in DESCRIPTIVE_FIELDS}}
    return values, details
