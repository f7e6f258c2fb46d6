"""The effects library (plant/effects): every effect compiles, is exactly neutral at its neutral value, changes
the response in the direction its documentation states, and declares what the workbench needs.

The checks that apply to every library effect are parametrised over the registry (:func:`library_effects`), so a
new effect file in plant/effects is tested without editing this file (``tests/plant/test_effect_slots.py`` proves
it)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from plant import PlantModel, registered_effects, step_drive
from plant.effect import library_effects
from plant.effects.library_support import FitRange
from plant.linear import linearise, modal_summary
from plant.signals import InputSignals, sine_drive

#: every library effect of the registry (collected once; the one-file test runs the checks below on its own)
LIBRARY = library_effects()

STEP = step_drive(300.0, 1.5, t_step=0.1, dt=1e-3)


@pytest.fixture(scope="module")
def nominal_step(table2_model):
    return table2_model.simulate(STEP, dt_out=1e-3, record_states=True)


@pytest.fixture(scope="module")
def models():
    return {name: PlantModel("table2", effects=[name]) for name in LIBRARY}


def _step(model: PlantModel, **values: float):
    res = model.simulate(STEP, dt_out=1e-3, params=model.param_batch(**values))
    assert res.ok, res.failures()
    return res


def test_library_is_the_eight_effects_in_report_order():
    assert LIBRARY[:8] == ("piezo_creep", "geometric_stiffening", "air_damping", "dielectric_leakage",
                           "amplifier_current_limit", "laser_sensor", "root_compliance", "thermal_drift")


@pytest.mark.parametrize("name", LIBRARY)
def test_library_is_registered_and_documented(name):
    reg = registered_effects()
    cls = reg[name]
    assert cls.role == "effect"
    assert len(cls.origin) > 40 and len(cls.signature) > 80 and cls.description, name
    assert cls.own_parameters(), name
    for par in cls.own_parameters():
        assert par.unit and par.description, (name, par.name)
        assert math.isfinite(par.lower) and math.isfinite(par.upper), (name, par.name)
        assert par.lower <= par.default <= par.upper, (name, par.name)
    # everything the workbench needs is on the parameters' own declarations (docs/effects.md, "What a library
    # effect declares"): a neutral value (at least one: the test below switches the effect off with them) ...
    assert cls.neutral_values(), name
    # ... a fit range on every parameter fitted by default (at least one), inside the parameter's bounds ...
    assert cls.default_fit_names(), name
    for par in cls.own_parameters():
        if par.neutral is not None:
            assert par.lower <= par.neutral <= par.upper, (name, par.name)
        if par.name in cls.default_fit_names() or par.fit is not None:
            assert isinstance(par.fit, FitRange), (name, par.name)
            assert par.lower <= par.fit.lower < par.fit.upper <= par.upper, (name, par.name)
    # ... and the three strengths the hidden-effect challenge hides it at
    strengths = cls.challenge_strengths()
    assert len(strengths) == 3 and all(strengths), name
    for values in strengths:
        for pname, value in values.items():
            par = next(p for p in cls.own_parameters() if p.name == pname)
            assert par.lower <= value <= par.upper, (name, pname, value)


@pytest.mark.parametrize("name", LIBRARY)
def test_guess_is_within_bounds_with_and_without_data(name, nominal_step, table2_model):
    cls = registered_effects()[name]
    t = nominal_step.t
    z3 = nominal_step["z3_meas"][0]
    pred = {n: nominal_step[n][0] for n in nominal_step.output_names}
    data = {
        "t_s": t,
        "inputs": {"v_ch1": STEP.values[0, :, 0][: t.size], "v_ch2": STEP.values[0, :, 1][: t.size],
                   "z0dd": STEP.values[0, :, 2][: t.size]},
        "measured": {"z3_meas": 0.95 * z3 + 1e-5},
        "predicted": pred,
        "params": dict(zip(table2_model.param_names, table2_model.p_nominal)),
    }
    for d in (None, {}, data):
        g = cls.guess(d)
        assert set(g) <= {p.name for p in cls.own_parameters()}
        for pname, value in g.items():
            par = next(p for p in cls.own_parameters() if p.name == pname)
            assert math.isfinite(value) and par.lower <= value <= par.upper, (name, pname, value)


@pytest.mark.parametrize("name", LIBRARY)
def test_compiles_and_is_neutral(name, models, table2_model):
    # tight tolerance on both sides: extra states change the step-size sequence, so compare converged solutions
    model = models[name]
    cls = registered_effects()[name]
    res = model.simulate(STEP, dt_out=1e-3, params=model.param_batch(**cls.neutral_values()), rtol=1e-10)
    ref = table2_model.simulate(STEP, dt_out=1e-3, rtol=1e-10)
    assert res.ok
    peak = np.max(np.abs(ref["z3_meas"][0]))
    assert np.max(np.abs(res["z3_meas"][0] - ref["z3_meas"][0])) < 1e-7 * peak
    assert np.max(np.abs(res["v_patch1"][0] - ref["v_patch1"][0])) < 1e-7 * 300.0


def test_piezo_creep_keeps_drifting_in_the_step_direction(models, nominal_step):
    z_nom = nominal_step["z3"][0]
    z = _step(models["piezo_creep"], gamma_creep=0.1, tau_creep=0.3)["z3"][0]
    k_mid, k_end = int(0.6 / 1e-3), -1
    assert z[k_end] > z_nom[k_end] * 1.02  # more stroke
    assert (z[k_end] - z[k_mid]) > (z_nom[k_end] - z_nom[k_mid]) + 1e-5  # still creeping up


def test_geometric_stiffening_hardens_and_softens(models, nominal_step):
    z_nom = nominal_step["z3"][0][-1]
    hard = _step(models["geometric_stiffening"], kappa_nl=2e4)["z3"][0][-1]
    soft = _step(models["geometric_stiffening"], kappa_nl=-5e3)["z3"][0][-1]
    assert hard < z_nom * 0.995 and soft > z_nom * 1.002
    small = models["geometric_stiffening"].simulate(step_drive(3.0, 1.5, t_step=0.1, dt=1e-3), dt_out=1e-3,
                                                    params=models["geometric_stiffening"].param_batch(kappa_nl=2e4))
    ref = models["geometric_stiffening"].simulate(step_drive(3.0, 1.5, t_step=0.1, dt=1e-3), dt_out=1e-3)
    # cubic: at 1 % of the amplitude the relative effect is ~1e-4 of the large-amplitude one
    assert abs(small["z3"][0][-1] / ref["z3"][0][-1] - 1) < 1e-5


def test_air_damping_damps_the_ringing_not_the_static_stroke(models, nominal_step):
    z_nom = nominal_step["z3"][0]
    z = _step(models["air_damping"], c_air=0.2)["z3"][0]
    overshoot_nom = np.max(z_nom) - z_nom[-1]
    overshoot = np.max(z) - z[-1]
    assert overshoot < 0.9 * overshoot_nom
    assert abs(z[-1] / z_nom[-1] - 1) < 2e-3


def test_dielectric_leakage_lowers_static_stroke_and_drains_open_circuit(models, nominal_step):
    z_nom = nominal_step["z3"][0][-1]
    g = 5e-5
    z = _step(models["dielectric_leakage"], G_leak=g)["z3"][0][-1]
    ratio = z / z_nom
    assert ratio == pytest.approx(1.0 / (1.0 + 1500.0 * g), rel=0.02)
    oc = PlantModel("table2", effects=["dielectric_leakage"], terminal="open_circuit")
    x0 = np.zeros(oc.n_states)
    x0[6:9] = oc.param_value("C_ep") * 1.0  # 1 V on every patch couple
    quiet = InputSignals(0.0, 0.01, np.zeros((1, 101, 3)))
    kept = oc.simulate(quiet, dt_out=0.01, x0=x0)["v_stored"][0]
    lost = oc.simulate(quiet, dt_out=0.01, x0=x0, params=oc.param_batch(G_leak=1e-5))["v_stored"][0]
    tau = oc.param_value("C_ep") / 1e-5
    assert kept[-1] == pytest.approx(kept[0], rel=0.2)  # nominal: only the piezo coupling moves it
    assert lost[-1] / lost[0] < kept[-1] / kept[0] * math.exp(-1.0 / tau) * 1.1


def test_amplifier_current_limit_slows_the_step_but_not_the_end(models, nominal_step):
    i_max = 0.02
    res = models["amplifier_current_limit"].simulate(
        STEP, dt_out=1e-3, params=models["amplifier_current_limit"].param_batch(I_max=i_max))
    v_patch = res["v_patch1"][0]
    c_ep = models["amplifier_current_limit"].param_value("C_ep")
    slope = np.max(np.diff(v_patch)) / 1e-3
    assert slope <= i_max / (3 * c_ep) * 1.05  # slew limit of a current-limited source into 3 C_ep
    k = int(0.13 / 1e-3)
    assert res["z3"][0][k] < 0.7 * nominal_step["z3"][0][k]
    assert res["z3"][0][-1] == pytest.approx(nominal_step["z3"][0][-1], rel=0.02)


def test_laser_sensor_offset_spot_and_lag(models, nominal_step):
    m = models["laser_sensor"]
    z3 = nominal_step["z3"][0]
    off = _step(m, z_offset=2e-4)
    assert np.allclose(off["z3_meas"][0] - off["z3"][0], 2e-4, atol=1e-12)
    spot = _step(m, spot_offset=0.25)
    assert np.allclose(spot["z3_meas"][0], 0.75 * spot["z3"][0] + 0.25 * spot["z2"][0], atol=1e-12)
    lag = _step(m, tau_sensor=0.01)
    meas, phys = lag["z3_meas"][0], lag["z3"][0]
    assert np.allclose(phys, z3, atol=1e-4 * np.max(np.abs(z3)))  # the physics is untouched (to integration accuracy)
    k = int(0.11 / 1e-3)
    assert meas[k] < 0.8 * z3[k]  # reading lags the rise
    assert meas[-1] == pytest.approx(z3[-1], rel=1e-3)


def test_root_compliance_lowers_resonances_keeps_static_stroke(models, nominal_step):
    m = models["root_compliance"]
    long_step = step_drive(300.0, 5.0, t_step=0.1, dt=1e-3)
    z = m.simulate(long_step, dt_out=1e-2, params=m.param_batch(clamp_compliance=1e-2))["z3"][0]
    z_nom = m.simulate(long_step, dt_out=1e-2)["z3"][0]
    assert z[-1] == pytest.approx(z_nom[-1], rel=1e-3)  # the clamp carries no load at equilibrium
    f_nom = modal_summary(linearise(m)).modes[0]["frequency_Hz"]
    f_cl = modal_summary(linearise(m, params=m.param_batch(clamp_compliance=1e-2)[0])).modes[0]["frequency_Hz"]
    assert f_cl < 0.9 * f_nom


def test_thermal_drift_gain_grows_with_time(models, table2_model):
    inp = sine_drive(300.0, 1.0, 6.0, dt=1e-3)
    m = models["thermal_drift"]
    warm = m.simulate(inp, dt_out=1e-3, params=m.param_batch(dT_dt=2.0))["z3"][0]
    ref = table2_model.simulate(inp, dt_out=1e-3)["z3"][0]
    early, late = slice(1000, 2000), slice(5000, 6000)
    ratio_early = np.ptp(warm[early]) / np.ptp(ref[early])
    ratio_late = np.ptp(warm[late]) / np.ptp(ref[late])
    # κ_T = 2.5e-3 /K and 2 K/s: ~+0.4 % per second of record
    assert ratio_late > ratio_early + 0.01
    assert ratio_late == pytest.approx(1 + 2.5e-3 * 2.0 * 5.5, rel=0.02)
