"""board_config: Table 2 exactly as printed; loader errors name file, key and reason."""

from __future__ import annotations

import math
import re
from pathlib import Path

import pytest

from board_config import (
    CORE_PARAMETER_NAMES,
    ConfigError,
    EffectEntry,
    load_mfc_limits,
    load_monitor_settings,
    load_parameter_set,
)

TABLE2_AS_PRINTED = {
    "R_ep": 1500, "C_ep": 1.06e-5, "d_ep": 1.37e-5, "m1": 1.16e-3, "m2": 2.32e-3, "m3": 1.39e-3,
    "k1": 332.98, "k2": 125.40, "k3": 21.28, "c1": 0.098, "c2": 0.020, "c3": 0.025,
    "alpha_h": 0.605, "A_h": -1, "n_h": 1, "beta_h": 8.307, "gamma_h": 0,
}


def test_table2_exactly_as_printed():
    ps = load_parameter_set("table2")
    assert dict(ps.values) == pytest.approx(TABLE2_AS_PRINTED, rel=0, abs=0)
    assert ps.details["beta_h"]["printed_unit"] == "V^-n"
    assert ps.details["k3"]["method"] == "MEM"


def test_tables_1_and_3():
    lim = load_mfc_limits()
    assert (lim.voltage_min, lim.voltage_max) == (-500.0, 1500.0)
    assert lim.clamp_voltage(-600.0) == -500.0 and lim.clamp_voltage(2000.0) == 1500.0
    mon = load_monitor_settings()
    assert (mon.f_mon, mon.eps_th, mon.count_max, mon.counter_up, mon.counter_down) == (100.0, 0.225, 200, 2, 1)
    assert mon.e0z == 0.75e-3 and mon.kerr_z == 0.075


def _write_variant(tmp_path: Path, pattern: str, replacement: str) -> Path:
    text = (Path(__file__).parents[2] / "board_config" / "params" / "table2.toml").read_text()
    new, n = re.subn(pattern, replacement, text, flags=re.M)
    assert n == 1, pattern
    path = tmp_path / "variant.toml"
    path.write_text(new)
    return path


@pytest.mark.parametrize(
    ("pattern", "replacement", "key", "reason"),
    [
        (r"^k3 .*$", "", "parameters.k3", "missing required key"),
        (r"^(gamma_h .*)$", r'\1\nk4 = { value = 1.0, unit = "N/m" }', "parameters.k4", "unknown key"),
        (r"value = 21\.28", 'value = "stiff"', "parameters.k3.value", "expected a number"),
        (r"value = 1\.16e-3", "value = 0.0", "parameters.m1.value", "outside the allowed range"),
        (r"value = 332\.98", "value = -332.98", "parameters.k1.value", "outside the allowed range"),
        (r"value = 1\.06e-5", "value = -1.06e-5", "parameters.C_ep.value", "outside the allowed range"),
        (r"value = 0\.098", "value = nan", "parameters.c1.value", "must be finite"),
        (r'unit = "N/m",   method = "MEM", definition = "Stiffness related to tip',
         'unit = "kN/m",   method = "MEM", definition = "Stiffness related to tip', "parameters.k3.unit",
         "expected unit 'N/m'"),
        (r"value = 0\.605", "value = true", "parameters.alpha_h.value", "expected a number"),
        (r"value = 0\.605", "value = 1.5", "parameters.alpha_h.value", "outside the allowed range"),
    ],
)
def test_bad_parameter_files_name_file_key_and_reason(tmp_path, pattern, replacement, key, reason):
    path = _write_variant(tmp_path, pattern, replacement)
    with pytest.raises(ConfigError) as err:
        load_parameter_set(path)
    assert err.value.file == str(path)
    assert err.value.key == key
    assert reason in err.value.reason
    assert str(path) in str(err.value) and key in str(err.value)


def test_not_toml_and_missing_file(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[parameters\nk1 = 3")
    with pytest.raises(ConfigError, match="not valid TOML"):
        load_parameter_set(bad)
    with pytest.raises(ConfigError, match="file not found"):
        load_parameter_set(tmp_path / "absent.toml")
    with pytest.raises(ConfigError, match="unknown parameter set"):
        load_parameter_set("no_such_set")


def test_round_trip_with_effects(tmp_path):
    ps = load_parameter_set("table2").with_values(name="mine", k3=20.0)
    ps = ps.with_effects((EffectEntry("tip_support", {"k_tip": 3.5}, {"k_tip": "N/m"}),))
    path = tmp_path / "mine.toml"
    path.write_text(ps.to_toml())
    back = load_parameter_set(path)
    assert back.name == "mine"
    assert back.values["k3"] == 20.0
    assert all(math.isclose(back.values[k], ps.values[k], rel_tol=0, abs_tol=0) for k in CORE_PARAMETER_NAMES)
    assert back.effects[0].name == "tip_support" and back.effects[0].parameters["k_tip"] == 3.5
    assert back.effects[0].units["k_tip"] == "N/m"


def test_with_values_validates():
    ps = load_parameter_set("table2")
    with pytest.raises(ConfigError, match="outside the allowed range"):
        ps.with_values(m2=-1.0)
    with pytest.raises(ConfigError, match="unknown core parameter"):
        ps.with_values(k9=1.0)
