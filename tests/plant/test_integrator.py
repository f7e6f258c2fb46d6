"""The batch integrator (Dormand–Prince 5(4) with a PI step-size controller): properties of the algorithm, not
timings — rejection rate and step size at the stability limit of the 102 Hz mode, tolerance proportionality,
accuracy against solve_ivp, the interval entry point of the integration seam (rig, stepper, observer) equal to
``simulate``, failures reported as ``IntegrationFailed`` with their status, and a changed controller constant reaching
the compiled-kernel cache key."""

from __future__ import annotations

import math
import pickle

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import plant.integrate_steps as integrate_steps
from plant import IntegrationFailed, IntegrationStatus, Integrator, PlantModel, PlantStepper, sine_drive, step_drive
from plant.compose import generate_source
from plant.linear import linearise
from plant.reference import make_solve_ivp_rhs


def _dopri5_stability(z: complex) -> float:
    """|R(z)| of the 5th-order Dormand–Prince solution: Σ_{k≤5} z^k/k! + z^6/600."""
    return abs(sum(z**k / math.factorial(k) for k in range(6)) + z**6 / 600.0)


def _stable_step_limit(model: PlantModel, p: np.ndarray) -> float:
    """Largest h with |R(hλ)| ≤ 1 for the fastest eigenvalue λ of the linearisation at rest (s)."""
    lam = max(np.linalg.eigvals(linearise(model, params=p).A), key=abs)
    lo, hi = 0.0, 10.0 / abs(lam)
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if _dopri5_stability(mid * lam) <= 1.0 else (lo, mid)
    return lo


@pytest.fixture(scope="module")
def mbit_batch(table2_model):
    rng = np.random.default_rng(11)
    dev = rng.uniform(-0.4, 0.4, size=(4, 3))
    p = table2_model.param_batch(k3=21.28 * (1 + dev[:, 0]), alpha_h=0.605 * (1 + dev[:, 1]),
                                 beta_h=8.307 * (1 + dev[:, 2]))
    inp = sine_drive(600.0, 0.1, 10.0, dt=1e-3)
    return p, inp, table2_model.simulate(inp, dt_out=0.01, params=p, threads=1)


def test_few_rejections_and_steps_at_the_stability_limit(table2_model, mbit_batch):
    """At the stability limit of the 102 Hz mode the PI controller neither oscillates (few rejected attempts)
    nor hides below the limit (mean accepted step close to the largest stable Dormand–Prince step)."""
    p, inp, res = mbit_batch
    assert res.ok
    assert np.all(res.n_rejected <= res.n_steps)
    rate = res.n_rejected.sum() / res.n_steps.sum()
    assert rate < 0.08  # the elementary controller (before issue 14) rejected ~28 % here
    for b in range(p.shape[0]):
        accepted = res.n_steps[b] - res.n_rejected[b]
        mean_step = (inp.t[-1] - inp.t[0]) / accepted
        limit = _stable_step_limit(table2_model, p[b])
        assert 0.85 * limit < mean_step < 1.02 * limit


def test_error_falls_with_the_tolerance(table2_model, table2_params):
    """Error control works: on the 300 V step (accuracy-limited ringing, not stability-limited), tightening
    rtol by 100x lowers the error against a tight reference by > 10x."""
    inp = step_drive(300.0, 0.6, t_step=0.1)
    f = make_solve_ivp_rhs(dict(table2_params.values), inp.t, inp.values[0])
    t_eval = np.arange(61) * 0.01
    ref = solve_ivp(f, (0.0, 0.6), np.zeros(12), method="LSODA", rtol=1e-11, atol=1e-15, t_eval=t_eval,
                    max_step=5e-4)
    z_ref = ref.y[0] + ref.y[1] + ref.y[2]
    errs = []
    for rtol in (1e-4, 1e-6):
        res = table2_model.simulate(inp, dt_out=0.01, rtol=rtol)
        errs.append(np.max(np.abs(res["z3"][0] - z_ref)) / np.max(np.abs(z_ref)))
    assert errs[1] < errs[0] / 10


def test_deviated_member_matches_solve_ivp_rtol_1e9(table2_model, table2_params, mbit_batch):
    p, inp, res = mbit_batch
    names = table2_model.param_names
    prm = dict(table2_params.values, **{n: p[0, names.index(n)] for n in ("k3", "alpha_h", "beta_h")})
    f = make_solve_ivp_rhs(prm, inp.t, inp.values[0])
    n = 501  # the first 5 s (the reference is plain Python: keep the test short)
    ref = solve_ivp(f, (0.0, res.t[n - 1]), np.zeros(12), method="LSODA", rtol=1e-9, atol=1e-13, t_eval=res.t[:n],
                    max_step=2e-3)
    z_ref = ref.y[0] + ref.y[1] + ref.y[2]
    assert np.max(np.abs(res["z3"][0, :n] - z_ref)) / np.max(np.abs(z_ref)) < 1e-4


