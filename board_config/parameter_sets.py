"""Model parameter sets: TOML files in SI units, validated on load.

A parameter set has the seventeen core parameters of the seed paper's Table 2 (section ``[parameters]``)
and, optionally, added physical effects with their own parameters (an array of tables ``[[effects]]``),
as written by ``shm fit --save``. The configuration layer checks the structure of the effect tables;
the plant checks their names, units and bounds when it composes the model (it knows the effects).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Any

from board_config.errors import ConfigError
from board_config.parameter import Parameter, ParameterVector
from board_config.quantities import parse_quantities, read_toml
from board_config.toml_writer import toml_key, toml_string, toml_value

PARAMS_DIR = Path(__file__).resolve().parent / "params"

_POS: dict[str, Any] = {"lower": 0.0, "lower_open": True}
_NONNEG: dict[str, Any] = {"lower": 0.0}
#: the beam's three sections, root to tip (the index 1..3 of m_i, k_i, c_i)
_SECTIONS = ("Root", "Intermediate", "Tip")


def _per_section(symbol: str, unit: str, bounds: dict[str, Any], what: str
                 ) -> tuple[tuple[str, str, dict[str, Any], str], ...]:
    """The rows of a per-section parameter: ``symbol1`` .. ``symbol3``, root to tip."""
    return tuple((f"{symbol}{i}", unit, bounds, f"{section} {what}") for i, section in enumerate(_SECTIONS, 1))


#: The core parameters (seed paper Table 2), in the order of the core parameter block (``core_index``): name, SI
#: unit, physical bounds, description. The one declaration of each: the plant's layout indices (``plant.layout``)
#: and the core effects' parameters are taken from here; the values come from a parameter set (``table2.toml``).
CORE_PARAMETERS: tuple[Parameter, ...] = tuple(
    Parameter(name, unit, description=text, core_index=i, **bounds)
    for i, (name, unit, bounds, text) in enumerate((
        ("R_ep", "ohm", _POS, "Patch resistance"),
        ("C_ep", "F", _POS, "Patch capacitance"),
        ("d_ep", "m/V", _POS, "Patch piezoelectric coefficient"),
        *_per_section("m", "kg", _POS, "section mass"),
        *_per_section("k", "N/m", _POS, "bending stiffness"),
        *_per_section("c", "N*s/m", _NONNEG, "structural damping"),
        ("alpha_h", "1", {"lower": 0.0, "upper": 1.0}, "Bouc-Wen linearity factor"),
        ("A_h", "1", {}, "Bouc-Wen dissipation gain"),
        ("n_h", "1", _POS, "Bouc-Wen exponent n"),
        ("beta_h", "C^-n", {}, "Bouc-Wen shape factor"),
        ("gamma_h", "C^-n", {}, "Bouc-Wen shape factor"),
    ))
)
#: name -> core parameter
CORE_SCHEMA: Mapping[str, Parameter] = MappingProxyType({p.name: p for p in CORE_PARAMETERS})
#: name -> index in the core parameter block
CORE_INDEX: Mapping[str, int] = MappingProxyType({p.name: i for i, p in enumerate(CORE_PARAMETERS)})
CORE_PARAMETER_NAMES: tuple[str, ...] = tuple(CORE_SCHEMA)


def core_parameters(*names: str) -> tuple[Parameter, ...]:
    """The named core parameters from the schema (what a core effect declares as its ``parameters``)."""
    return tuple(CORE_SCHEMA[n] for n in names)


@dataclass(frozen=True)
class EffectEntry:
    """An added physical effect as written in a parameter set: name or dotted path, and parameter values."""

    name: str
    parameters: Mapping[str, float] = field(default_factory=dict)
    units: Mapping[str, str] = field(default_factory=dict)


@dataclass(frozen=True)
class ParameterSet:
    """A validated parameter set. ``values`` holds the core parameters in SI units."""

    name: str
    values: Mapping[str, float]
    details: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)
    effects: tuple[EffectEntry, ...] = ()
    meta: Mapping[str, Any] = field(default_factory=dict)
    source: str = "<memory>"

    def __getitem__(self, key: str) -> float:
        return self.values[key]

    def with_values(self, name: str | None = None, **changes: float) -> ParameterSet:
        """A copy with some core values changed (validated like a file would be)."""
        values = dict(self.values)
        for key, value in changes.items():
            if key not in CORE_SCHEMA:
                raise ConfigError(self.source, f"parameters.{key}", "unknown core parameter")
            values[key] = CORE_SCHEMA[key].quantity.check(self.source, f"parameters.{key}.value", value)
        return ParameterSet(name or self.name, MappingProxyType(values), self.details, self.effects,
                            self.meta, self.source)

    def core_vector(self) -> ParameterVector:
        """The core parameters with this set's values."""
        return ParameterVector.of(CORE_PARAMETERS, (self.values[p.name] for p in CORE_PARAMETERS))

    def with_effects(self, effects: tuple[EffectEntry, ...], name: str | None = None) -> ParameterSet:
        return ParameterSet(name or self.name, self.values, self.details, tuple(effects), self.meta,
                            self.source)

    def to_toml(self) -> str:
        """Serialise to the same TOML format the loader reads (round-trips through :func:`load_parameter_set`)."""
        lines = ["[meta]", f"name = {toml_string(self.name)}"]
        for key, value in self.meta.items():
            if key != "name" and isinstance(value, (str, int, float)) and not isinstance(value, bool):
                lines.append(f"{toml_key(key)} = {toml_value(value)}")
        lines += ["", "[parameters]"]
        for key in CORE_PARAMETER_NAMES:
            det = dict(self.details.get(key, {}))
            det["unit"] = CORE_SCHEMA[key].unit
            fields = [f"value = {toml_value(self.values[key])}"]
            fields += [f"{f} = {toml_string(str(v))}" for f, v in det.items()]
            lines.append(f"{key} = {{ {', '.join(fields)} }}")
        for eff in self.effects:
            lines += ["", "[[effects]]", f"name = {toml_string(eff.name)}", "[effects.parameters]"]
            for key, value in eff.parameters.items():
                unit = eff.units.get(key, "1")
                lines.append(f"{toml_key(key)} = {{ value = {toml_value(value)}, unit = {toml_string(unit)} }}")
        return "\n".join(lines) + "\n"


