"""Honest intervals (issue 26 point 6): with the right model the Jacobian's 95 % intervals cover the truth, also on
correlated (AR(1), ρ = 0.95) laser noise; when the fitted model leaves more than the noise the intervals come from a
moving-block bootstrap over the record (``workbench.fit._bootstrap``), wider where the Jacobian's miss the truth, and
the report says the model does not explain the record yet."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from plant.effect import Parameter, PhysicalEffect, load_effect_file
from plant.layout import B_FM, B_ZD
from workbench.fit import fit_records
from workbench.fit._bootstrap import block_length, block_weights, bootstrap_refit, decorrelation_lag
from workbench.simulation import synth_record, synth_test, truth_model

NOISE = 2e-6
FOREIGN_FILE = Path(__file__).parents[1] / "workbench_foreign_effects.py"


@settings(max_examples=40, deadline=None)
@given(n=st.integers(1, 400), length=st.integers(1, 60), seed=st.integers(0, 1000))
def test_block_weights_draw_n_samples_in_contiguous_blocks(n, length, seed):
    w = block_weights(n, length, 5, np.random.default_rng(seed))
    assert w.shape == (5, n) and np.all(w >= 0) and np.allclose(w, np.round(w))
    assert np.allclose(w.sum(axis=1), n)
    if length >= n:  # one block: the whole record once
        assert np.all(w == 1)


def test_block_weights_repeat_with_the_seed_and_differ_between_replicates():
    a = block_weights(300, 20, 4, np.random.default_rng(3))
    assert np.array_equal(a, block_weights(300, 20, 4, np.random.default_rng(3)))
    assert not np.array_equal(a[0], a[1])


def test_block_length_follows_the_residual_dependence():
    rng = np.random.default_rng(0)
    n = 4000
    white = rng.normal(size=n)
    ar = np.empty(n)
    ar[0] = 0.0
    e = rng.normal(size=n)
    for i in range(1, n):
        ar[i] = 0.95 * ar[i - 1] + e[i]
    assert decorrelation_lag(white) <= 2 and block_length(white) <= 4
    # ρ^l < 1/e from l ≈ 19.5: the lag of the sample autocorrelation is of that order
    assert 10 <= decorrelation_lag(ar) <= 45
    # a mistuned resonance: it crosses 1/e within a quarter period, but stays correlated over the record
    wave = np.sin(2 * np.pi * np.arange(n) / 50.0)
    assert decorrelation_lag(wave) > 1000 and block_length(wave) == n // 8


def test_gauss_newton_refit_reaches_each_replicates_weighted_least_squares():
    """On a linear model (fixed Jacobian exact) each replicate's refit is its weighted least-squares solution."""
    rng = np.random.default_rng(1)
    m, k = 200, 2
    A = rng.normal(size=(m, k))
    y = A @ np.array([0.4, 0.6]) + 0.1 * rng.normal(size=m) + 0.3 * np.sin(np.arange(m) / 7.0)

    class Linear:
        def simulate(self, U):
            return SimpleNamespace(U=np.atleast_2d(U), ok=np.ones(np.atleast_2d(U).shape[0], bool))

        def residuals(self, sim, part):
            return y[None] - sim.U @ A.T

    u_hat = np.linalg.lstsq(A, y, rcond=None)[0]
    w = block_weights(m, 10, 6, np.random.default_rng(2))
    U = bootstrap_refit(Linear(), u_hat, y - A @ u_hat, -A, w, n_iterations=4)
    for b in range(6):
        sw = np.sqrt(w[b])
        exact = np.linalg.lstsq(A * sw[:, None], y * sw, rcond=None)[0]
        assert U[b] == pytest.approx(exact, abs=1e-6)
    assert np.ptp(U[:, 0]) > 1e-3  # the replicates differ


class SmoothTipFriction(PhysicalEffect):
    """A tip friction with a free smoothing width: F_m3 −= F tanh(ż3 / v) (the form a discovery emits)."""

    name = "test_smooth_tip_friction"
    parameters = (Parameter("F_fr", "N", 5e-4, 0.0, 5e-3, "friction force"),
                  Parameter("v_fr", "m/s", 1e-3, 1e-5, 1e-1, "smoothing width"))

    @staticmethod
    def rates(t, x, p, bus, dx, so, po):
        bus[B_FM + 2] -= p[po] * math.tanh(bus[B_ZD + 2] / p[po + 1])


