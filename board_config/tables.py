"""Loaders for the small fixed tables: MFC limits (Table 1) and monitor settings (Table 3)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from board_config.errors import ConfigError
from board_config.quantities import QuantitySpec, parse_quantities, read_toml

CONFIG_DIR = Path(__file__).resolve().parent


@dataclass(frozen=True)
class MfcLimits:
    """MFC operational limits (Table 1), SI units."""

    voltage_min: float  # V
    voltage_max: float  # V
    temperature_min: float  # K
    temperature_max: float  # K
    frequency_max: float  # Hz
    stall_force: float  # N
    free_strain: float  # 1
    lifetime_cycles_1kVpp: float  # cycles

    def clamp_voltage(self, volts: float) -> float:
        """The nearest voltage inside the allowed range (V)."""
        return min(max(volts, self.voltage_min), self.voltage_max)


@dataclass(frozen=True)
class MonitorSettings:
    """Condition-monitor settings (Table 3, Eq. 11), SI units."""

    f_mon: float  # Hz
    eps_th: float  # 1
    count_max: int  # count
    counter_up: int  # count
    counter_down: int  # count
    e0z: float  # m
    kerr_z: float  # 1


_LIMITS_SCHEMA = {
    "voltage_min": QuantitySpec("V"),
    "voltage_max": QuantitySpec("V"),
    "temperature_min": QuantitySpec("K", lower=0.0, lower_open=True),
    "temperature_max": QuantitySpec("K", lower=0.0, lower_open=True),
    "frequency_max": QuantitySpec("Hz", lower=0.0, lower_open=True),
    "stall_force": QuantitySpec("N", lower=0.0, lower_open=True),
    "free_strain": QuantitySpec("1", lower=0.0, lower_open=True),
    "lifetime_cycles_1kVpp": QuantitySpec("cycles", lower=0.0, lower_open=True),
}

_MONITOR_SCHEMA = {
    "f_mon": QuantitySpec("Hz", lower=0.0, lower_open=True),
    "eps_th": QuantitySpec("1", lower=0.0, lower_open=True),
    "count_max": QuantitySpec("count", integer=True, lower=1),
    "counter_up": QuantitySpec("count", integer=True, lower=1),
    "counter_down": QuantitySpec("count", integer=True, lower=0),
    "e0z": QuantitySpec("m", lower=0.0, lower_open=True),
    "kerr_z": QuantitySpec("1", lower=0.0, lower_open=True),
}


def load_mfc_limits(path: str | Path | None = None) -> MfcLimits:
    """Table 1 limits; ``voltage_min < voltage_max`` is checked too."""
    path = Path(path) if path is not None else CONFIG_DIR / "mfc_limits.toml"
    data = read_toml(path)
    values, _ = parse_quantities(str(path), "limits", data.get("limits"), _LIMITS_SCHEMA)
    if values["voltage_min"] >= values["voltage_max"]:
        raise ConfigError(str(path), "limits.voltage_min", "must be below limits.voltage_max")
    return MfcLimits(**values)


def load_monitor_settings(path: str | Path | None = None) -> MonitorSettings:
    """Table 3 monitor settings."""
    path = Path(path) if path is not None else CONFIG_DIR / "monitor.toml"
    data = read_toml(path)
    values, _ = parse_quantities(str(path), "monitor", data.get("monitor"), _MONITOR_SCHEMA)
    counts = {k: int(values[k]) for k in ("count_max", "counter_up", "counter_down")}  # integer=True in the schema
    return MonitorSettings(f_mon=values["f_mon"], eps_th=values["eps_th"], e0z=values["e0z"], kerr_z=values["kerr_z"],
                           **counts)