def available_parameter_sets() -> list[str]:
    """Names of the parameter sets shipped with the package."""
    return sorted(p.stem for p in PARAMS_DIR.glob("*.toml"))


def resolve_parameter_file(name_or_path: str | Path) -> Path:
    """A shipped set's name (``table2``) or a path to a TOML file."""
    text = str(name_or_path)
    candidate = Path(text)
    if text.endswith(".toml") or candidate.exists() or "/" in text:
        return candidate
    shipped = PARAMS_DIR / f"{text}.toml"
    if not shipped.exists():
        raise ConfigError(text, "-", f"unknown parameter set (shipped sets: {', '.join(available_parameter_sets())};"
                                     " or give a path to a .toml file)")
    return shipped


def load_parameter_set(name_or_path: str | Path | ParameterSet) -> ParameterSet:
    """Load and validate a parameter set; errors name file, key and reason. A :class:`ParameterSet` is returned as it
    is, so callers that take either a name/path or a loaded set need no check of their own."""
    if isinstance(name_or_path, ParameterSet):
        return name_or_path
    path = resolve_parameter_file(name_or_path)
    data = read_toml(path)
    file = str(path)
    unknown = set(data) - {"meta", "parameters", "effects"}
    if unknown:
        raise ConfigError(file, sorted(unknown)[0], "unknown section (expected meta, parameters, effects)")
    meta = data.get("meta", {})
    if not isinstance(meta, Mapping):
        raise ConfigError(file, "meta", "expected a table")
    if "parameters" not in data:
        raise ConfigError(file, "parameters", "missing required section")
    values, details = parse_quantities(file, "parameters", data["parameters"],
                                       {k: p.quantity for k, p in CORE_SCHEMA.items()})
    effects = []
    raw_effects = data.get("effects", [])
    if not isinstance(raw_effects, list):
        raise ConfigError(file, "effects", "expected an array of tables [[effects]]")
    for i, entry in enumerate(raw_effects):
        where = f"effects[{i}]"
        if not isinstance(entry, Mapping):
            raise ConfigError(file, where, "expected a table")
        extra = set(entry) - {"name", "parameters"}
        if extra:
            raise ConfigError(file, f"{where}.{sorted(extra)[0]}", "unknown key (expected name, parameters)")
        name = entry.get("name")
        if not isinstance(name, str) or not name:
            raise ConfigError(file, f"{where}.name", "missing or empty effect name")
        pvals, pdet = parse_quantities(file, f"{where}.parameters", entry.get("parameters", {}), {},
                                       allow_unknown=True)
        effects.append(EffectEntry(name, MappingProxyType({k: float(v) for k, v in pvals.items()}),
                                   MappingProxyType({k: d["unit"] for k, d in pdet.items()})))
    name = meta.get("name", path.stem)
    return ParameterSet(
        name=str(name),
        values=MappingProxyType({k: float(v) for k, v in values.items()}),
        details=MappingProxyType({k: MappingProxyType(v) for k, v in details.items()}),
        effects=tuple(effects),
        meta=MappingProxyType(dict(meta)),
        source=file,
    )
