"""The fitting objective: weighted residuals of the targets as a function of the free parameters.

Residuals are measured − simulated on every measured channel, divided by the channel's noise level σ, so errors
read in units of the noise floor. Parameter rows are simulated as one batch (``PlantModel.simulate(params=...)``).
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from board_config.parameter import Parameter
from plant import PlantModel
from workbench.fit._targets import FitError, Target


@dataclass
class SimBatch:
    """Simulated channels of every target for a batch of parameter rows: ``y[i]`` is (B, n_ch, n_t)."""

    y: list[np.ndarray]
    ok: np.ndarray  # (B,) every target integrated
    status: list[np.ndarray]
    full: list[np.ndarray] | None = None  # (B, n_t, n_outputs) when requested


class Objective:
    """Weighted residuals of ``targets`` as a function of the free parameters (in the unit box).

    ``models`` maps each target to the model to simulate (same effects, possibly different terminals);
    ``base_values`` are parameter values (by name) that override the models' nominal vectors.
    """

    def __init__(self, targets: Sequence[Target], models: Sequence[PlantModel], free: Sequence[Parameter],
                 base_values: Mapping[str, float] | None = None, rtol: float = 1e-6, threads: int | None = None):
        self.targets = list(targets)
        self.models = list(models)
        self.free = list(free)
        self.rtol = rtol
        self.threads = threads
        self.n_sims = 0
        self.sim_wall_s = 0.0
        self._p0 = []
        self._cols = []
        for m in self.models:
            p = m.p_nominal.copy()
            for name, value in (base_values or {}).items():
                if name in m.param_names:
                    p[m.param_index(name)] = value
            self._p0.append(p)
            try:
                self._cols.append(np.array([m.param_index(fp.name) for fp in self.free], dtype=int))
            except KeyError as exc:
                raise FitError(str(exc.args[0])) from None

    @property
    def k(self) -> int:
        return len(self.free)

    @staticmethod
    def max_steps(tg: Target) -> int:
        """Step budget of one free run: a sound model of this rig needs well under 5 000 steps per simulated
        second (stiffest library effect at its range bound: ~4 000/s); a candidate that blows up makes the
        step-size controller crawl, and this stops it (reported as a failed, i.e. diverging, free run)."""
        return int(50_000 + 20_000 * float(tg.t[-1] - tg.t[0]))

    def values(self, u: np.ndarray) -> dict[str, float]:
        return {fp.name: float(fp.from_unit(ui)) for fp, ui in zip(self.free, np.atleast_1d(u))}

    def param_rows(self, i: int, U: np.ndarray) -> np.ndarray:
        U = np.atleast_2d(U)
        P = np.tile(self._p0[i], (U.shape[0], 1))
        for j, fp in enumerate(self.free):
            P[:, self._cols[i][j]] = fp.from_unit(U[:, j])
        return P

    def simulate(self, U: np.ndarray, keep_full: bool = False) -> SimBatch:
        U = np.atleast_2d(np.asarray(U, float))
        ys, stats, fulls = [], [], []
        ok = np.ones(U.shape[0], bool)
        t0 = time.perf_counter()
        for i, (tg, m) in enumerate(zip(self.targets, self.models)):
            P = self.param_rows(i, U) if self.k else self._p0[i][None]
            res = m.simulate(tg.inputs, t_out=tg.t, params=P, rtol=self.rtol, threads=self.threads,
                             max_steps=self.max_steps(tg))
            y = res.y[:, :, tg.out_idx(m)].transpose(0, 2, 1)
            if y.shape[0] != U.shape[0]:
                y = np.broadcast_to(y, (U.shape[0], *y.shape[1:]))
            bad = (res.status != 0) | ~np.all(np.isfinite(y), axis=(1, 2))
            if bad.shape[0] != U.shape[0]:
                bad = np.broadcast_to(bad, (U.shape[0],))
            ok &= ~bad
            ys.append(np.array(y))
            stats.append(res.status)
            if keep_full:
                fulls.append(res.y)
        self.n_sims += U.shape[0] * len(self.targets)
        self.sim_wall_s += time.perf_counter() - t0
        return SimBatch(ys, ok, stats, fulls if keep_full else None)

    def residuals(self, sim: SimBatch, part: str = "train") -> np.ndarray:
        """(B, M) weighted residuals (measured − simulated)/σ over ``part`` ('train', 'held' or 'all').

        A member whose integration failed gets, instead, the residual of a model that predicts nothing,
        doubled and pushed 10 σ further out — worse than any member that ran."""
        blocks = []
        for tg, y in zip(self.targets, sim.y):
            mask = part_mask(tg, part)
            if not mask.any():
                continue
            meas = tg.measured[:, mask] / tg.sigma[:, None]
            r = meas[None] - np.nan_to_num(y[:, :, mask], nan=0.0, posinf=0.0, neginf=0.0) / tg.sigma[None, :, None]
            if not sim.ok.all():
                r[~sim.ok] = 2.0 * meas[None] + np.where(meas[None] >= 0, 10.0, -10.0)
            blocks.append(r.reshape(r.shape[0], -1))
        return np.concatenate(blocks, axis=1)


def part_mask(tg: Target, part: str) -> np.ndarray:
    if part == "train":
        return tg.train
    if part == "held":
        return tg.held
    if part == "all":
        return np.ones_like(tg.train)
    raise ValueError(f"part must be 'train', 'held' or 'all', got {part!r}")


def rms(r: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(r)))) if r.size else float("nan")


def lag1_autocorrelation(r: np.ndarray) -> float:
    r = np.asarray(r, float) - np.mean(r)
    den = float(np.dot(r, r))
    return float(np.dot(r[1:], r[:-1]) / den) if den > 0 and r.size > 2 else 0.0
