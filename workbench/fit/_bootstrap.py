"""Parameter intervals when the fitted model does not explain the record: a moving-block bootstrap over the record.

The Jacobian's ``cov = s² (JᵀJ)⁻¹`` (:mod:`workbench.fit._optimiser`) is honest when what is left is noise — white or
correlated (the lag-1 inflation). When the model leaves *structure* (held-out error above the noise floor: a wrong or
incomplete model), the optimum is a compromise between parts of the record that pull the parameters different ways,
and the Jacobian, which sees only the residual's size, states intervals many standard errors away from the truth.

The block bootstrap sees that structure. The training samples are resampled in contiguous blocks (moving-block
bootstrap, Künsch 1989): replicate b weights sample i by how many of its drawn blocks cover i, and the parameters
are refitted to the weighted training residual Σ w_bi r_i(u)². A part of the record that pulls the parameters its own
way is drawn more often in some replicates and less in others, so the spread of the refitted values shows how much
the answer depends on which part of the record one believes.

* **Block length** from the training residual's autocorrelation: twice the lag beyond which its magnitude stays
  below 1/e (the blocks keep the residual's dependence, also an oscillating one's), at least 1 and at most an
  eighth of the samples.
* **Refit** from the fitted point, all replicates as one batch per iteration: damped Gauss–Newton steps with the
  Jacobian of the fitted point (weighted by the replicate's block counts; a step that does not lower the replicate's
  weighted cost is refused and the damping raised), in the unit box of the free parameters.
* **Intervals**: the standard error is the larger of the replicates' standard deviation and the Jacobian's; the 95 %
  interval spans the 2.5 and 97.5 percentiles of the refitted values and ± 1.96 standard errors (so it is never
  narrower than the Jacobian's, and a few replicates that jump to another basin widen it).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from workbench.fit._objective import Objective
from workbench.fit._optimiser import FitOutcome, train_residual_and_jacobian

#: above this held-out RMS (noise σ) the model does not explain the record and intervals come from the bootstrap
MODEL_EXPLAINS_SIGMA = 1.5
#: replicates of the bootstrap and Gauss–Newton iterations per replicate (one batch of simulations each)
N_REPLICATES = 40
N_ITERATIONS = 4
LEVEL = 0.95


@dataclass(frozen=True)
class BootstrapIntervals:
    """Refitted values of the free parameters over the replicates, and what they give."""

    values: np.ndarray  # (n_replicates, k) in the parameters' own units
    block_length: int  # samples
    n_iterations: int
    level: float

    @property
    def n_replicates(self) -> int:
        return int(self.values.shape[0])

    @property
    def stderr(self) -> np.ndarray:
        return np.std(self.values, axis=0, ddof=1) if self.n_replicates > 1 else np.full(self.values.shape[1], np.inf)

    @property
    def lower(self) -> np.ndarray:
        return np.quantile(self.values, (1 - self.level) / 2, axis=0)

    @property
    def upper(self) -> np.ndarray:
        return np.quantile(self.values, (1 + self.level) / 2, axis=0)

    def describe(self) -> str:
        return (f"moving-block bootstrap over the training residual ({self.n_replicates} replicates, blocks of "
                f"{self.block_length} samples, refitted from the fitted point in {self.n_iterations} Gauss–Newton "
                "steps)")


def decorrelation_lag(r: np.ndarray) -> int:
    """The lag beyond which the autocorrelation of ``r`` stays within ±1/e (``r.size`` when it never does): an
    oscillating residual (a mistuned resonance) crosses 1/e within a quarter period but stays correlated over
    many periods, and its blocks must hold them."""
    r = np.asarray(r, float) - float(np.mean(r))
    n = r.size
    if n < 3 or not np.any(r):
        return 1
    f = np.fft.rfft(r, 2 * n)
    acf = np.fft.irfft(f * np.conj(f))[:n]
    acf = acf / acf[0]
    above = np.flatnonzero(np.abs(acf) >= math.exp(-1.0))
    return int(above[-1]) + 1 if above.size < n else n


def block_length(r: np.ndarray) -> int:
    """Block length (samples) for the residual ``r``: twice its decorrelation lag, within [1, n/8]."""
    return int(np.clip(2 * decorrelation_lag(r), 1, max(1, r.size // 8)))


def block_weights(n: int, length: int, n_replicates: int, rng: np.random.Generator) -> np.ndarray:
    """(n_replicates, n) moving-block bootstrap counts: each replicate draws ⌈n / length⌉ blocks of ``length``
    contiguous samples with uniformly random starts, cut to n samples in all; sample i's weight is how many drawn
    blocks cover it (the counts sum to n)."""
    if n < 1 or length < 1:
        raise ValueError(f"need n >= 1 and length >= 1, got n={n}, length={length}")
    length = min(length, n)
    n_blocks = -(-n // length)
    w = np.zeros((n_replicates, n + 1))
    starts = rng.integers(0, n - length + 1, size=(n_replicates, n_blocks))
    for b in range(n_replicates):
        for j, s in enumerate(starts[b]):
            take = min(length, n - j * length)  # the last block is cut so that n samples are drawn
            w[b, s] += 1.0
            w[b, s + take] -= 1.0
    return np.cumsum(w, axis=1)[:, :n]


def bootstrap_refit(obj: Objective, u_hat: np.ndarray, r_hat: np.ndarray, jacobian: np.ndarray,
                    weights: np.ndarray, *, n_iterations: int = N_ITERATIONS) -> np.ndarray:
    """(n_replicates, k) unit-box points minimising each replicate's weighted training cost Σ w r(u)², reached
    from ``u_hat`` (training residual ``r_hat``) by damped Gauss–Newton steps with the fixed ``jacobian`` (dr/du at
    ``u_hat``, (M, k)); every iteration simulates all replicates as one batch."""
    nb = weights.shape[0]
    U = np.tile(np.asarray(u_hat, float), (nb, 1))
    r = np.tile(r_hat, (nb, 1))
    cost = np.einsum("bm,bm->b", weights, r * r)
    lam = np.full(nb, 1e-3)
    for _ in range(n_iterations):
        steps = np.zeros_like(U)
        for b in range(nb):
            Jw = jacobian * weights[b][:, None]
            H = jacobian.T @ Jw
            H = H + lam[b] * np.diag(np.maximum(np.diag(H), 1e-12 * max(float(np.max(np.diag(H))), 1e-300)))
            try:
                steps[b] = -np.linalg.solve(H, Jw.T @ r[b])
            except np.linalg.LinAlgError:
                steps[b] = 0.0
        trial = np.clip(U + steps, 0.0, 1.0)
        sim = obj.simulate(trial)
        r_new = obj.residuals(sim, "train")
        c_new = np.einsum("bm,bm->b", weights, r_new * r_new)
        better = sim.ok & np.isfinite(c_new) & (c_new < cost)
        U[better], r[better], cost[better] = trial[better], r_new[better], c_new[better]
        lam = np.where(better, np.maximum(lam / 3.0, 1e-6), lam * 10.0)
    return U


def bootstrap_intervals(obj: Objective, u_hat: np.ndarray, jacobian: np.ndarray, *,
                        n_replicates: int = N_REPLICATES, n_iterations: int = N_ITERATIONS, seed: int = 0,
                        level: float = LEVEL) -> BootstrapIntervals:
    """The bootstrap of the module docstring at the fitted point ``u_hat`` (unit box) with its Jacobian."""
    r_hat = obj.residuals(obj.simulate(np.asarray(u_hat, float)[None]), "train")[0]
    length = block_length(r_hat)
    w = block_weights(r_hat.size, length, n_replicates, np.random.default_rng(seed))
    U = bootstrap_refit(obj, np.asarray(u_hat, float), r_hat, jacobian, w, n_iterations=n_iterations)
    values = np.column_stack([fp.from_unit(U[:, j]) for j, fp in enumerate(obj.free)]) if obj.k else U
    return BootstrapIntervals(np.asarray(values, float), length, n_iterations, level)


def apply_bootstrap(obj: Objective, outcome: FitOutcome, *, n_replicates: int = N_REPLICATES,
                    n_iterations: int = N_ITERATIONS, seed: int = 0) -> BootstrapIntervals:
    """Replace the Jacobian intervals of ``outcome``'s estimates (in place) by the bootstrap's: the standard error
    becomes the larger of the two (the Jacobian's kept as ``stderr_jacobian``), the interval the bootstrap's
    percentiles, ``interval_method`` says so. A parameter the records cannot identify stays so."""
    _, jac = train_residual_and_jacobian(obj)
    boot = bootstrap_intervals(obj, outcome.u, jac(outcome.u), n_replicates=n_replicates,
                               n_iterations=n_iterations, seed=seed, level=LEVEL)
    for j, e in enumerate(outcome.estimates):
        if not math.isfinite(e.stderr):
            continue
        e.stderr_jacobian = e.stderr
        e.stderr = max(e.stderr, float(boot.stderr[j]))
        # the union of the percentile interval and ± 1.96 standard errors: never narrower than the Jacobian's,
        # and a minority of replicates that jump to another basin (the record partly asking for another answer)
        # widens it even when the percentiles of 40 replicates leave them out
        e.interval_low = min(float(boot.lower[j]), e.value - 1.96 * e.stderr)
        e.interval_high = max(float(boot.upper[j]), e.value + 1.96 * e.stderr)
        e.interval_method = "block bootstrap"
    return boot