@pytest.mark.slow
def test_misspecified_fit_gets_a_bootstrap_interval_several_times_wider():
    """Truth: dry friction at the tip AND velocity-squared drag on mass 2; fitted: the friction alone. The
    Jacobian's interval of the friction force misses the truth by several standard errors; the bootstrap's is
    several times wider, and the report says the model does not explain the record yet."""
    foreign = load_effect_file(FOREIGN_FILE)
    truth = truth_model("table2", [foreign.TipDryFriction, foreign.Mass2Drag], {"F_coulomb": 1e-3, "c_drag2": 3.0})
    rec = synth_record(synth_test("mbit-b"), truth, noise={"z3": NOISE}, seed=3)
    rep = fit_records([rec], "table2", add=[SmoothTipFriction], max_nfev=20)
    assert rep.outcome.held_rms_sigma > 1.5 and rep.interval_method == "block bootstrap"
    est = {e.name: e for e in rep.outcome.estimates}
    f = est["F_fr"]
    assert f.interval_method == "block bootstrap" and math.isfinite(f.stderr_jacobian)
    assert abs(f.value - 1e-3) > 4 * f.stderr_jacobian  # the Jacobian's interval misses by many standard errors
    assert f.stderr > 4 * f.stderr_jacobian
    assert f.interval_high - f.interval_low > 4 * 2 * 1.96 * f.stderr_jacobian
    assert f.interval_low <= f.value <= f.interval_high
    assert any("does not explain the record yet" in n and "bootstrap" in n for n in rep.notes)
    s = rep.summary()
    assert s["interval_method"] == "block bootstrap" and s["model_explains_record"] is False
    assert "block bootstrap" in f.describe()


def test_right_model_keeps_the_jacobian_intervals():
    rec = synth_record(synth_test("mbit-b"), truth_model("table2", [], {"k3": 21.28 * 0.8}), noise={"z3": NOISE},
                       seed=4)
    rep = fit_records([rec], "table2", free=["k3:10:40"])
    (e,) = rep.outcome.estimates
    assert rep.outcome.held_rms_sigma <= 1.5 and rep.interval_method == "jacobian" and e.interval_method == "jacobian"
    assert e.interval_low == pytest.approx(e.value - 1.96 * e.stderr)
    assert rep.summary()["model_explains_record"] is True
    assert not any("bootstrap" in n for n in rep.notes)


def _ar1_record(values: dict[str, float], seed: int, rho: float = 0.95):
    """An MBIT.b record of the truth with AR(1) laser noise of marginal standard deviation NOISE (stated in the
    record's metadata, as a rig would state its laser's noise)."""
    rec = synth_record(synth_test("mbit-b"), truth_model("table2", [], values), noise={}, seed=seed)
    rng = np.random.default_rng(1000 + seed)
    e = rng.normal(0.0, NOISE * math.sqrt(1 - rho ** 2), rec.t.size)
    n = np.empty_like(e)
    n[0] = rng.normal(0.0, NOISE)
    for i in range(1, e.size):
        n[i] = rho * n[i - 1] + e[i]
    ch = rec.channels["z3"]
    channels = dict(rec.channels) | {"z3": dataclasses.replace(ch, values=ch.values + n, noise_std=NOISE)}
    return dataclasses.replace(rec, channels=channels)


@pytest.mark.slow
def test_right_model_intervals_cover_the_truth_on_ar1_laser_noise():
    """Coverage of the stated 95 % intervals over seeds with AR(1) noise (ρ = 0.95): measured 32 of 32 (k3 and
    c3, 16 seeds); without the correlation inflation of the standard error it falls to 26 of 32 (checked by
    patching ``lag1_autocorrelation`` to 0)."""
    truth = {"k3": 21.28 * 0.8, "c3": 0.03}
    inside = []
    for seed in range(16):
        rep = fit_records([_ar1_record(truth, seed)], "table2", free=["k3:10:40", "c3:0.001:0.2"])
        assert rep.interval_method == "jacobian"
        inside += [e.interval_low <= truth[e.name] <= e.interval_high for e in rep.outcome.estimates]
    assert np.mean(inside) >= 0.9


@pytest.mark.slow
def test_cli_fit_says_the_model_does_not_explain_the_record_and_the_interval_method(tmp_path, capsys):
    """``shm fit --json`` on a record the fitted model cannot explain (k3 freed; the truth also has drag on mass
    2): fit.json and stdout name the interval method, say the model does not explain the record, and the text
    report's note says so."""
    from shm_cli.main import main
    from workbench.records import write_record

    foreign = load_effect_file(FOREIGN_FILE)
    truth = truth_model("table2", [foreign.Mass2Drag], {"k3": 21.28 * 0.8, "c_drag2": 3.0})
    path = write_record(synth_record(synth_test("mbit-b"), truth, noise={"z3": NOISE}, seed=3), tmp_path / "d.csv")
    code = main(["fit", str(path), "--params", "table2", "--free", "k3:10:40", "--out", str(tmp_path / "fit"),
                 "--json"])
    out, err = capsys.readouterr()
    assert code == 0
    summary = json.loads(out)
    assert summary["held_rms_sigma"]["after"] > 1.5
    assert summary["interval_method"] == "block bootstrap" and summary["model_explains_record"] is False
    (est,) = summary["estimates"]
    assert est["interval_method"] == "block bootstrap" and est["interval_low"] < est["value"] < est["interval_high"]
    assert "does not explain the record yet" in err
    saved = json.loads((tmp_path / "fit" / "fit.json").read_text())
    assert saved["interval_method"] == "block bootstrap"
