"""Board configuration and scenario files: shipped files load; every bad input names file, key and reason."""

from __future__ import annotations

import copy

import pytest

from board_config import ConfigError
from board_config.board import DEFAULT_BOARD_FILE, load_board_config
from board_config.quantities import read_toml
from board_config.scenario import available_scenarios, load_scenario, parse_scenario


def test_shipped_board_config():
    c = load_board_config()
    assert c.tick_rate == 100.0 and c.tick_period == 0.01
    assert c.maintenance_sequence == ("a", "b")
    assert c.sensing_exceedance_levels == (0.5e-3, 1e-3, 2e-3, 4e-3)
    assert c.power_wake_min_voltage >= c.power_brownout_voltage + c.power_brownout_hysteresis
    assert c.ticks(c.sensing_quiet_period) == 1000


def _write(tmp_path, data_text):
    p = tmp_path / "board.toml"
    p.write_text(data_text)
    return p


def _mutated(tmp_path, old, new):
    text = DEFAULT_BOARD_FILE.read_text()
    assert old in text
    return _write(tmp_path, text.replace(old, new, 1))


@pytest.mark.parametrize(("old", "new", "key", "reason"), [
    ('rate            = { value = 100.0, unit = "Hz"', 'rate            = { value = 100.0, unit = "kHz"',
     "tick.rate.unit", "expected unit 'Hz'"),
    ('quiet_period        = { value = 10.0,', 'quiet_period        = { value = -1.0,',
     "sensing.quiet_period.value", "outside the allowed range"),
    ('debounce_ticks    = { value = 2,', 'debounce_ticks    = { value = 2.5,', "wake.debounce_ticks.value",
     "expected an integer"),
    ('sequence    = ["a", "b"]', 'sequence    = ["a", "c"]', "maintenance.sequence[1]", "unknown value 'c'"),
    ('value = [0.5e-3, 1.0e-3, 2.0e-3, 4.0e-3]', 'value = [0.5e-3, 2.0e-3, 1.0e-3]',
     "sensing.exceedance_levels.value", "strictly increasing"),
    ('wake_min_voltage    = { value = 2.70,', 'wake_min_voltage    = { value = 2.35,', "power.wake_min_voltage",
     "at least brownout_voltage"),
    ('[log]', '[logs]', "logs", "unknown section"),
])
def test_bad_board_config_names_key_and_reason(tmp_path, old, new, key, reason):
    p = _mutated(tmp_path, old, new)
    with pytest.raises(ConfigError) as exc:
        load_board_config(p)
    msg = str(exc.value)
    assert str(p) in msg and key in msg and reason in msg


def test_unknown_key_and_overrides(tmp_path):
    p = _mutated(tmp_path, "[safe]\n", "[safe]\nbogus = { value = 1, unit = \"s\" }\n")
    with pytest.raises(ConfigError, match=r"safe\.bogus.*unknown key"):
        load_board_config(p)
    c = load_board_config(overrides={"sensing": {"quiet_period": {"value": 3.0, "unit": "s"}}})
    assert c.sensing_quiet_period == 3.0
    with pytest.raises(ConfigError, match=r"scen\.toml: key 'board\.power\.current_sensing\.unit'"):
        load_board_config(overrides={"power": {"current_sensing": {"value": 3.0, "unit": "mA"}}},
                          overrides_source="scen.toml")
    with pytest.raises(ConfigError, match=r"board\.radio"):
        load_board_config(overrides={"radio": {}}, overrides_source="scen.toml")


def test_shipped_scenarios_load():
    names = available_scenarios()
    assert {"default", "maintenance", "degraded", "faults"} <= set(names)
    for n in names:
        s = load_scenario(n)
        assert s.duration > 0 and s.phases
        load_board_config(overrides=s.board_overrides, overrides_source=s.source)
    d = load_scenario("default")
    assert d.expect_verdict == "PASS" and d.duration == pytest.approx(1350.0)
    assert [p.kind for p in d.phases].count("maintenance") == 1
    m = load_scenario("maintenance")
    assert m.duration <= 180.0  # "a few minutes of real time at most"
    assert load_scenario("degraded").expect_verdict == "FAULT"


BASE = read_toml(load_scenario("faults").source)


@pytest.mark.parametrize(("mutate", "key", "reason"), [
    (lambda d: d["phase"][0].__setitem__("kind", "cruise"), "phase[0].kind", "unknown value 'cruise'"),
    (lambda d: d["phase"][0]["vibration_rms"].__setitem__("unit", "g"), "phase[0].vibration_rms.unit",
     "expected unit 'm/s^2'"),
    (lambda d: d["event"][0]["at"].__setitem__("value", 1e6), "event[0].at", "after the end of the last phase"),
    (lambda d: d["event"][0].__setitem__("kind", "meteor"), "event[0].kind", "unknown value 'meteor'"),
    (lambda d: d["event"][2].__setitem__("mode", "melted"), "event[2].mode", "unknown value 'melted'"),
    (lambda d: d["rig"].__setitem__("deviations", {"k3": -2.0}), "rig.deviations.k3", "outside the allowed range"),
    (lambda d: d["rig"].__setitem__("coupling", "magic"), "rig.coupling", "unknown value 'magic'"),
    (lambda d: d["rig"].__setitem__("battery", 1), "rig.battery", "unknown key"),
    (lambda d: d["scenario"].__setitem__("seed", -1), "scenario.seed", "non-negative integer"),
    (lambda d: d["scenario"].__setitem__("expect_verdict", "MAYBE"), "scenario.expect_verdict", "unknown value"),
    (lambda d: d.__setitem__("phase", []), "phase", "at least one"),
])
def test_bad_scenarios_name_key_and_reason(mutate, key, reason):
    data = copy.deepcopy(BASE)
    mutate(data)
    with pytest.raises(ConfigError) as exc:
        parse_scenario(data, "bad.toml")
    msg = str(exc.value)
    assert "bad.toml" in msg and key in msg and reason in msg, msg


def test_unknown_scenario_name_lists_the_shipped_ones():
    with pytest.raises(ConfigError, match=r"shipped: .*default"):
        load_scenario("no-such-scenario")
