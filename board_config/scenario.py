"""Scenarios for ``shm run``: what the aircraft, the maintainers and the rig do, as a TOML file.

Format (documented in full, with examples, in ``docs/scenarios.md``)::

    [scenario]
    name = "default"
    description = "..."
    seed = 1                                   # default seed (``--seed`` overrides)
    expect_verdict = "PASS"                    # optional: PASS | FAULT | NONE (what the MBITs should say)

    [rig]                                      # the simulated rig (truth plant, battery, sensors)
    params = "table2"                          # parameter set of the truth plant
    deviations = { k3 = -0.30 }                # relative: truth = nominal * (1 + d)
    effects = []                               # added physical effects (names or dotted paths)
    battery_initial_voltage = { value = 3.0, unit = "V" }
    z3_noise = { value = 2e-6, unit = "m" }    # laser noise (1 sigma) ... see _RIG_SCHEMA

    [board.power]                              # optional overrides of board_config/board.toml, same shape
    current_sensing = { value = 3e-3, unit = "A" }

    [[phase]]                                  # consecutive phases; their durations add up to the run length
    name = "cruise"
    kind = "flight"                            # ground | flight | landing | maintenance
    duration = { value = 900, unit = "s" }
    vibration_rms = { value = 0.6, unit = "m/s^2" }

    [[event]]                                  # things that happen at a time
    kind = "gust"                              # gust | link_outage | sensor_fault | rearm | battery_load
    at = { value = 600, unit = "s" }
    peak = { value = 15, unit = "m/s^2" }
    duration = { value = 1.5, unit = "s" }

Time is measured from the start of the first phase (s). Every quantity carries its unit (SI only).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Any

from board_config.errors import ConfigError
from board_config.parameter import DEVIATION_RANGE, deviation_problem
from board_config.quantities import QuantitySpec, parse_quantities, read_toml

SCENARIO_DIR = Path(__file__).resolve().parent / "scenarios"

PHASE_KINDS = ("ground", "flight", "landing", "maintenance")
EVENT_KINDS = ("gust", "link_outage", "sensor_fault", "rearm", "battery_load")
SENSOR_FAULT_MODES = ("nan", "flag", "frozen_seq", "out_of_range")
VERDICTS = ("PASS", "FAULT", "NONE")

_POS: dict[str, Any] = {"lower": 0.0, "lower_open": True}
_NONNEG: dict[str, Any] = {"lower": 0.0}


def _opt(unit: str, **kw: Any) -> QuantitySpec:
    return QuantitySpec(unit, required=False, **kw)


_VIBRATION = {
    "duration": QuantitySpec("s", **_POS),
    "vibration_rms": _opt("m/s^2", **_NONNEG, upper=490.0),
    "band_low": _opt("Hz", **_POS),
    "band_high": _opt("Hz", **_POS),
    "tone_frequency": _opt("Hz", **_POS),
    "tone_amplitude": _opt("m/s^2", **_NONNEG, upper=490.0),
}
_PHASE_SCHEMA: dict[str, dict[str, QuantitySpec]] = {
    "ground": dict(_VIBRATION),
    "flight": dict(_VIBRATION),
    "landing": {
        **_VIBRATION,
        "touchdown_peak": QuantitySpec("m/s^2", **_NONNEG, upper=490.0),
        "touchdown_frequency": _opt("Hz", **_POS),
        "touchdown_decay": _opt("s", **_POS),
    },
    "maintenance": dict(_VIBRATION),
}
_PHASE_DEFAULTS = {
    "vibration_rms": 0.0, "band_low": 5.0, "band_high": 150.0, "tone_frequency": 0.0, "tone_amplitude": 0.0,
    "touchdown_peak": 0.0, "touchdown_frequency": 12.0, "touchdown_decay": 0.15,
}

_EVENT_SCHEMA: dict[str, dict[str, QuantitySpec]] = {
    "gust": {
        "at": QuantitySpec("s", **_NONNEG),
        "peak": QuantitySpec("m/s^2", **_POS, upper=490.0),
        "duration": QuantitySpec("s", **_POS),
        "frequency": _opt("Hz", **_POS),
    },
    "link_outage": {"at": QuantitySpec("s", **_NONNEG), "duration": QuantitySpec("s", **_POS)},
    "sensor_fault": {"at": QuantitySpec("s", **_NONNEG), "duration": QuantitySpec("s", **_POS)},
    "rearm": {"at": QuantitySpec("s", **_NONNEG)},
    "battery_load": {
        "at": QuantitySpec("s", **_NONNEG),
        "duration": QuantitySpec("s", **_POS),
        "current": QuantitySpec("A", **_POS, upper=1.0),
    },
}

_RIG_SCHEMA = {
    "battery_initial_voltage": _opt("V", **_POS, upper=5.0),
    "z3_noise": _opt("m", **_NONNEG),
    "accel_noise": _opt("m/s^2", **_NONNEG),
    "v_patch_noise": _opt("V", **_NONNEG),
    "env_rate": _opt("Hz", lower=100.0, upper=20_000.0),
    "watchdog": _opt("s", **_POS),
}
_RIG_DEFAULTS = {
    "battery_initial_voltage": 3.0, "z3_noise": 2.0e-6, "accel_noise": 0.02, "v_patch_noise": 1.0e-4,
    "env_rate": 1000.0, "watchdog": 0.1,
}
_RIG_PLAIN = ("params", "deviations", "effects", "effect_params", "coupling")


@dataclass(frozen=True)
class Phase:
    """One consecutive phase of the scenario. Times in s, accelerations in m/s^2, frequencies in Hz.

    ``ground``/``flight``: band-limited random base vibration (``vibration_rms`` over ``band_low``..``band_high``)
    plus an optional tone. ``landing``: the same plus a touchdown transient (a decaying sine of
    ``touchdown_peak`` at ``touchdown_frequency`` with time constant ``touchdown_decay``) at the phase start.
    ``maintenance``: external high-voltage equipment present (``hv_present``) for the whole phase.
    """

    name: str
    kind: str
    start: float
    duration: float
    vibration_rms: float = 0.0
    band_low: float = 5.0
    band_high: float = 150.0
    tone_frequency: float = 0.0
    tone_amplitude: float = 0.0
    touchdown_peak: float = 0.0
    touchdown_frequency: float = 12.0
    touchdown_decay: float = 0.15

    @property
    def end(self) -> float:
        return self.start + self.duration

    @property
    def hv_present(self) -> bool:
        return self.kind == "maintenance"


@dataclass(frozen=True)
class ScenarioEvent:
    """Something that happens at time ``at`` (s).

    ``gust``: an abnormal base-acceleration load of ``peak`` (m/s^2) lasting ``duration`` (s): a 1−cos pulse, or a
    Hann-windowed sine burst at ``frequency`` (Hz) if given. ``link_outage``: every link exchange fails for
    ``duration``. ``sensor_fault``: the rig's sensors misbehave for ``duration`` (``mode``: nan, flag, frozen_seq,
    out_of_range). ``rearm``: the operator sends the re-arm command. ``battery_load``: an extra ``current`` (A) drawn
    from the board battery for ``duration`` (a failing component).
    """

    kind: str
    at: float
    duration: float = 0.0
    peak: float = 0.0
    frequency: float = 0.0
    current: float = 0.0
    mode: str = ""

    @property
    def end(self) -> float:
        return self.at + self.duration


@dataclass(frozen=True)
class RigSpec:
    """The simulated rig of a scenario (see :class:`hil_stub.rig.SimulatedRig`)."""

    params: str = "table2"
    deviations: Mapping[str, float] = field(default_factory=dict)
    effects: tuple[str, ...] = ()
    effect_params: Mapping[str, float] = field(default_factory=dict)
    coupling: str = "coupled"
    battery_initial_voltage: float = 3.0  # V
    z3_noise: float = 2.0e-6  # m (1 sigma)
    accel_noise: float = 0.02  # m/s^2 (1 sigma)
    v_patch_noise: float = 1.0e-4  # V (1 sigma)
    env_rate: float = 1000.0  # Hz, base-acceleration sample rate
    watchdog: float = 0.1  # s without a board command -> the rig zeroes the HV demand


LIFE_LAW_KINDS = ("constant", "linear", "exponential", "power", "step")
#: per law kind: its quantities (besides ``parameter`` and ``kind``); relative deviations are in "1"
_LIFE_LAW_SCHEMA: dict[str, dict[str, QuantitySpec]] = {
    "constant": {"value": QuantitySpec("1", lower=DEVIATION_RANGE[0], upper=DEVIATION_RANGE[1])},
    "linear": {"rate": QuantitySpec("1/h", lower=-1.0, upper=1.0), "start": _opt("h", **_NONNEG)},
    "exponential": {"amplitude": QuantitySpec("1", lower=-5.0, upper=5.0),
                    "time_constant": QuantitySpec("h", **_POS), "start": _opt("h", **_NONNEG)},
    "power": {"amplitude": QuantitySpec("1", lower=-5.0, upper=5.0), "exponent": QuantitySpec("1", **_POS, upper=10.0),
              "reference": QuantitySpec("h", **_POS), "start": _opt("h", **_NONNEG)},
    "step": {"size": QuantitySpec("1", lower=DEVIATION_RANGE[0], upper=DEVIATION_RANGE[1]),
             "at": QuantitySpec("h", **_NONNEG)},
}
_LIFE_SCHEMA = {
    "visits": QuantitySpec("1", integer=True, lower=1, upper=1000),
    "visit_interval": QuantitySpec("h", **_POS),
    "first_visit": _opt("h", **_NONNEG),
    "flights_between_visits": _opt("1", integer=True, lower=0, upper=100_000),
    "tick_flights": _opt("1", integer=True, lower=0, upper=1000),
}


@dataclass(frozen=True)
class LifeLaw:
    """One term of a parameter's degradation law: a relative deviation d(h) against operating time h (hours).

    ``constant``: d = value. ``linear``: d = rate·(h − start)⁺. ``exponential``: d = amplitude·(exp((h − start)⁺ /
    time_constant) − 1). ``power``: d = amplitude·((h − start)⁺ / reference)^exponent (crack-growth-like).
    ``step``: d = size for h ≥ at (sudden damage). Terms of the same parameter add up.
    """

    parameter: str
    kind: str
    value: float = 0.0
    rate: float = 0.0
    amplitude: float = 0.0
    time_constant: float = 1.0
    exponent: float = 1.0
    reference: float = 1.0
    size: float = 0.0
    at: float = 0.0
    start: float = 0.0


@dataclass(frozen=True)
class LifeSpec:
    """Many maintenance visits over an operating life (``[life]``): the scenario's phases are one visit, played
    at operating hours ``first_visit + i·visit_interval`` (i = 0 … visits−1) on a truth plant whose deviations
    follow ``laws``; the ``flights_between_visits`` are summarised (logged), not ticked — unless ``tick_flights``
    > 0: then that many flights (the phases of ``flight_scenario`` before its first maintenance phase, with their
    events) are ticked by the board before every visit after the first, and their usage is summarised in the log."""

    visits: int
    visit_interval: float  # h of operating time between visits
    first_visit: float = 0.0  # h
    flights_between_visits: int = 0
    laws: tuple[LifeLaw, ...] = ()
    tick_flights: int = 0  # flights ticked by the board before each visit after the first (0: summarised only)
    flight_scenario: str = "default"  # whose phases before its first maintenance phase make one ticked flight

    def visit_hours(self) -> list[float]:
        return [self.first_visit + i * self.visit_interval for i in range(self.visits)]


@dataclass(frozen=True)
class Scenario:
    name: str
    description: str
    seed: int
    phases: tuple[Phase, ...]
    events: tuple[ScenarioEvent, ...]
    rig: RigSpec
    board_overrides: Mapping[str, Any] = field(default_factory=dict)
    expect_verdict: str | None = None
    source: str = "<memory>"
    life: LifeSpec | None = None  # [life]: many visits over an operating life (docs/scenarios.md)

    @property
    def duration(self) -> float:
        """Total length (s): the end of the last phase."""
        return self.phases[-1].end if self.phases else 0.0

    def phase_at(self, t: float) -> Phase | None:
        for ph in self.phases:
            if ph.start <= t < ph.end:
                return ph
        return None

    def events_of(self, kind: str) -> tuple[ScenarioEvent, ...]:
        return tuple(e for e in self.events if e.kind == kind)

    def hv_intervals(self) -> list[tuple[float, float]]:
        """Time intervals (s) with external HV equipment present."""
        return [(p.start, p.end) for p in self.phases if p.hv_present]

    def with_rig(self, **changes: Any) -> Scenario:
        from dataclasses import replace

        return replace(self, rig=replace(self.rig, **changes))


def available_scenarios() -> list[str]:
    """Names of the scenarios shipped in ``board_config/scenarios``."""
    return sorted(p.stem for p in SCENARIO_DIR.glob("*.toml"))


def resolve_scenario_file(name_or_path: str | Path) -> Path:
    """The scenario file of a shipped name (``aging``) or a path. A bare name that is also a directory here (a run's
    ``--out aging``) still means the shipped scenario: a directory is never a scenario file."""
    text = str(name_or_path)
    candidate = Path(text)
    shipped = SCENARIO_DIR / f"{text}.toml"
    if candidate.is_dir():
        name = text.rstrip("/")  # (a shell completes a directory's name with a slash)
        if name and "/" not in name and (SCENARIO_DIR / f"{name}.toml").is_file():
            return SCENARIO_DIR / f"{name}.toml"
        raise ConfigError(text, "-", "is a directory, not a scenario file (give a .toml file or a shipped name: "
                                     f"{', '.join(available_scenarios())})")
    if text.endswith(".toml") or "/" in text or candidate.exists():
        return candidate
    if not shipped.exists():
        raise ConfigError(text, "-", f"unknown scenario (shipped: {', '.join(available_scenarios())}; "
                                     "or give a path to a .toml file)")
    return shipped


def _plain_str(file: str, key: str, value: Any, allowed: tuple[str, ...] | None = None) -> str:
    if not isinstance(value, str) or not value:
        raise ConfigError(file, key, f"expected a non-empty string, got {value!r}")
    if allowed is not None and value not in allowed:
        raise ConfigError(file, key, f"unknown value {value!r} (allowed: {', '.join(allowed)})")
    return value


def _number_map(file: str, key: str, value: Any) -> dict[str, float]:
    if not isinstance(value, Mapping):
        raise ConfigError(file, key, "expected a table of name = number")
    out = {}
    for k, v in value.items():
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise ConfigError(file, f"{key}.{k}", f"expected a number, got {v!r}")
        out[str(k)] = float(v)
    return out


def _parse_rig(file: str, table: Any) -> RigSpec:
    if table is None:
        return RigSpec()
    if not isinstance(table, Mapping):
        raise ConfigError(file, "rig", "expected a table")
    plain = {k: v for k, v in table.items() if k in _RIG_PLAIN}
    quant = {k: v for k, v in table.items() if k not in _RIG_PLAIN}
    unknown = set(quant) - set(_RIG_SCHEMA)
    if unknown:
        raise ConfigError(file, f"rig.{sorted(unknown)[0]}",
                          f"unknown key (known: {', '.join(sorted([*_RIG_PLAIN, *_RIG_SCHEMA]))})")
    vals, _ = parse_quantities(file, "rig", quant, _RIG_SCHEMA)
    kw: dict[str, Any] = {**_RIG_DEFAULTS, **vals}
    if "params" in plain:
        kw["params"] = _plain_str(file, "rig.params", plain["params"])
    if "coupling" in plain:
        kw["coupling"] = _plain_str(file, "rig.coupling", plain["coupling"], ("coupled", "paper", "none"))
    if "deviations" in plain:
        devs = _number_map(file, "rig.deviations", plain["deviations"])
        for k, d in devs.items():
            if (reason := deviation_problem(k, d)) is not None:
                raise ConfigError(file, f"rig.deviations.{k}", reason)
        kw["deviations"] = MappingProxyType(devs)
    if "effect_params" in plain:
        kw["effect_params"] = MappingProxyType(_number_map(file, "rig.effect_params", plain["effect_params"]))
    if "effects" in plain:
        eff = plain["effects"]
        if not isinstance(eff, list) or not all(isinstance(e, str) and e for e in eff):
            raise ConfigError(file, "rig.effects", "expected an array of effect names or dotted paths")
        kw["effects"] = tuple(eff)
    return RigSpec(**kw)


def parse_scenario(data: Mapping[str, Any], file: str, default_name: str = "scenario") -> Scenario:
    """Validate a parsed scenario mapping; errors name the file, the dotted key and the reason."""
    unknown = set(data) - {"scenario", "rig", "board", "phase", "event", "life"}
    if unknown:
        raise ConfigError(file, sorted(unknown)[0],
                          "unknown section (expected scenario, rig, board, phase, event, life)")
    head = data.get("scenario", {})
    if not isinstance(head, Mapping):
        raise ConfigError(file, "scenario", "expected a table")
    extra = set(head) - {"name", "description", "seed", "expect_verdict"}
    if extra:
        raise ConfigError(file, f"scenario.{sorted(extra)[0]}",
                          "unknown key (known: name, description, seed, expect_verdict)")
    name = _plain_str(file, "scenario.name", head.get("name", default_name))
    description = head.get("description", "")
    if not isinstance(description, str):
        raise ConfigError(file, "scenario.description", "expected a string")
    seed = head.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ConfigError(file, "scenario.seed", f"expected a non-negative integer, got {seed!r}")
    expect = head.get("expect_verdict")
    if expect is not None:
        expect = _plain_str(file, "scenario.expect_verdict", expect, VERDICTS)

    raw_phases = data.get("phase", [])
    if not isinstance(raw_phases, list) or not raw_phases:
        raise ConfigError(file, "phase", "expected at least one [[phase]] table")
    phases: list[Phase] = []
    t = 0.0
    for i, entry in enumerate(raw_phases):
        where = f"phase[{i}]"
        if not isinstance(entry, Mapping):
            raise ConfigError(file, where, "expected a table")
        kind = _plain_str(file, f"{where}.kind", entry.get("kind"), PHASE_KINDS)
        pname = _plain_str(file, f"{where}.name", entry.get("name", f"{kind}-{i}"))
        quant = {k: v for k, v in entry.items() if k not in ("kind", "name")}
        vals, _ = parse_quantities(file, where, quant, _PHASE_SCHEMA[kind])
        kw = {k: _PHASE_DEFAULTS[k] for k in _PHASE_SCHEMA[kind] if k in _PHASE_DEFAULTS}
        kw.update(vals)
        if kw.get("band_high", 1.0) <= kw.get("band_low", 0.0):
            raise ConfigError(file, f"{where}.band_high", f"must exceed band_low ({kw['band_low']:g} Hz)")
        phases.append(Phase(name=pname, kind=kind, start=t, **kw))
        t += float(vals["duration"])

    raw_events = data.get("event", [])
    if not isinstance(raw_events, list):
        raise ConfigError(file, "event", "expected an array of tables [[event]]")
    events: list[ScenarioEvent] = []
    for i, entry in enumerate(raw_events):
        where = f"event[{i}]"
        if not isinstance(entry, Mapping):
            raise ConfigError(file, where, "expected a table")
        kind = _plain_str(file, f"{where}.kind", entry.get("kind"), EVENT_KINDS)
        mode = ""
        quant = {k: v for k, v in entry.items() if k not in ("kind", "mode")}
        if kind == "sensor_fault":
            mode = _plain_str(file, f"{where}.mode", entry.get("mode", "nan"), SENSOR_FAULT_MODES)
        elif "mode" in entry:
            raise ConfigError(file, f"{where}.mode", f"'mode' applies to sensor_fault events only, not {kind}")
        vals, _ = parse_quantities(file, where, quant, _EVENT_SCHEMA[kind])
        if vals["at"] > t:
            raise ConfigError(file, f"{where}.at", f"event at {vals['at']:g} s is after the end of the last phase "
                                                   f"({t:g} s)")
        events.append(ScenarioEvent(kind=kind, mode=mode, **{k: float(v) for k, v in vals.items()}))
    events.sort(key=lambda e: e.at)

    board = data.get("board", {})
    if not isinstance(board, Mapping):
        raise ConfigError(file, "board", "expected a table of board.toml sections")
    return Scenario(name=name, description=description, seed=int(seed), phases=tuple(phases),
                    events=tuple(events), rig=_parse_rig(file, data.get("rig")),
                    board_overrides=MappingProxyType(dict(board)), expect_verdict=expect, source=file,
                    life=_parse_life(file, data["life"]) if "life" in data else None)


def _parse_life(file: str, table: Any) -> LifeSpec:
    """``[life]`` with ``[[life.law]]`` terms (see :class:`LifeSpec`, :class:`LifeLaw`, docs/scenarios.md)."""
    if not isinstance(table, Mapping):
        raise ConfigError(file, "life", "expected a table")
    quant = {k: v for k, v in table.items() if k not in ("law", "flight_scenario")}
    unknown = set(quant) - set(_LIFE_SCHEMA)
    if unknown:
        raise ConfigError(file, f"life.{sorted(unknown)[0]}",
                          f"unknown key (known: {', '.join(sorted([*_LIFE_SCHEMA, 'law', 'flight_scenario']))})")
    flight_scenario = _plain_str(file, "life.flight_scenario", table.get("flight_scenario", "default"))
    vals, _ = parse_quantities(file, "life", quant, _LIFE_SCHEMA)
    raw = table.get("law", [])
    if not isinstance(raw, list):
        raise ConfigError(file, "life.law", "expected an array of tables [[life.law]]")
    laws = []
    for i, entry in enumerate(raw):
        where = f"life.law[{i}]"
        if not isinstance(entry, Mapping):
            raise ConfigError(file, where, "expected a table")
        param = _plain_str(file, f"{where}.parameter", entry.get("parameter"))
        kind = _plain_str(file, f"{where}.kind", entry.get("kind"), LIFE_LAW_KINDS)
        q = {k: v for k, v in entry.items() if k not in ("parameter", "kind")}
        lv, _ = parse_quantities(file, where, q, _LIFE_LAW_SCHEMA[kind])
        laws.append(LifeLaw(parameter=param, kind=kind, **{k: float(v) for k, v in lv.items()}))
    return LifeSpec(visits=int(vals["visits"]), visit_interval=float(vals["visit_interval"]),
                    first_visit=float(vals.get("first_visit", 0.0)),
                    flights_between_visits=int(vals.get("flights_between_visits", 0)), laws=tuple(laws),
                    tick_flights=int(vals.get("tick_flights", 0)), flight_scenario=flight_scenario)


def load_scenario(name_or_path: str | Path) -> Scenario:
    """A shipped scenario by name (``default``, ``maintenance``, ...) or a TOML file path."""
    path = resolve_scenario_file(name_or_path)
    return parse_scenario(read_toml(path), str(path), default_name=path.stem)
