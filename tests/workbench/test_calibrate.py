"""Calibration to the paper's stated numbers: the shipped `calibrated` set and the fitting path."""

from __future__ import annotations

import json

import pytest

from board_config import load_parameter_set
from plant import PlantModel
from plant.linear import static_tip_gain_closed_form
from shm_cli.main import main
from workbench.fit import ClaimTarget, calibrate, load_claim_targets
from workbench.fit._calibrate import model_figures


def _figures(name: str):
    ps = load_parameter_set(name)
    act, oc = PlantModel(ps), PlantModel(ps, terminal="open_circuit")
    return model_figures(act, oc, act.p_nominal)


def test_shipped_calibrated_set_meets_what_it_claims():
    cal, t2 = _figures("calibrated"), _figures("table2")
    assert cal.first_resonance_Hz == pytest.approx(5.8, rel=0.01)
    assert cal.second_resonance_Hz == pytest.approx(37.0, rel=0.01)
    assert cal.rc_pole_Hz == pytest.approx(10.0, rel=0.01)
    assert cal.static_tip_gain_m_per_V == pytest.approx(t2.static_tip_gain_m_per_V, rel=0.01)
    assert min(cal.damping_ratios) >= 0.0099
    # honest: the harvesting gains stay far below the paper's 35 / 68 V/g (documented in paper-reproduction.md)
    assert cal.harvest_gain_first_V_per_g < 0.1 * 35.0
    assert cal.harvest_gain_second_V_per_g < 0.1 * 68.0
    # but it is more than table2 gives at its own resonances
    assert cal.harvest_gain_first_V_per_g > t2.harvest_gain_first_V_per_g


def test_measured_masses_and_patch_electrics_are_not_touched():
    cal, t2 = load_parameter_set("calibrated"), load_parameter_set("table2")
    for key in ("m1", "m2", "m3", "R_ep", "C_ep", "alpha_h", "beta_h", "A_h", "n_h", "gamma_h"):
        assert cal.values[key] == t2.values[key], key


def test_fitting_stiffnesses_places_the_two_resonances():
    base = load_parameter_set("table2")
    targets = [ClaimTarget("first_resonance_Hz", 5.8, "Hz", 1.0, "test"),
               ClaimTarget("second_resonance_Hz", 37.0, "Hz", 1.0, "test")]
    res = calibrate(base, targets, free=("k1", "k2", "k3"))
    assert res.success
    assert res.final.first_resonance_Hz == pytest.approx(5.8, rel=1e-3)
    assert res.final.second_resonance_Hz == pytest.approx(37.0, rel=1e-3)
    assert res.history[-1] < res.history[0]
    for key in ("m1", "d_ep", "c1"):
        assert res.params.values[key] == base.values[key]


def test_claims_file_targets_and_bad_free_parameter():
    base = load_parameter_set("table2")
    targets = load_claim_targets(static_gain_m_per_v=static_tip_gain_closed_form(PlantModel(base)))
    assert {t.name for t in targets} >= {"first_resonance_Hz", "harvest_gain_first_V_per_g", "static_tip_gain_m_per_V"}
    with pytest.raises(ValueError, match="free parameter 'k9'"):
        calibrate(base, targets, free=("k9",))
    with pytest.raises(ValueError, match="positive to be fitted"):
        calibrate(base, targets, free=("gamma_h",))


def test_cli_calibrate_saves_a_loadable_set(tmp_path, capsys):
    save = tmp_path / "mine.toml"
    rc = main(["calibrate", "--params", "table2", "--free", "k1", "k2", "k3", "--save", str(save),
               "--out", str(tmp_path / "out"), "--json"])
    summary = json.loads(capsys.readouterr().out)
    assert rc == 0 and summary["success"]
    assert (tmp_path / "out" / "calibration.png").stat().st_size > 0
    loaded = load_parameter_set(save)
    assert loaded.name == "calibrated"
    first = next(r for r in summary["claims_table"] if r["claim"] == "first_resonance_Hz")
    assert abs(first["rel_error_calibrated"]) < 0.01
    assert main(["calibrate", "--params", "table2", "--min-damping", "2", "--out", str(tmp_path)]) == 2
