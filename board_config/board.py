"""The board firmware configuration (``board_config/board.toml``): regime thresholds, currents per regime,
timers, plausibility limits. Every number the regime logic uses comes from here.

Overrides (from a scenario's ``[board]`` table) have the same shape as the file, section by section, and are
validated with the same schema, so a scenario cannot smuggle in an unknown key or a wrong unit.
"""

from __future__ import annotations

import copy
import itertools
import math
from collections.abc import Mapping
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

from board_config.errors import ConfigError
from board_config.quantities import DESCRIPTIVE_FIELDS, QuantitySpec, parse_quantities, read_toml

CONFIG_DIR = Path(__file__).resolve().parent
DEFAULT_BOARD_FILE = CONFIG_DIR / "board.toml"

_POS: dict[str, Any] = {"lower": 0.0, "lower_open": True}
_NONNEG: dict[str, Any] = {"lower": 0.0}
_COUNT1: dict[str, Any] = {"integer": True, "lower": 1}

#: section -> key -> spec (scalar quantities)
BOARD_SCHEMA: dict[str, dict[str, QuantitySpec]] = {
    "tick": {
        "rate": QuantitySpec("Hz", lower=1.0, upper=10_000.0),
        "link_loss_ticks": QuantitySpec("count", **_COUNT1, upper=1000),
        "overrun_ticks": QuantitySpec("count", **_COUNT1, upper=10_000),
        "stale_ticks": QuantitySpec("count", **_COUNT1, upper=10_000),
    },
    "wake": {
        "patch_voltage": QuantitySpec("V", **_POS),
        "base_acceleration": QuantitySpec("m/s^2", **_POS),
        "debounce_ticks": QuantitySpec("count", **_COUNT1, upper=10_000),
    },
    "sensing": {
        "quiet_period": QuantitySpec("s", **_POS),
        "rainflow_gate": QuantitySpec("m", **_NONNEG),
        "max_episode": QuantitySpec("s", **_POS),
        "rainflow_bin_width": QuantitySpec("m", **_POS),
    },
    "maintenance": {
        "hv_debounce": QuantitySpec("s", **_NONNEG),
        "settle": QuantitySpec("s", **_NONNEG),
    },
    "power": {
        "current_standby": QuantitySpec("A", **_NONNEG, upper=1.0),
        "current_sensing": QuantitySpec("A", **_NONNEG, upper=1.0),
        "current_maintenance": QuantitySpec("A", **_NONNEG, upper=1.0),
        "current_safe": QuantitySpec("A", **_NONNEG, upper=1.0),
        "wake_min_voltage": QuantitySpec("V", **_POS, upper=10.0),
        "brownout_voltage": QuantitySpec("V", **_POS, upper=10.0),
        "brownout_hysteresis": QuantitySpec("V", **_NONNEG, upper=5.0),
        "brownout_ticks": QuantitySpec("count", **_COUNT1, upper=10_000),
    },
    "sensors": {
        "z3_limit": QuantitySpec("m", **_POS),
        "v_patch_limit": QuantitySpec("V", **_POS),
        "z0dd_limit": QuantitySpec("m/s^2", **_POS),
        "v_battery_max": QuantitySpec("V", **_POS),
    },
    "safe": {
        "link_recovery": QuantitySpec("s", **_NONNEG),
    },
    "log": {
        "telemetry_period": QuantitySpec("s", **_POS),
    },
}

#: keys holding an array quantity ``{ value = [...], unit = "..." }``: section -> key -> element spec
BOARD_ARRAY_SCHEMA: dict[str, dict[str, QuantitySpec]] = {
    "sensing": {"exceedance_levels": QuantitySpec("m", **_POS)},
}

#: keys holding plain (non-quantity) values: section -> key -> allowed values
BOARD_PLAIN_SCHEMA: dict[str, dict[str, tuple[str, ...]]] = {
    "maintenance": {"sequence": ("a", "b")},
}


