"""The lane integrator (issue 14): groups of ``LANES`` batch members sharing one step size in one work array, the
effect hooks rewritten in lane form (:mod:`plant.lanes`). It must give each member what the member-by-member
integrator gives (to the tolerance), against solve_ivp too, with per-member inputs, recorded states and bus, a
padded last group, members whose parameter branches differ, and members that fail alone."""

from __future__ import annotations

import ast
import itertools
import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.integrate import solve_ivp

from plant import InputSignals, IntegrationStatus, PlantModel, sine_drive, step_drive
from plant.effect import PhysicalEffect
from plant.integrate import LANES
from plant.lanes import LaneFormUnsupported, lane_hook_source
from plant.layout import X_Q
from plant.reference import make_solve_ivp_rhs
from plant.stepper import LANE_MIN_BATCH, Integrator, work_items


def _deviated(model: PlantModel, n: int, seed: int = 3) -> np.ndarray:
    rng = np.random.default_rng(seed)
    dev = rng.uniform(-0.4, 0.4, size=(n, 3))
    return model.param_batch(k3=21.28 * (1 + dev[:, 0]), alpha_h=0.605 * (1 + dev[:, 1]),
                             beta_h=8.307 * (1 + dev[:, 2]))


def _rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


def _assert_as_accurate(lanes: np.ndarray, alone: np.ndarray, exact: np.ndarray) -> None:
    """The lane result is as accurate as the member-by-member one at the same tolerance, each column against a
    result at rtol 1e-10: its error is at most 3x the other's (or 1e-6 of the column's largest value)."""
    lanes, alone, exact = (np.atleast_2d(np.asarray(a).T).T for a in (lanes, alone, exact))
    for k in range(exact.shape[1]):
        if np.max(np.abs(exact[:, k])) == 0.0:
            continue
        err_lanes, err_alone = _rel(lanes[:, k], exact[:, k]), _rel(alone[:, k], exact[:, k])
        assert err_lanes < max(3.0 * err_alone, 1e-6), (k, err_lanes, err_alone)


def test_the_core_composition_has_a_lane_form(table2_model):
    assert table2_model.kernels().HAS_LANES
    integ = Integrator(table2_model)
    assert integ.lanes == LANES
    assert not integ.uses_lanes(LANE_MIN_BATCH - 1) and integ.uses_lanes(LANE_MIN_BATCH)
    assert integ.uses_lanes(1, lanes=True) and not integ.uses_lanes(10_000, lanes=False)


def test_lanes_match_member_by_member_with_padding_states_and_bus(table2_model):
    """A batch that is not a multiple of LANES, each member with its own drive: outputs, states and bus agree with
    the member-by-member integrator to the tolerance; every member's final state is exact (continuable)."""
    n = LANES + 5
    p = _deviated(table2_model, n)
    t = np.arange(0.0, 2.0 + 1e-9, 1e-3)
    amp = np.linspace(100.0, 600.0, n)[:, None]
    va = amp * np.sin(2 * np.pi * (1.0 + 0.2 * np.arange(n))[:, None] * t)
    values = np.zeros((n, t.size, 3))
    values[:, :, 0], values[:, :, 1] = va, -va
    inp = InputSignals(t0=0.0, dt=1e-3, values=values)
    kw = dict(dt_out=0.01, params=p, record_states=True, record_bus=True)
    lanes = table2_model.simulate(inp, lanes=True, **kw)
    alone = table2_model.simulate(inp, lanes=False, **kw)
    ref = table2_model.simulate(inp, lanes=False, rtol=1e-10, **kw)
    assert lanes.ok and alone.ok
    for b in range(n):
        for got, want, exact in ((lanes["z3"][b], alone["z3"][b], ref["z3"][b]),
                                 (lanes.states[b], alone.states[b], ref.states[b]),
                                 (lanes.bus[b], alone.bus[b], ref.bus[b])):
            _assert_as_accurate(got, want, exact)
    assert np.all(lanes.n_steps[:LANES] == lanes.n_steps[0])  # one step sequence per group
    assert np.all(lanes.n_steps[LANES:] == lanes.n_steps[LANES])


def test_lane_member_matches_solve_ivp_rtol_1e9(table2_model, table2_params):
    p = _deviated(table2_model, LANE_MIN_BATCH, seed=11)
    inp = sine_drive(600.0, 0.1, 5.0, dt=1e-3)
    res = table2_model.simulate(inp, dt_out=0.01, params=p, lanes=True)
    names = table2_model.param_names
    for b in (0, LANE_MIN_BATCH - 1):
        prm = dict(table2_params.values, **{k: p[b, names.index(k)] for k in ("k3", "alpha_h", "beta_h")})
        f = make_solve_ivp_rhs(prm, inp.t, inp.values[0])
        ref = solve_ivp(f, (0.0, res.t[-1]), np.zeros(12), method="LSODA", rtol=1e-9, atol=1e-13, t_eval=res.t,
                        max_step=2e-3)
        assert _rel(res["z3"][b], ref.y[0] + ref.y[1] + ref.y[2]) < 1e-4


def test_a_parameter_branch_that_differs_between_members(table2_model):
    """Bouc-Wen's n_h = 1 branch runs alone when a whole group has n_h = 1; a group mixing n_h = 1 and 2 takes
    the per-member branch and still gives each member its own dynamics."""
    n = LANES
    p = _deviated(table2_model, n)
    p[::2, table2_model.param_index("n_h")] = 2.0
    inp = step_drive(300.0, 0.5, t_step=0.05)
    lanes = table2_model.simulate(inp, dt_out=0.005, params=p, lanes=True)
    alone = table2_model.simulate(inp, dt_out=0.005, params=p, lanes=False)
    exact = table2_model.simulate(inp, dt_out=0.005, params=p, lanes=False, rtol=1e-10)
    for b in range(n):
        _assert_as_accurate(lanes["qh3"][b], alone["qh3"][b], exact["qh3"][b])
    assert _rel(alone["qh3"][0], alone["qh3"][1]) > 1e-3  # the branches really differ


