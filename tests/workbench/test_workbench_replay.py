"""Replay: free run reproduces the truth when model = truth; the k-step predictor; FRF replay; errors."""

from __future__ import annotations

import numpy as np
import pytest

from plant import PlantModel
from workbench.compare import fit_percent
from workbench.records import record_from_arrays
from workbench.simulation import model_for, replay, replay_frf, synth_frf, synth_record, synth_test, truth_model
from workbench.simulation._replay import ReplayError


@pytest.fixture(scope="module")
def nominal() -> PlantModel:
    return truth_model("table2")


def test_free_run_equals_truth_without_noise(nominal: PlantModel) -> None:
    rec = synth_record(synth_test("mbit-b"), nominal, noise={"z3": 0.0}, seed=0)
    rep = replay(model_for(rec, "table2"), rec, predict=False)
    cr = rep.channels["z3"]
    assert cr.model_output == "z3_meas" and cr.unit == "m"
    # same model, same inputs: identical up to integrator tolerance (and the 10-digit CSV-free in-memory path)
    assert np.max(np.abs(cr.residual)) < 1e-5 * np.max(np.abs(cr.measured))
    assert rep.drive_name == "va" and np.max(rep.drive) == pytest.approx(300.0)
    assert "prediction not requested" in rep.prediction_note


def test_prediction_is_labelled_and_tracks_the_measurement(nominal: PlantModel) -> None:
    rec = synth_record(synth_test("mbit-a", duration_s=10.0), nominal, seed=4)
    rep = replay(model_for(rec, "table2"), rec, horizon_s=0.05, interval_s=0.01)
    p = rep.prediction
    assert p is not None and p.steps == 5 and p.interval_s == pytest.approx(0.01)
    assert "5-step-ahead prediction" in p.label and "observer" in p.method
    assert fit_percent(p.measured["z3"], p.predicted["z3"]) > 99.0
    assert p.t[0] == pytest.approx(0.05) and np.all(np.diff(p.t) > 0)


def test_prediction_absorbs_a_slow_error_the_free_run_keeps(nominal: PlantModel) -> None:
    """An offset on the measurement: the free run keeps it, the observer's corrections remove most of it."""
    rec = synth_record(synth_test("mbit-a", duration_s=10.0), nominal, seed=5)
    shifted = record_from_arrays(rec.t, {"v_ch1_V": rec["v_ch1"], "v_ch2_V": rec["v_ch2"],
                                         "z3_m": rec["z3"] + 80e-6}, {"test": "mbit-a"})
    rep = replay(model_for(shifted, "table2"), shifted)
    free = np.sqrt(np.mean(rep.channels["z3"].residual ** 2))
    pred = np.sqrt(np.mean((rep.prediction.measured["z3"] - rep.prediction.predicted["z3"]) ** 2))
    assert free > 75e-6 and pred < 0.5 * free


def test_prediction_unavailable_is_explained(nominal: PlantModel) -> None:
    t = np.arange(30) * 1e-3
    rec = record_from_arrays(t, {"v_ch1_V": 10 * t, "z3_m": 0 * t}, {})
    rep = replay(model_for(rec, "table2"), rec)
    assert rep.prediction is None and "too short" in rep.prediction_note


def test_channel_without_model_output_and_terminal_mismatch(nominal: PlantModel) -> None:
    t = np.arange(100) * 1e-3
    rec = record_from_arrays(t, {"v_ch1_V": t, "strain_1": t}, {})
    with pytest.raises(ReplayError, match=r"channel 'strain' matches no model output.*model_output"):
        replay(nominal, rec)
    rec2 = record_from_arrays(t, {"v_ch1_V": t, "z3_m": t}, {"terminal": "open_circuit"})
    with pytest.raises(ReplayError, match=r"terminal 'open_circuit'.*model's terminal is 'amplifier'"):
        replay(nominal, rec2)
    rec3 = record_from_arrays(t, {"v_ch1_V": t, "z3_m": t}, {"channels": {"z3_m": {"model_output": "z9"}}})
    with pytest.raises(ReplayError, match="declares model_output 'z9'"):
        replay(nominal, rec3)


def test_frf_replay_matches_truth_table(nominal: PlantModel) -> None:
    spec = synth_test("frf", f0_hz=5.0, f1_hz=40.0, n_freqs=6)
    table = synth_frf(spec, nominal, noise_rel=0.0, noise_phase_deg=0.0)
    rep = replay_frf(model_for(table, "table2"), table)
    np.testing.assert_allclose(rep.modelled["z3"], rep.measured["z3"], rtol=1e-6)
    # the first bending mode (17 Hz) shows as a peak with about -90° phase
    k = np.argmax(np.abs(rep.measured["z3"]))
    assert 10.0 < table.frequency_Hz[k] < 25.0