def test_run_chunk_entry_point_equals_simulate(table2_model):
    """The rig, stepper and observer integrate through ``Integrator.interval`` (the compiled ``run_chunk``, no
    rejection counts): same numbers as ``simulate``."""
    inp = sine_drive(300.0, 2.0, 1.0, dt=1e-3)
    ref = table2_model.simulate(inp, dt_out=0.01, record_states=True)
    n_out = ref.t.size
    y = np.empty((1, n_out, table2_model.n_outputs))
    xs = np.empty((1, n_out, table2_model.n_states))
    steps = Integrator(table2_model, 1e-6).interval(np.zeros((1, 12)), table2_model.p_nominal[None].copy(),
                                                    inp.values, inp.t0, inp.dt, ref.t, 0.01, y, xs)
    assert steps == ref.n_steps[0]
    np.testing.assert_array_equal(y, ref.y)
    np.testing.assert_array_equal(xs, ref.states)


def test_failures_are_reported_as_integration_failed(table2_model):
    """A diverging member: the seam raises ``IntegrationFailed`` (a ``FloatingPointError``) with the status, the
    member and the time, from a stepper interval and from a batch simulation alike."""
    p = table2_model.param_batch(n=2)
    p[1, table2_model.param_index("c3")] = -50.0  # negative damping: unstable
    res = table2_model.simulate(sine_drive(600.0, 1.0, 3.0), dt_out=0.01, params=p, max_steps=200_000)
    with pytest.raises(FloatingPointError) as info:
        res.raise_on_failure("batch: ")
    exc = info.value
    assert isinstance(exc, IntegrationFailed) and exc.member == 1 and exc.status != IntegrationStatus.OK
    assert exc.status == IntegrationStatus(int(res.status[1])) and str(exc).startswith("batch: batch member 1: ")
    assert 0.0 <= exc.t < 3.0 and np.all(np.isfinite(res.y[1, res.t <= exc.t]))
    back = pickle.loads(pickle.dumps(exc))  # a campaign worker process reports it to its parent
    assert (str(back), back.status, back.member, back.t) == (str(exc), exc.status, exc.member, exc.t)
    table2_model.simulate(sine_drive(600.0, 1.0, 0.1), dt_out=0.01).raise_on_failure()  # nothing to raise
    st = PlantStepper(table2_model, params=p, max_steps=200_000)
    u = np.zeros((2, 3))
    u[:, 0] = 600.0
    with pytest.raises(IntegrationFailed) as info:
        for _ in range(300):
            st.advance(u, 0.01)
    exc = info.value
    assert exc.member == 1 and exc.status != IntegrationStatus.OK
    assert exc.t == pytest.approx(st.t) and exc.status.message in str(exc)


def test_dense_output_does_not_steer_the_steps(table2_model):
    """Output times come from dense output: a 10x denser output grid leaves the steps and the values unchanged
    (to the dense output's accuracy)."""
    inp = sine_drive(600.0, 0.5, 2.0, dt=1e-3)
    coarse = table2_model.simulate(inp, dt_out=0.01)
    fine = table2_model.simulate(inp, dt_out=0.001)
    assert coarse.n_steps[0] == fine.n_steps[0]
    z_fine = fine["z3"][0, ::10]
    assert np.max(np.abs(z_fine - coarse["z3"][0])) < 1e-6 * np.max(np.abs(coarse["z3"][0]))


def test_controller_constants_reach_the_kernel_cache_key(table2_model, monkeypatch):
    """Numba's disk cache keys on the generated file: the integrator's constants must be in its text, so that
    changing one recompiles instead of loading stale machine code."""
    args = (table2_model.effects, *table2_model._offsets, table2_model.n_states, True)
    before = generate_source(*args)
    assert f"_PI_BETA = {integrate_steps._PI_BETA!r}" in before
    monkeypatch.setattr(integrate_steps, "_PI_BETA", integrate_steps._PI_BETA / 2)
    assert generate_source(*args) != before


def test_short_intervals_ramp_up_as_fast_as_the_elementary_controller(table2_model):
    """A rig or stepper restarts the integrator every 10 ms tick from a 0.1 ms step. Until the first rejection the
    step grows by the elementary controller's factor (up to 5x), so a tick of the MBIT.a drive takes about six
    attempts, as before the PI controller (applying PI from the first step took ~8.7)."""
    from plant import PlantStepper

    st = PlantStepper(table2_model)
    ticks = 200
    for _ in range(ticks):
        v = 600.0 * np.sin(2 * np.pi * 0.1 * np.array([st.t, st.t + 0.01]))
        st.advance(np.stack([100.0 + v, 100.0 - v, 0.0 * v], axis=1), 0.01)
    assert st.total_steps / ticks < 7.0
