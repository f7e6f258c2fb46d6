"""Which parameters can these records tell apart, and which test would?

For a re-estimated parameter, the sensitivity of the simulated measurement to a 2 % change of every core
parameter (one batched simulation at the fitted values) gives one column per parameter; two parameters whose
columns correlate above :data:`CONFUSED_ABOVE` *and* that leave the parameter uncertain by more than
:data:`UNCERTAIN_ABOVE` (relative standard error with both free, from the 2×2 Fisher information JᵀJ in noise
units) cannot be told apart on these records: a change of one is mimicked by a change of the other (mass and
stiffness on a quasi-static test, d_ep and a stiffness on a step). For each such pair the same information is
computed on the standard synthetic tests (:data:`SEPARATING_TESTS`, 2 µm laser noise); the test that pins the
parameter best with both free is the one that would separate them.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from board_config import CORE_SCHEMA, ParameterSet
from plant import InputSignals, PlantModel
from workbench.fit import RowsObjective, Target

CONFUSED_ABOVE = 0.9
#: relative standard error (both parameters free) above which a correlated pair is "not told apart"
UNCERTAIN_ABOVE = 0.05
#: laser noise assumed for the separating tests (m)
TEST_NOISE_M = 2e-6
#: core parameters whose sensitivities are compared (those the re-estimation candidates free)
COMPARED = ("k1", "k2", "k3", "c1", "c2", "c3", "m1", "m2", "m3", "d_ep", "R_ep", "C_ep", "alpha_h", "beta_h")
#: test kinds (and shortened overrides) tried for separating a confused pair
SEPARATING_TESTS: Mapping[str, Mapping[str, float]] = {"mbit-a": {}, "mbit-b": {}, "sweep": {"duration_s": 15.0},
                                                       "step": {}}
_STEP = 0.02


@dataclass
class Confusion:
    a: str
    b: str
    rho: float  # correlation of their sensitivity columns on the records
    rel_se: float  # relative standard error of ``a`` with ``b`` free too, on the records
    separating: list[tuple[str, float, float]]  # (test kind, |ρ| there, relative s.e. of a there), best first


def _corr(x: np.ndarray, y: np.ndarray) -> float:
    nx, ny = float(np.linalg.norm(x)), float(np.linalg.norm(y))
    return float(np.dot(x, y) / (nx * ny)) if nx > 0 and ny > 0 else 0.0


def sensitivity_matrix(targets: Sequence[Target], values: Mapping[str, float],
                       names: Sequence[str] = COMPARED) -> tuple[list[str], np.ndarray]:
    """(names with a visible effect, (n, M) sensitivities of the σ-weighted records to ln(value) at ``values``)."""
    models = [tg.model for tg in targets]
    ro = RowsObjective(targets, models)
    rows = []
    for i, m in enumerate(models):
        p0 = np.array(ro.nominal(i))
        for n, v in values.items():
            if n in m.param_names:
                p0[m.param_index(n)] = v
        P = np.tile(p0, (len(names) + 1, 1))
        for r, n in enumerate(names, start=1):
            j = m.param_index(n)
            P[r, j] = p0[j] * np.exp(_STEP) if p0[j] != 0 else _STEP
        rows.append(P)
    sim = ro.run(rows)
    R = ro.residuals(sim, "all")
    J = (R[1:] - R[0][None]) / _STEP
    keep = [k for k in range(len(names)) if sim.ok[k + 1] and np.linalg.norm(J[k]) > 1e-9]
    return [names[k] for k in keep], J[keep]


def joint_rel_se(ja: np.ndarray, jb: np.ndarray) -> float:
    """Standard error of ln(a) with b free too, from the columns' Fisher information (σ units)."""
    aa, bb, ab = float(np.dot(ja, ja)), float(np.dot(jb, jb)), float(np.dot(ja, jb))
    det = aa * bb - ab * ab
    return float(np.sqrt(bb / det)) if det > 0 and bb > 0 else float("inf")


def _test_separation(params: ParameterSet, a: str, b: str, kind: str,
                     over: Mapping[str, float]) -> tuple[float, float]:
    from workbench.simulation import synth_inputs, synth_test

    spec = synth_test(kind, **over)
    t, u, _ = synth_inputs(spec)
    model = PlantModel(params)
    p0 = model.p_nominal
    P = np.tile(p0, (3, 1))
    for r, n in ((1, a), (2, b)):
        j = model.param_index(n)
        P[r, j] = p0[j] * np.exp(_STEP) if p0[j] != 0 else _STEP
    sub = 4
    res = model.simulate(InputSignals(0.0, 1.0 / spec.rate_hz, u), t_out=t[::sub], params=P)
    y = res.y[:, :, model.output_names.index("z3_meas")] * np.sqrt(sub) / (TEST_NOISE_M * _STEP)
    ja, jb = y[1] - y[0], y[2] - y[0]
    return abs(_corr(ja, jb)), joint_rel_se(ja, jb)


def confusions(targets: Sequence[Target], params: ParameterSet, fitted: Mapping[str, float],
               about: Sequence[str], threshold: float = CONFUSED_ABOVE) -> tuple[list[Confusion], dict[str, tuple]]:
    """Pairs (one of ``about``, another core parameter) these records cannot separate, each with the synthetic
    tests ranked by how well they separate the pair; and, per ``about`` parameter, its closest other (name, ρ,
    relative standard error of the parameter with that other one free too)."""
    names, J = sensitivity_matrix(targets, fitted)
    fitted_set = params.with_values(None, **{k: v for k, v in fitted.items() if k in CORE_SCHEMA}) if fitted else params
    out, closest = [], {}
    for a in about:
        if a not in names:
            continue
        ia = names.index(a)
        best: tuple = ("", 0.0, 0.0)
        for ib, b in enumerate(names):
            if b == a or b in about:
                continue
            rho = _corr(J[ia], J[ib])
            se = joint_rel_se(J[ia], J[ib])
            if abs(rho) > abs(best[1]):
                best = (b, rho, se)
            if abs(rho) >= threshold and se >= UNCERTAIN_ABOVE:
                sep = sorted(((k, *_test_separation(fitted_set, a, b, k, o)) for k, o in SEPARATING_TESTS.items()),
                             key=lambda kr: kr[2])
                out.append(Confusion(a, b, rho, se, sep))
        closest[a] = best
    return out, closest