@dataclass(frozen=True)
class BoardConfig:
    """Validated board configuration, SI units. Field names are ``<section>_<key>`` of ``board.toml``."""

    tick_rate: float  # Hz
    tick_link_loss_ticks: int
    tick_overrun_ticks: int
    tick_stale_ticks: int
    wake_patch_voltage: float  # V
    wake_base_acceleration: float  # m/s^2
    wake_debounce_ticks: int
    sensing_quiet_period: float  # s
    sensing_rainflow_gate: float  # m
    sensing_max_episode: float  # s
    sensing_rainflow_bin_width: float  # m
    sensing_exceedance_levels: tuple[float, ...]  # m
    maintenance_hv_debounce: float  # s
    maintenance_settle: float  # s
    maintenance_sequence: tuple[str, ...]
    power_current_standby: float  # A
    power_current_sensing: float  # A
    power_current_maintenance: float  # A
    power_current_safe: float  # A
    power_wake_min_voltage: float  # V
    power_brownout_voltage: float  # V
    power_brownout_hysteresis: float  # V
    power_brownout_ticks: int
    sensors_z3_limit: float  # m
    sensors_v_patch_limit: float  # V
    sensors_z0dd_limit: float  # m/s^2
    sensors_v_battery_max: float  # V
    safe_link_recovery: float  # s
    log_telemetry_period: float  # s
    source: str = "<memory>"

    @property
    def tick_period(self) -> float:
        """Tick period (s)."""
        return 1.0 / self.tick_rate

    def ticks(self, seconds: float) -> int:
        """A duration (s) as a whole number of ticks (rounded, at least 0)."""
        return max(0, round(seconds * self.tick_rate))

    def as_dict(self) -> dict[str, Any]:
        return {f.name: getattr(self, f.name) for f in fields(self)}


def _merge(base: dict[str, Any], overrides: Mapping[str, Any], where: str) -> dict[str, Any]:
    out = copy.deepcopy(base)
    for section, table in overrides.items():
        if section == "meta":
            continue
        if section not in BOARD_SCHEMA:
            raise ConfigError(where, f"board.{section}",
                              f"unknown board section (known: {', '.join(sorted(BOARD_SCHEMA))})")
        if not isinstance(table, Mapping):
            raise ConfigError(where, f"board.{section}", "expected a table")
        dest = out.setdefault(section, {})
        for key, value in table.items():
            dest[key] = value
    return out


def _parse_array(file: str, dotted: str, entry: Any, spec: QuantitySpec) -> tuple[float, ...]:
    if not isinstance(entry, Mapping) or "value" not in entry or "unit" not in entry:
        raise ConfigError(file, dotted, "expected an inline table { value = [...], unit = \"...\" }")
    extra = set(entry) - {"value", "unit"} - DESCRIPTIVE_FIELDS
    if extra:
        raise ConfigError(file, f"{dotted}.{sorted(extra)[0]}", "unknown field in quantity table")
    if entry["unit"] != spec.unit:
        raise ConfigError(file, f"{dotted}.unit", f"expected unit '{spec.unit}', got '{entry['unit']}'")
    values = entry["value"]
    if not isinstance(values, list) or not values:
        raise ConfigError(file, f"{dotted}.value", "expected a non-empty array of numbers")
    out = tuple(float(spec.check(file, f"{dotted}.value[{i}]", v)) for i, v in enumerate(values))
    if any(b <= a for a, b in itertools.pairwise(out)):
        raise ConfigError(file, f"{dotted}.value", f"levels must be strictly increasing, got {list(out)}")
    return out


