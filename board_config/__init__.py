"""Typed, validated configuration: parameter sets (TOML, SI units), MFC limits, monitor settings.

This package imports nothing else of ours.
"""

from board_config.errors import ConfigError, InputError
from board_config.mbit import MbitDefinition, load_mbit, load_mbit_definitions
from board_config.parameter import (
    DEVIATION_RANGE,
    FitRange,
    Parameter,
    ParameterError,
    ParameterVector,
    deviation_problem,
)
from board_config.parameter_sets import (
    CORE_INDEX,
    CORE_PARAMETER_NAMES,
    CORE_PARAMETERS,
    CORE_SCHEMA,
    EffectEntry,
    ParameterSet,
    available_parameter_sets,
    load_parameter_set,
)
from board_config.quantities import QuantitySpec, parse_quantities, read_toml
from board_config.tables import MfcLimits, MonitorSettings, load_mfc_limits, load_monitor_settings

__all__ = [
    "CORE_INDEX",
    "CORE_PARAMETERS",
    "CORE_PARAMETER_NAMES",
    "CORE_SCHEMA",
    "DEVIATION_RANGE",
    "ConfigError",
    "EffectEntry",
    "FitRange",
    "InputError",
    "MbitDefinition",
    "MfcLimits",
    "MonitorSettings",
    "Parameter",
    "ParameterError",
    "ParameterSet",
    "ParameterVector",
    "QuantitySpec",
    "available_parameter_sets",
    "deviation_problem",
    "load_mbit",
    "load_mbit_definitions",
    "load_mfc_limits",
    "load_monitor_settings",
    "load_parameter_set",
    "parse_quantities",
    "read_toml",
]
