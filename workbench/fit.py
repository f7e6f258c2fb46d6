"""Fit added physical effects (and freed parameters) to measurement records, with held-out scoring.

The discipline is that of the nonlinear system-identification benchmarks: parameters are fitted on a
*training* part and judged on a *held-out* part they never saw.

* **Split.** Each record is cut into ``n_blocks`` contiguous blocks; even blocks train, odd blocks are held out
  (``holdout="blocks"``, the default — every test regime is seen by both parts). With several records,
  ``holdout="records"`` holds out every second record whole. The model always runs free from rest over the whole
  record (it never sees a measured output); the split only says which samples score what.
* **Residuals** are measured − simulated on every measured channel, divided by the channel's noise level σ
  (the record's ``noise_std`` metadata, else a robust estimate from the data), so errors read in units of the
  noise floor: a held-out RMS of 1.0 σ is as good as the data allow. Long records are sub-sampled to at most
  ``max_rate_Hz`` for fitting (pointwise residuals, no filtering).
* **Optimiser.** scipy ``least_squares`` (trust-region reflective) in the unit box of the free parameters
  (log-scaled where a parameter spans decades). The finite-difference Jacobian's columns are integrated as
  *one batch* (``PlantModel.simulate(params=...)`` with k parameter rows), and so are the multi-start screening
  points — the compiled integrator runs the batch members in parallel threads.
* **Uncertainty.** Standard errors from the Jacobian at the optimum, ``cov = s² (JᵀJ)⁻¹`` with
  s² = RSS/(N − k), inflated by (1 + ρ₁)/(1 − ρ₁) for the lag-1 autocorrelation ρ₁ of the training residual;
  the correlation matrix flags parameters the data cannot separate.

:func:`fit_records` is the entry point used by ``shm fit``; :mod:`workbench.diagnose` builds on the same
:class:`Objective`.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from board_config import CORE_PARAMETER_NAMES, EffectEntry, ParameterSet, load_parameter_set
from board_config.errors import InputError
from plant import InputSignals, PhysicalEffect, PlantModel
from plant.effect import EffectError, effect_source_file, importable_by_path, resolve_effect
from workbench.effect_library import (
    FreeParameter,
    core_free_parameter,
    effect_free_parameters,
    guess_values,
    resolve_candidates,
)
from workbench.records import FrfRecord, Record
from workbench.replay import estimate_noise_std, model_output_for

#: a sub-sampled record keeps at most this rate for fitting (Hz)
DEFAULT_MAX_RATE_HZ = 250.0
DEFAULT_BLOCKS = 10
#: every training and every held-out block must hold at least this many (sub-sampled) samples
MIN_BLOCK_SAMPLES = 25
#: forward-difference step of the Jacobian in the unit box
FD_STEP = 2e-3


class FitError(InputError):
    """Fitting cannot start or cannot proceed (bad records, bad effect, a user effect producing NaN, ...)."""


# ----------------------------------------------------------------------------------------------------------------
# data: records cut into training / held-out parts


@dataclass
class Target:
    """One record prepared for fitting: the samples used, the measured channels in σ units, the split."""

    record: Record
    model: PlantModel
    inputs: InputSignals
    sample_idx: np.ndarray
    t: np.ndarray
    channels: tuple[str, ...]
    outputs: tuple[str, ...]
    units: tuple[str, ...]
    sigma: np.ndarray  # (n_ch,) SI noise level per channel
    sigma_source: tuple[str, ...]
    measured: np.ndarray  # (n_ch, n_t) SI
    train: np.ndarray  # (n_t,) bool
    held: np.ndarray  # (n_t,) bool

    @property
    def name(self) -> str:
        return self.record.name

    def out_idx(self, model: PlantModel) -> np.ndarray:
        return np.array([model.output_names.index(o) for o in self.outputs])


def _check_record(rec: Any) -> Record:
    if isinstance(rec, FrfRecord):
        raise FitError(f"{rec.path}: a frequency-response table cannot be replayed in the time domain for fitting; "
                       "give time records (mfc-shm-record/1)")
    if not isinstance(rec, Record):
        raise FitError(f"expected a measurement record, got {type(rec).__name__}")
    if not rec.outputs:
        raise FitError(f"{rec.path}: the record has no measured output channel to fit")
    return rec


def block_masks(n: int, n_blocks: int) -> tuple[np.ndarray, np.ndarray]:
    """(train, held) boolean masks of ``n`` samples cut into ``n_blocks`` contiguous blocks (even train)."""
    edges = np.linspace(0, n, n_blocks + 1).round().astype(int)
    train = np.zeros(n, bool)
    held = np.zeros(n, bool)
    for b in range(n_blocks):
        (train if b % 2 == 0 else held)[edges[b]:edges[b + 1]] = True
    return train, held


def prepare_targets(records: Sequence[Record], model_for_record: Callable[[Record], PlantModel], *,
                    holdout: str = "blocks", n_blocks: int = DEFAULT_BLOCKS,
                    max_rate_Hz: float = DEFAULT_MAX_RATE_HZ) -> list[Target]:
    """Cut records into training/held-out parts (see the module docstring); errors name record and reason."""
    if not records:
        raise FitError("no records given")
    if holdout not in ("blocks", "records"):
        raise FitError(f"holdout must be 'blocks' or 'records', got {holdout!r}")
    if holdout == "records" and len(records) < 2:
        raise FitError("holdout 'records' needs at least two records (every second one is held out); "
                       "give more records or use holdout 'blocks'")
    if n_blocks < 2 or n_blocks % 2:
        raise FitError(f"n_blocks must be an even number >= 2, got {n_blocks}")
    targets = []
    for k, raw in enumerate(records):
        rec = _check_record(raw)
        model = model_for_record(rec)
        stride = max(1, math.floor(rec.sample_rate_Hz / max_rate_Hz + 1e-9))
        idx = np.arange(0, rec.n_samples, stride)
        n = idx.size
        if holdout == "blocks":
            need = n_blocks * MIN_BLOCK_SAMPLES
            if n < need:
                raise FitError(
                    f"{rec.path}: too short to hold out: {rec.n_samples} samples ({rec.duration_s:.3g} s; {n} after "
                    f"sub-sampling to ≤ {max_rate_Hz:g} Hz) but {n_blocks} blocks of at least {MIN_BLOCK_SAMPLES} "
                    f"samples each need {need}; give a longer record, several records with holdout 'records', "
                    "or fewer blocks")
            train, held = block_masks(n, n_blocks)
        else:
            if n < 2 * MIN_BLOCK_SAMPLES:
                raise FitError(f"{rec.path}: too short: {n} samples, at least {2 * MIN_BLOCK_SAMPLES} needed")
            train = np.full(n, k % 2 == 0)
            held = ~train
        channels = tuple(rec.outputs)
        outputs = tuple(model_output_for(model, rec.path, c, rec.channels[c].model_output) for c in channels)
        meas = np.vstack([rec[c][idx] for c in channels])
        sig, src = [], []
        for c in channels:
            ch = rec.channels[c]
            if ch.noise_std is not None and ch.noise_std > 0:
                s, how = float(ch.noise_std), "record metadata noise_std"
            else:
                s, how = estimate_noise_std(rec[c]), "estimated from the data (MAD of second differences)"
            floor = 1e-6 * max(float(np.ptp(rec[c])), 1e-300)
            if not s > floor:
                s, how = floor, "floor: 1e-6 of the channel's range (noise-free data)"
            sig.append(s)
            src.append(how)
        targets.append(Target(
            record=rec, model=model, inputs=rec.input_signals(), sample_idx=idx, t=rec.t[idx].copy(),
            channels=channels, outputs=outputs, units=tuple(rec.channels[c].si_unit for c in channels),
            sigma=np.array(sig), sigma_source=tuple(src), measured=meas, train=train, held=held))
    if not any(t.train.any() for t in targets) or not any(t.held.any() for t in targets):
        raise FitError("the split leaves no training or no held-out samples")
    return targets


# ----------------------------------------------------------------------------------------------------------------
# the objective: batched simulation of parameter rows


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

    def __init__(self, targets: Sequence[Target], models: Sequence[PlantModel], free: Sequence[FreeParameter],
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


# ----------------------------------------------------------------------------------------------------------------
# the optimiser


@dataclass
class FitHistoryPoint:
    """One step of the optimiser: evaluation count, training error (RMS in σ units) and the parameters."""

    iteration: int
    n_sims: int
    train_rms_sigma: float
    values: dict[str, float]


@dataclass
class ParameterEstimate:
    name: str
    unit: str
    owner: str
    value: float
    stderr: float
    lower: float
    upper: float
    at_bound: bool

    def describe(self) -> str:
        se = "not identifiable" if not math.isfinite(self.stderr) else f"± {self.stderr:.3g}"
        return f"{self.name} = {self.value:.4g} {se} {self.unit}" + (" (at its range bound)" if self.at_bound else "")


@dataclass
class FitOutcome:
    """The optimum of one objective: estimates, training/held-out errors, history, cost of getting there."""

    u: np.ndarray
    estimates: list[ParameterEstimate]
    correlation: np.ndarray
    train_rms_sigma: float
    held_rms_sigma: float
    train_rss: float
    held_rss: float
    n_train: int
    n_held: int
    rho1_train: float
    rho1_held: float
    history: list[FitHistoryPoint]
    sim: SimBatch
    ok: bool
    message: str
    n_sims: int
    wall_s: float

    @property
    def values(self) -> dict[str, float]:
        return {e.name: e.value for e in self.estimates}


def _starts(obj: Objective, guess_u: np.ndarray | None, n_random: int, rng: np.random.Generator) -> np.ndarray:
    pts = []
    if guess_u is not None:
        pts.append(np.clip(guess_u, 0, 1))
    k = obj.k
    # a small space-filling design: stratified per dimension (Latin hypercube)
    if n_random > 0:
        perms = np.column_stack([rng.permutation(n_random) for _ in range(k)])
        pts.extend((perms + rng.uniform(0.15, 0.85, size=(n_random, k))) / n_random)
    return np.array(pts)


def train_residual_and_jacobian(obj: Objective, batched: bool = True
                                ) -> tuple[Callable[[np.ndarray], np.ndarray], Callable[[np.ndarray], np.ndarray]]:
    """The training residual ``r(u)`` (cached per point) and its forward-difference Jacobian over the unit box
    (step :data:`FD_STEP`, taken inward at the upper bound), for ``least_squares``. ``batched`` integrates the k
    perturbed points in one batch; otherwise one column at a time (what scipy's own finite differences do; the
    benchmark's baseline)."""
    k = obj.k
    cache: dict[bytes, np.ndarray] = {}

    def fun(u: np.ndarray) -> np.ndarray:
        key = np.round(u, 12).tobytes()
        if key not in cache:
            cache[key] = obj.residuals(obj.simulate(u[None]), "train")[0]
        return cache[key]

    def jac(u: np.ndarray) -> np.ndarray:
        steps = np.where(u + FD_STEP <= 1.0, FD_STEP, -FD_STEP)
        U = np.tile(u, (k, 1)) + np.diag(steps)
        r0 = fun(u)
        if batched:
            R = obj.residuals(obj.simulate(U), "train")
        else:
            R = np.vstack([obj.residuals(obj.simulate(U[j:j + 1]), "train") for j in range(k)])
        return ((R - r0[None]) / steps[:, None]).T

    return fun, jac


def optimise(obj: Objective, guess: Mapping[str, float] | None = None, *, n_screen: int | None = None,
             n_refine: int = 2, max_nfev: int = 40, seed: int = 0, stop_at_rms: float = 1.05,
             on_iteration: Callable[[FitHistoryPoint], None] | None = None,
             batched_jacobian: bool = True) -> FitOutcome:
    """Multi-start least squares in the unit box (see the module docstring).

    A batch of screening points (the guess + a Latin hypercube) is simulated at once, then a finer batch
    around the best of them (unless it is already at the noise floor); the best ``n_refine`` (and the guess) are
    refined by ``least_squares`` with the batched Jacobian (a further start is skipped once the training RMS is
    at ``stop_at_rms`` noise levels); the best training cost wins.
    """
    t_start = time.perf_counter()
    sims0 = obj.n_sims
    history: list[FitHistoryPoint] = []
    rng = np.random.default_rng(seed)
    k = obj.k
    if k == 0:
        sim = obj.simulate(np.zeros((1, 0)))
        return _outcome(obj, np.zeros(0), sim, None, history, "no free parameters", t_start, sims0)
    guess_u = None
    if guess:
        guess_u = np.array([float(fp.to_unit(guess.get(fp.name, fp.from_unit(0.5)))) for fp in obj.free])
    n_screen = n_screen if n_screen is not None else max(12, 4 * k + 4)
    U0 = _starts(obj, guess_u, n_screen, rng)
    sim0 = obj.simulate(U0)
    cost0 = np.array([rms(r) for r in obj.residuals(sim0, "train")])
    cost0[~sim0.ok] = np.inf
    order = np.argsort(cost0)
    if np.isfinite(cost0[order[0]]) and cost0[order[0]] > stop_at_rms:
        # zoom: a second, finer design around the best point (resonant records have narrow basins — a
        # stiffness or clamp compliance that puts a mode at the right time of a sweep — which a coarse design
        # brackets but rarely hits)
        half = 1.5 / n_screen ** (1.0 / k)
        centre = U0[order[0]]
        lo, hi = np.clip(centre - half, 0, 1), np.clip(centre + half, 0, 1)
        n_zoom = n_screen + 4
        perms = np.column_stack([rng.permutation(n_zoom) for _ in range(k)])
        Uz = lo + (hi - lo) * (perms + rng.uniform(0.2, 0.8, size=(n_zoom, k))) / n_zoom
        simz = obj.simulate(Uz)
        costz = np.array([rms(r) for r in obj.residuals(simz, "train")])
        costz[~simz.ok] = np.inf
        U0 = np.vstack([U0, Uz])
        cost0 = np.concatenate([cost0, costz])
        order = np.argsort(cost0)
    best_seen = [float(cost0[order[0]])]
    it = [0]

    def note(u: np.ndarray, cost_rms: float) -> None:
        if cost_rms < best_seen[0] * (1 - 1e-9) or not history:
            best_seen[0] = min(best_seen[0], cost_rms)
        it[0] += 1
        pt = FitHistoryPoint(it[0], obj.n_sims - sims0, best_seen[0], obj.values(u))
        history.append(pt)
        if on_iteration is not None:
            on_iteration(pt)

    note(U0[order[0]], float(cost0[order[0]]))
    fun, jac = train_residual_and_jacobian(obj, batched=batched_jacobian)

    def callback(intermediate_result):
        note(intermediate_result.x, math.sqrt(2.0 * intermediate_result.cost / max(len(fun(intermediate_result.x)),
                                                                                   1)))

    # refine the best screening points, and always the data-informed guess (row 0): a narrow basin (a current
    # limit that binds only near its true value) can look worse than a flat region at coarse screening
    refine = list(order[:n_refine])
    if guess_u is not None and 0 not in refine:
        refine = [refine[0], 0, *refine[1:]][:max(n_refine, 2)]
    results = []
    for j in refine:
        if not np.isfinite(cost0[j]):
            continue
        if results and rms(min(results, key=lambda r: r.cost).fun) <= stop_at_rms:
            break  # already at the noise floor: another start cannot do better
        try:
            res = least_squares(fun, U0[j], jac=jac, bounds=(np.zeros(k), np.ones(k)), method="trf",
                                x_scale=1.0, max_nfev=max_nfev, ftol=1e-6, xtol=1e-6, gtol=1e-8,
                                callback=callback)
        except (ValueError, FloatingPointError) as exc:
            raise FitError(f"the optimiser failed: {exc}") from exc
        results.append(res)
    if not results:
        best_u = U0[order[0]]
        message = "every screening point failed to integrate"
    else:
        best = min(results, key=lambda r: r.cost)
        best_u = best.x
        message = str(best.message)
    sim = obj.simulate(best_u[None])
    return _outcome(obj, best_u, sim, jac if results else None, history, message, t_start, sims0)


def _outcome(obj: Objective, u: np.ndarray, sim: SimBatch, jac, history, message: str, t_start: float,
             sims0: int) -> FitOutcome:
    r_tr = obj.residuals(sim, "train")[0]
    r_he = obj.residuals(sim, "held")[0]
    k = obj.k
    rho_tr = lag1_autocorrelation(r_tr)
    estimates: list[ParameterEstimate] = []
    corr = np.eye(k)
    if k:
        values = obj.values(u)
        stderr = np.full(k, np.inf)
        if jac is not None and sim.ok.all():
            J = jac(u)
            d = np.array([fp.dvalue_du(values[fp.name]) for fp in obj.free])
            Jp = J / d[None, :]
            n = r_tr.size
            s2 = float(np.dot(r_tr, r_tr)) / max(n - k, 1)
            rho = min(max(rho_tr, 0.0), 0.99)
            infl = (1 + rho) / (1 - rho)
            jtj = Jp.T @ Jp
            try:
                cov = np.linalg.inv(jtj) * s2 * infl
                diag = np.diag(cov)
                ok = np.all(np.isfinite(diag)) and np.all(diag >= 0) and np.linalg.cond(jtj) < 1e14
            except np.linalg.LinAlgError:
                ok = False
            if ok:
                stderr = np.sqrt(diag)
                with np.errstate(invalid="ignore", divide="ignore"):
                    corr = cov / np.outer(stderr, stderr)
            col_norm = np.linalg.norm(J, axis=0)
            stderr[col_norm < 1e-12 * max(float(np.max(col_norm)), 1e-300)] = np.inf
        for j, fp in enumerate(obj.free):
            uj = float(u[j])
            estimates.append(ParameterEstimate(fp.name, fp.unit, fp.owner, values[fp.name], float(stderr[j]),
                                               fp.lower, fp.upper, at_bound=(uj <= 1e-6 or uj >= 1 - 1e-6)))
    return FitOutcome(
        u=np.array(u, float), estimates=estimates, correlation=corr, train_rms_sigma=rms(r_tr),
        held_rms_sigma=rms(r_he), train_rss=float(np.dot(r_tr, r_tr)), held_rss=float(np.dot(r_he, r_he)),
        n_train=int(r_tr.size), n_held=int(r_he.size), rho1_train=rho_tr, rho1_held=lag1_autocorrelation(r_he),
        history=history, sim=sim, ok=bool(sim.ok.all()), message=message, n_sims=obj.n_sims - sims0,
        wall_s=time.perf_counter() - t_start)


# ----------------------------------------------------------------------------------------------------------------
# scoreboards


@dataclass
class ChannelScore:
    """One channel on one part (training or held-out), SI units and in units of its noise level."""

    record: str
    channel: str
    unit: str
    part: str
    n: int
    rms: float
    sigma: float
    fit_pct: float

    @property
    def rms_sigma(self) -> float:
        return self.rms / self.sigma


def channel_scores(targets: Sequence[Target], sim: SimBatch, member: int = 0) -> list[ChannelScore]:
    out = []
    for tg, y in zip(targets, sim.y):
        for part, mask in (("train", tg.train), ("held", tg.held)):
            if not mask.any():
                continue
            for j, c in enumerate(tg.channels):
                meas = tg.measured[j, mask]
                e = meas - y[member, j, mask]
                den = float(np.linalg.norm(meas - meas.mean()))
                fitp = 100.0 * (1 - float(np.linalg.norm(e)) / den) if den > 0 else float("nan")
                out.append(ChannelScore(tg.name, c, tg.units[j], part, int(mask.sum()), rms(e), float(tg.sigma[j]),
                                        fitp))
    return out


# ----------------------------------------------------------------------------------------------------------------
# shm fit


@dataclass
class FitReport:
    """What ``shm fit`` reports: before/after on training and held-out data, estimates, history, the new set."""

    added: list[str]
    free: list[FreeParameter]
    outcome: FitOutcome
    before: list[ChannelScore]
    after: list[ChannelScore]
    before_train_rms_sigma: float
    before_held_rms_sigma: float
    base_set: ParameterSet
    model: PlantModel
    save_name: str
    targets: list[Target]
    baseline_sim: SimBatch
    wall_s: float
    notes: list[str] = field(default_factory=list)

    @property
    def parameter_set(self) -> ParameterSet:
        """The fitted parameter set (``[[effects]]`` with every added effect); :class:`FitError` when an added
        effect cannot be referred to from a file (defined in a script or a function)."""
        return fitted_parameter_set(self.base_set, self.model, self.outcome.values, self.save_name, meta={
            "description": f"{self.base_set.name} + {', '.join(self.added) or 'refit'}, fitted by shm fit to "
                           f"{', '.join(tg.name for tg in self.targets)}",
            "fitted_from": self.base_set.name,
        })

    def summary(self) -> dict[str, Any]:
        o = self.outcome
        return {
            "added_effects": self.added,
            "free_parameters": [fp.describe() for fp in self.free],
            "estimates": [e.__dict__ for e in o.estimates],
            "correlation": o.correlation.tolist(),
            "train_rms_sigma": {"before": self.before_train_rms_sigma, "after": o.train_rms_sigma},
            "held_rms_sigma": {"before": self.before_held_rms_sigma, "after": o.held_rms_sigma},
            "channels_before": [s.__dict__ | {"rms_sigma": s.rms_sigma} for s in self.before],
            "channels_after": [s.__dict__ | {"rms_sigma": s.rms_sigma} for s in self.after],
            "history": [h.__dict__ for h in o.history],
            "optimiser": o.message,
            "simulations": o.n_sims,
            "wall_s": self.wall_s,
            "parameter_set": self.save_name,
            "notes": self.notes,
        }


def effect_entry_name(cls: type[PhysicalEffect]) -> str:
    """How a parameter set refers to an effect: its registered name, else its dotted path."""
    try:
        if resolve_effect(cls.name) is cls:
            return cls.name
    except EffectError:
        pass
    source_file = effect_source_file(cls)
    if source_file is not None:  # loaded from a file: refer to it by its absolute path
        return f"{source_file}:{cls.__qualname__}"
    if not importable_by_path(cls):
        raise FitError(f"effect '{cls.name}' ({cls.__module__}.{cls.__qualname__}) is defined in a script or inside "
                       "a function, so a parameter set cannot refer to it; put it in an importable module and add "
                       "it as 'package.module:ClassName'")
    return f"{cls.__module__}:{cls.__qualname__}"


def fitted_parameter_set(base: ParameterSet, model: PlantModel, values: Mapping[str, float], name: str,
                         meta: Mapping[str, Any] | None = None) -> ParameterSet:
    """``base`` with fitted core values and every added effect (with all its parameter values) as ``[[effects]]``;
    loadable at once by :class:`PlantModel` (``shm run``, the board monitor)."""
    p = model.p_nominal.copy()
    for n, v in values.items():
        p[model.param_index(n)] = v
    core_changes = {n: float(p[model.param_index(n)]) for n in CORE_PARAMETER_NAMES
                    if float(p[model.param_index(n)]) != float(base.values[n])}
    new = base.with_values(name=name, **core_changes) if core_changes else base
    entries = []
    for cls in model.effects:
        if cls.role != "effect":
            continue
        own = cls.own_parameters()
        entries.append(EffectEntry(effect_entry_name(cls),
                                   {q.name: float(p[model.param_index(q.name)]) for q in own},
                                   {q.name: q.unit for q in own}))
    merged_meta = dict(new.meta)
    merged_meta.update(meta or {})
    merged_meta["name"] = name
    return ParameterSet(name, new.values, new.details, tuple(entries), merged_meta, new.source)


def model_factory(params: ParameterSet, effects: Sequence[type[PhysicalEffect]]):
    """A per-record model builder (cached by terminal)."""
    cache: dict[str, PlantModel] = {}

    def build(rec: Record) -> PlantModel:
        terminal = rec.terminal or ("open_circuit" if rec.drive()[0] == "z0dd" else "amplifier")
        if terminal not in cache:
            cache[terminal] = PlantModel(params, effects=list(effects), terminal=terminal)
        return cache[terminal]

    return build


def check_effect_runs(model: PlantModel, cls: type[PhysicalEffect], target: Target) -> None:
    """Run the composed model once on a short stretch of a record; a user effect that produces NaN/Inf or
    writes outside its slots is reported by name."""
    n = min(target.inputs.n_samples, max(50, int(0.2 / target.inputs.dt)))
    short = InputSignals(target.inputs.t0, target.inputs.dt, target.inputs.values[:, :n])
    t_end = short.t[-1]
    try:
        res = model.simulate(short, t_end=t_end, dt_out=max(t_end / 20, short.dt))
    except (IndexError, ValueError) as exc:
        raise FitError(f"effect '{cls.name}': the composed model fails to run: {type(exc).__name__}: {exc} — "
                       "check that the hooks only index x[so + k], p[po + k] and y[yo + k] within what the effect "
                       "declares") from exc
    if not res.ok or not np.all(np.isfinite(res.y)):
        bad = [n for j, n in enumerate(res.output_names) if not np.all(np.isfinite(res.y[0, :, j]))]
        raise FitError(f"effect '{cls.name}': the model with this effect produces non-finite values at its starting "
                       f"parameters ({'; '.join(res.failures()) or 'outputs ' + ', '.join(bad[:5])}) — check the "
                       "effect's hooks (division by a zero parameter? NaN written to the bus or to y?)")


def fit_records(records: Sequence[Record], params: ParameterSet | str = "table2",
                add: Sequence[str | type[PhysicalEffect]] = (), free: Sequence[str] = (), *,
                save_name: str = "fitted", holdout: str = "blocks", n_blocks: int = DEFAULT_BLOCKS,
                max_rate_Hz: float = DEFAULT_MAX_RATE_HZ, max_nfev: int = 40, seed: int = 0,
                on_iteration: Callable[[FitHistoryPoint], None] | None = None,
                on_baseline: Callable[[float, float], None] | None = None) -> FitReport:
    """Add ``add`` to the model, fit their parameters (and ``free`` ones: ``name`` or ``name:lower:upper``)
    on the training part of ``records``, and score before/after on training and held-out data.

    ``on_baseline(train_rms_sigma, held_rms_sigma)`` is called once the starting model has been scored,
    ``on_iteration(point)`` at every optimiser iteration (the live display of ``shm fit``)."""
    t0 = time.perf_counter()
    base = params if isinstance(params, ParameterSet) else load_parameter_set(params)
    try:
        classes = resolve_candidates(add)
    except EffectError as exc:
        raise FitError(str(exc)) from None
    base_build = model_factory(base, [])
    targets = prepare_targets(records, base_build, holdout=holdout, n_blocks=n_blocks, max_rate_Hz=max_rate_Hz)
    base_models = [tg.model for tg in targets]
    base_obj = Objective(targets, base_models, [])
    base_sim = base_obj.simulate(np.zeros((1, 0)), keep_full=True)
    if not base_sim.ok.all():
        raise FitError("the starting model fails to integrate on the records: "
                       + "; ".join(f"{tg.name}: status {int(s[0])}" for tg, s in zip(targets, base_sim.status)))
    # the effects' own starting guesses first (cheap; a malformed guess fails before anything compiles)
    data = guess_data(targets[0], base_sim, base_models[0])
    free_params: list[FreeParameter] = []
    guess: dict[str, float] = {}
    for cls in classes:
        try:
            own = effect_free_parameters(cls)
            guess.update(guess_values(cls, data, own))
        except EffectError as exc:
            raise FitError(str(exc)) from None
        free_params.extend(own)
    try:
        build = model_factory(base, classes)
        models = [build(tg.record) for tg in targets]
    except EffectError as exc:
        raise FitError(str(exc)) from None
    for cls in classes:
        check_effect_runs(models[0], cls, targets[0])
    for spec in free:
        try:
            fp = core_free_parameter(models[0], spec)
        except (EffectError, ValueError) as exc:
            raise FitError(str(exc)) from None
        free_params = [q for q in free_params if q.name != fp.name] + [fp]
    if not free_params:
        raise FitError("nothing to fit: add an effect (--add) or free a parameter (--free)")
    before = channel_scores(targets, base_sim)
    before_train = rms(base_obj.residuals(base_sim, "train")[0])
    before_held = rms(base_obj.residuals(base_sim, "held")[0])
    if on_baseline is not None:
        on_baseline(before_train, before_held)
    for fp in free_params:
        if fp.name not in guess:
            guess[fp.name] = float(models[0].p_nominal[models[0].param_index(fp.name)])
    obj = Objective(targets, models, free_params)
    outcome = optimise(obj, guess, max_nfev=max_nfev, seed=seed, on_iteration=on_iteration)
    if not outcome.ok:
        raise FitError(f"the fitted model fails to integrate on the records ({outcome.message})")
    after = channel_scores(targets, outcome.sim)
    notes = []
    for e in outcome.estimates:
        if e.at_bound:
            notes.append(f"{e.name} ended at a bound of its range [{e.lower:g}, {e.upper:g}] {e.unit}: widen it "
                         f"with --free {e.name}:LOWER:UPPER if the physics allows")
    return FitReport(
        added=[c.name for c in classes], free=free_params, outcome=outcome, before=before, after=after,
        before_train_rms_sigma=before_train, before_held_rms_sigma=before_held,
        base_set=base, model=models[0], save_name=save_name, targets=targets, baseline_sim=base_sim,
        wall_s=time.perf_counter() - t0, notes=notes)


def guess_data(target: Target, base_sim: SimBatch, model: PlantModel) -> dict[str, Any]:
    """The mapping an effect's ``guess`` reads (see :mod:`plant.effects.library_support`)."""
    full = base_sim.full[0][0] if base_sim.full else None
    rec = target.record
    u = rec.input_matrix()[target.sample_idx]
    data: dict[str, Any] = {
        "t_s": target.t,
        "inputs": {"v_ch1": u[:, 0], "v_ch2": u[:, 1], "z0dd": u[:, 2]},
        "measured": {o: target.measured[j] for j, o in enumerate(target.outputs)},
        "params": dict(zip(model.param_names, map(float, model.p_nominal))),
    }
    if full is not None:
        data["predicted"] = {n: full[:, j] for j, n in enumerate(model.output_names)}
    return data