def parse_board_config(data: Mapping[str, Any], file: str) -> BoardConfig:
    """Validate a board configuration mapping (the parsed TOML, overrides already merged)."""
    unknown = set(data) - set(BOARD_SCHEMA) - {"meta"}
    if unknown:
        raise ConfigError(file, sorted(unknown)[0],
                          f"unknown section (known: meta, {', '.join(sorted(BOARD_SCHEMA))})")
    values: dict[str, Any] = {}
    for section, schema in BOARD_SCHEMA.items():
        table = data.get(section)
        if table is None:
            raise ConfigError(file, section, "missing required section")
        if not isinstance(table, Mapping):
            raise ConfigError(file, section, f"expected a table, got {type(table).__name__}")
        arrays = BOARD_ARRAY_SCHEMA.get(section, {})
        plains = BOARD_PLAIN_SCHEMA.get(section, {})
        scalar_table = {k: v for k, v in table.items() if k not in arrays and k not in plains}
        vals, _ = parse_quantities(file, section, scalar_table, schema)
        for key, v in vals.items():
            values[f"{section}_{key}"] = v
        for key, spec in arrays.items():
            if key not in table:
                raise ConfigError(file, f"{section}.{key}", "missing required key")
            values[f"{section}_{key}"] = _parse_array(file, f"{section}.{key}", table[key], spec)
        for key, allowed in plains.items():
            if key not in table:
                raise ConfigError(file, f"{section}.{key}", "missing required key")
            seq = table[key]
            if not isinstance(seq, list) or not all(isinstance(s, str) for s in seq):
                raise ConfigError(file, f"{section}.{key}", f"expected an array of strings from {list(allowed)}")
            for i, s in enumerate(seq):
                if s not in allowed:
                    raise ConfigError(file, f"{section}.{key}[{i}]", f"unknown value {s!r} (allowed: {list(allowed)})")
            values[f"{section}_{key}"] = tuple(seq)
    cfg = BoardConfig(**values, source=file)
    if cfg.power_brownout_voltage + cfg.power_brownout_hysteresis > cfg.power_wake_min_voltage + 1e-12:
        raise ConfigError(file, "power.wake_min_voltage",
                          f"must be at least brownout_voltage + brownout_hysteresis "
                          f"({cfg.power_brownout_voltage + cfg.power_brownout_hysteresis:g} V), "
                          f"got {cfg.power_wake_min_voltage:g} V")
    if not math.isclose(cfg.tick_rate * cfg.tick_period, 1.0):
        raise ConfigError(file, "tick.rate", "invalid tick rate")
    return cfg


def load_board_config(path: str | Path | None = None, overrides: Mapping[str, Any] | None = None,
                      overrides_source: str = "<overrides>") -> BoardConfig:
    """Load ``board.toml`` (or ``path``), merge ``overrides`` (same shape, e.g. a scenario's ``[board]``) and validate.

    Errors name the file (the overrides' source for an overridden key), the dotted key and the reason.
    """
    path = Path(path) if path is not None else DEFAULT_BOARD_FILE
    data = read_toml(path)
    file = str(path)
    if overrides:
        # validate the overrides on their own first, so errors name the scenario file, not board.toml
        for section, table in overrides.items():
            if section not in BOARD_SCHEMA:
                raise ConfigError(overrides_source, f"board.{section}",
                                  f"unknown board section (known: {', '.join(sorted(BOARD_SCHEMA))})")
            if not isinstance(table, Mapping):
                raise ConfigError(overrides_source, f"board.{section}", "expected a table")
            arrays = BOARD_ARRAY_SCHEMA.get(section, {})
            plains = BOARD_PLAIN_SCHEMA.get(section, {})
            scalar = {k: v for k, v in table.items() if k not in arrays and k not in plains}
            schema = {k: QuantitySpec(s.unit, s.integer, s.lower, s.upper, s.lower_open, s.upper_open, False)
                      for k, s in BOARD_SCHEMA[section].items()}
            parse_quantities(overrides_source, f"board.{section}", scalar, schema)
            for key, spec in arrays.items():
                if key in table:
                    _parse_array(overrides_source, f"board.{section}.{key}", table[key], spec)
        data = _merge(data, overrides, overrides_source)
        file = f"{file} + {overrides_source}"
    return parse_board_config(data, file)