def test_a_member_that_exhausts_the_step_budget_costs_its_group_a_rerun_alone(table2_model):
    """Negative damping in one member: it crawls (tiny steps) until the step budget, which is per member, runs out.
    Its group shared those steps, so every member of that group is integrated again alone: the crawling member stops
    TOO_MANY_STEPS with NaN from where it stopped, the others finish exactly as the member-by-member integrator."""
    n = LANES
    p = _deviated(table2_model, n)
    p[3, table2_model.param_index("c3")] = -50.0
    inp = sine_drive(600.0, 1.0, 3.0)
    lanes = table2_model.simulate(inp, dt_out=0.01, params=p, max_steps=200_000, lanes=True)
    alone = table2_model.simulate(inp, dt_out=0.01, params=p, max_steps=200_000, lanes=False)
    assert lanes.status[3] == IntegrationStatus.TOO_MANY_STEPS == alone.status[3]
    stopped = np.flatnonzero(~np.isfinite(lanes["z3"][3]))
    assert stopped.size and np.all(~np.isfinite(lanes["z3"][3, stopped[0]:]))
    assert np.all(np.isfinite(lanes["z3"][3, :stopped[0]]))
    others = [b for b in range(n) if b != 3]
    assert np.all(lanes.status[others] == IntegrationStatus.OK)
    np.testing.assert_array_equal(lanes.y[others], alone.y[others])
    np.testing.assert_array_equal(lanes.n_steps, alone.n_steps)


def test_a_member_that_overflows_is_masked_and_the_group_goes_on(table2_model):
    """A member started at 1e200 m overflows at once: it stops DIVERGED with NaN after its first output (as alone),
    masked out of the group's error norm; the other members of its group finish with finite outputs that are as
    accurate as alone."""
    n = LANES
    p = _deviated(table2_model, n)
    x0 = np.zeros((n, table2_model.n_states))
    x0[5, 0] = 1e200
    inp = sine_drive(600.0, 1.0, 1.0)
    lanes = table2_model.simulate(inp, dt_out=0.01, params=p, x0=x0, lanes=True)
    alone = table2_model.simulate(inp, dt_out=0.01, params=p, x0=x0, lanes=False)
    assert lanes.status[5] == IntegrationStatus.DIVERGED == alone.status[5]
    assert np.isfinite(lanes["z3"][5, 0]) and np.all(np.isnan(lanes["z3"][5, 1:]))
    others = [b for b in range(n) if b != 5]
    assert np.all(lanes.status[others] == IntegrationStatus.OK)
    exact = table2_model.simulate(inp, dt_out=0.01, params=p[others], rtol=1e-10, lanes=False)
    for i, b in enumerate(others):
        _assert_as_accurate(lanes["z3"][b], alone["z3"][b], exact["z3"][i])


def test_library_compositions_have_lanes_but_an_effect_file_does_not(tmp_path):
    """A composition with an effect loaded from a file (usually a candidate tried once: compiling its lane kernels
    costs ~8 s, more than one fit saves) integrates member by member; the same effect from a package has lanes."""
    text = (Path(__file__).parents[2] / "docs" / "effects.md").read_text()
    block = re.search(r"```python\n# my_effects\.py\n(.*?)```", text, re.S)
    assert block
    path = tmp_path / "tip_support_file.py"
    path.write_text(block.group(1))
    model = PlantModel("table2", effects=[f"{path}:TipSupportSpring"])
    assert not model.kernels().HAS_LANES and not Integrator(model).uses_lanes(1000)
    assert PlantModel("table2", effects=["air_damping"]).kernels().HAS_LANES


class _WholeArrayEffect(PhysicalEffect):
    """A hook that passes its state array whole: no lane form."""

    name = "test_whole_array"
    description = "test"
    origin = "test"

    @staticmethod
    def post(t, x, p, bus, dx, X, P, B):
        dx[X_Q] += 0.0 * np.sum(x)


def test_a_hook_without_lane_form_is_named_and_its_composition_goes_member_by_member():
    with pytest.raises(LaneFormUnsupported, match="'x' other than by index"):
        lane_hook_source(_WholeArrayEffect.post, "l", "0")

    def early_return(t, x, p, bus, dx, X, P, B):
        if x[0] > 0.0:
            return
        dx[0] = 1.0

    with pytest.raises(LaneFormUnsupported, match="Return"):
        lane_hook_source(early_return, "l", "0")


def test_only_a_test_of_parameters_alone_is_unswitched():
    def on_parameter(t, x, p, bus, dx, X, P, B):
        if p[P.a] > 0.0:
            dx[0] = x[0]
        else:
            dx[0] = -x[0]

    def on_state(t, x, p, bus, dx, X, P, B):
        if x[0] > 0.0:
            dx[0] = x[0]

    src, _ = lane_hook_source(on_parameter, "l", "0")
    assert "_uniform_" in src
    ast.parse(src)
    src, _ = lane_hook_source(on_state, "l", "0")
    assert "_uniform_" not in src


@given(batch=st.integers(1, 500), items=st.integers(1, 64), unit=st.sampled_from([1, 4, 16, 32]))
def test_work_items_cover_the_batch_in_whole_groups(batch, items, unit):
    edges = work_items(batch, items, unit)
    assert edges[0] == 0 and edges[-1] == batch
    assert all(a < b for a, b in itertools.pairwise(edges))
    assert len(edges) - 1 <= items
    assert all(e % unit == 0 for e in edges[:-1])
