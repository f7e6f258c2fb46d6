"""Which physical effect is missing? Fit every candidate effect, score it on held-out data, rank, explain.

For each candidate effect (default: the whole library, :data:`workbench.effect_library.LIBRARY`):

1. add it to the model and fit its few parameters on the *training* part of the records
   (:func:`workbench.fit.optimise`: batched multi-start ``least_squares``);
2. score it on the *held-out* part: the reduction of the held-out residual energy against the nominal model,
   and a BIC-penalised held-out log-likelihood ratio

       ΔBIC_held = N_eff · ln(RSS₀/RSS) − k · ln(N_eff),   N_eff = N (1 − ρ₁)/(1 + ρ₁),

   with RSS in noise units, k the candidate's free parameters and ρ₁ the lag-1 autocorrelation of the
   candidate's held-out residual (a candidate that leaves structured residual earns fewer effective samples);
   training AIC/BIC are reported beside it;
3. reject it when its free run diverges (an integration failure or an output beyond 10× the measured range) or
   goes flat (output range below 5 % of the measured range where the measurement clearly moves);
4. accept it when it is stable, ΔBIC_held > 0 and it removes at least ``min_reduction`` (2 %) of the held-out
   residual energy.

The accepted candidates are ranked by ΔBIC_held; the best is "the missing effect" when it brings the held-out error
to within 2 σ, else "partly explained" (with where the rest lives). No accepted candidate: "nothing missing" when
the nominal model is already at the noise floor (held-out RMS ≤ 1.25 σ), else "not explained by the library", with
where the residual lives (test regimes, frequency bands) and the residual tests that fail.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from board_config import ParameterSet, load_parameter_set
from plant import PhysicalEffect
from plant.effect import EffectError
from workbench.effect_library import LIBRARY, FreeParameter, effect_free_parameters, guess_values, resolve_candidates
from workbench.fit import (
    DEFAULT_BLOCKS,
    DEFAULT_MAX_RATE_HZ,
    ChannelScore,
    FitError,
    FitOutcome,
    Objective,
    SimBatch,
    Target,
    channel_scores,
    check_effect_runs,
    guess_data,
    model_factory,
    optimise,
    prepare_targets,
    rms,
)
from workbench.localisation import localise, model_features
from workbench.records import Record
from workbench.residual_tests import ResidualTests, residual_tests

MIN_REDUCTION = 0.02
AT_NOISE_FLOOR = 1.25
#: a winner whose fitted model stays further than this (held-out RMS, σ) from the data explains only part of it
PARTIAL_ABOVE = 2.0


@dataclass
class CandidateResult:
    """One candidate effect, fitted and scored."""

    effect: str
    description: str
    origin: str
    signature: str
    free: list[FreeParameter]
    outcome: FitOutcome | None
    held_reduction: float = float("nan")  # 1 − RSS_held / RSS0_held
    delta_bic_held: float = float("-inf")
    n_eff_held: float = 0.0
    aic_train: float = float("nan")
    bic_train: float = float("nan")
    stable: bool = False
    rejection: str = ""
    accepted: bool = False
    channels: list[ChannelScore] = field(default_factory=list)
    wall_s: float = 0.0
    n_sims: int = 0
    load_s: float = 0.0  # composing / loading the compiled kernels
    sim_s: float = 0.0  # inside the batched integrator

    @property
    def held_rms_sigma(self) -> float:
        return self.outcome.held_rms_sigma if self.outcome else float("nan")

    @property
    def train_rms_sigma(self) -> float:
        return self.outcome.train_rms_sigma if self.outcome else float("nan")

    def estimates_text(self) -> str:
        if not self.outcome:
            return ""
        return "; ".join(e.describe() for e in self.outcome.estimates)

    def to_dict(self) -> dict[str, Any]:
        o = self.outcome
        return {
            "effect": self.effect, "description": self.description, "accepted": self.accepted,
            "stable": self.stable, "rejection": self.rejection, "held_reduction": self.held_reduction,
            "delta_bic_held": self.delta_bic_held, "n_eff_held": self.n_eff_held, "aic_train": self.aic_train,
            "bic_train": self.bic_train, "train_rms_sigma": self.train_rms_sigma,
            "held_rms_sigma": self.held_rms_sigma,
            "free_parameters": [fp.describe() for fp in self.free],
            "estimates": [e.__dict__ for e in o.estimates] if o else [],
            "correlation": o.correlation.tolist() if o else [],
            "channels": [s.__dict__ | {"rms_sigma": s.rms_sigma} for s in self.channels],
            "signature": self.signature, "origin": self.origin, "wall_s": self.wall_s, "simulations": self.n_sims,
            "load_s": self.load_s, "integrator_s": self.sim_s,
            "optimiser": o.message if o else "",
        }


@dataclass
class Diagnosis:
    """The ranked candidates and the verdict in words."""

    verdict: str  # "missing" | "partial" | "nothing_missing" | "unexplained"
    message: str
    winner: CandidateResult | None
    ranking: list[CandidateResult]
    baseline_train_rms_sigma: float
    baseline_held_rms_sigma: float
    baseline_channels: list[ChannelScore]
    where_it_fails: list[str]
    tests_before: list[ResidualTests]
    tests_after: list[ResidualTests]
    targets: list[Target]
    baseline_sim: SimBatch
    params_name: str
    timings: dict[str, float]
    notes: list[str] = field(default_factory=list)

    @property
    def ranked_names(self) -> list[str]:
        return [c.effect for c in self.ranking]

    def to_dict(self) -> dict[str, Any]:
        return {
            "verdict": self.verdict, "message": self.message,
            "winner": self.winner.effect if self.winner else None,
            "ranking": [c.to_dict() for c in self.ranking],
            "baseline": {"params": self.params_name, "train_rms_sigma": self.baseline_train_rms_sigma,
                         "held_rms_sigma": self.baseline_held_rms_sigma,
                         "channels": [s.__dict__ | {"rms_sigma": s.rms_sigma} for s in self.baseline_channels]},
            "where_it_fails": self.where_it_fails,
            "residual_tests_before": [_tests_summary(t) for t in self.tests_before],
            "residual_tests_after": [_tests_summary(t) for t in self.tests_after],
            "records": [{"name": tg.name, "test": tg.record.test, "samples_used": int(tg.t.size),
                         "train_samples": int(tg.train.sum()), "held_samples": int(tg.held.sum()),
                         "channels": list(tg.channels), "noise_sigma": tg.sigma.tolist(),
                         "noise_source": list(tg.sigma_source)} for tg in self.targets],
            "timings_s": self.timings, "notes": self.notes,
        }


def _tests_summary(t: ResidualTests) -> dict[str, Any]:
    return {"channel": t.channel, "input": t.input_name, "adequate": t.adequate,
            "failed": [x.key for x in t.failed],
            "tests": {x.key: {"verdict": x.verdict, "ratio": x.ratio} for x in t.tests}}


# ----------------------------------------------------------------------------------------------------------------


def _stability(outcome: FitOutcome, targets: Sequence[Target]) -> str:
    """'' when the free run is sound, else why it is rejected."""
    if not outcome.ok:
        return "free-run simulation diverged (integration failed) at the fitted parameters"
    for tg, y in zip(targets, outcome.sim.y):
        for j, c in enumerate(tg.channels):
            meas_range = float(np.ptp(tg.measured[j]))
            sim = y[0, j]
            if not np.all(np.isfinite(sim)):
                return f"free run produced non-finite {c} on {tg.name}"
            if float(np.max(np.abs(sim - np.median(tg.measured[j])))) > 10.0 * max(meas_range, 10 * tg.sigma[j]):
                return f"free run diverges: {c} on {tg.name} leaves 10× the measured range"
            if meas_range > 20.0 * tg.sigma[j] and float(np.ptp(sim)) < 0.05 * meas_range:
                return f"free run goes flat: {c} on {tg.name} varies by less than 5 % of the measurement"
    return ""


def _score(cand: CandidateResult, rss0_held: float, min_reduction: float) -> None:
    o = cand.outcome
    assert o is not None
    k = len(cand.free)
    rho = min(max(o.rho1_held, 0.0), 0.99)
    n_eff = max(o.n_held * (1 - rho) / (1 + rho), k + 2.0)
    cand.n_eff_held = n_eff
    cand.held_reduction = 1.0 - o.held_rss / rss0_held if rss0_held > 0 else float("nan")
    ratio = rss0_held / max(o.held_rss, 1e-300)
    cand.delta_bic_held = n_eff * math.log(ratio) - k * math.log(n_eff)
    n = max(o.n_train, 1)
    ll = n * math.log(max(o.train_rss, 1e-300) / n)
    cand.aic_train = ll + 2 * k
    cand.bic_train = ll + k * math.log(n)
    cand.accepted = cand.stable and cand.delta_bic_held > 0 and cand.held_reduction >= min_reduction


def fit_candidate(cls: type[PhysicalEffect], params: ParameterSet, targets: Sequence[Target], data: dict[str, Any],
                  rss0_held: float, *, min_reduction: float = MIN_REDUCTION, threads: int | None = None,
                  max_nfev: int = 30, seed: int = 0, batched_jacobian: bool = True,
                  on_iteration: Callable[[Any], None] | None = None) -> CandidateResult:
    """Fit one candidate on the training part and score it on the held-out part."""
    t0 = time.perf_counter()
    free = effect_free_parameters(cls)
    cand = CandidateResult(cls.name, cls.description, cls.origin, cls.signature, free, None)
    build = model_factory(params, [cls])
    try:
        models = [build(tg.record) for tg in targets]
        for m in models:
            m.kernels()
    except EffectError as exc:
        raise FitError(str(exc)) from None
    cand.load_s = time.perf_counter() - t0
    check_effect_runs(models[0], cls, targets[0])
    obj = Objective(targets, models, free, threads=threads)
    try:
        guess = guess_values(cls, data, free)
    except EffectError as exc:
        raise FitError(str(exc)) from None
    outcome = optimise(obj, guess, max_nfev=max_nfev, seed=seed, on_iteration=on_iteration,
                       batched_jacobian=batched_jacobian)
    cand.outcome = outcome
    cand.rejection = _stability(outcome, targets)
    cand.stable = not cand.rejection
    if outcome.ok:
        cand.channels = channel_scores(targets, outcome.sim)
    _score(cand, rss0_held, min_reduction)
    cand.wall_s = time.perf_counter() - t0
    cand.n_sims = outcome.n_sims
    cand.sim_s = obj.sim_wall_s
    return cand


def _input_for_tests(tg: Target) -> tuple[str, np.ndarray]:
    name, _unit, values = tg.record.drive()
    return name, values[tg.sample_idx]


def run_residual_tests(targets: Sequence[Target], sim: SimBatch) -> list[ResidualTests]:
    out = []
    for tg, y in zip(targets, sim.y):
        uname, u = _input_for_tests(tg)
        for j, c in enumerate(tg.channels):
            e = tg.measured[j] - y[0, j]
            try:
                out.append(residual_tests(e, u, channel=f"{tg.name}:{c}", input_name=uname))
            except ValueError:
                continue
    return out


def where_it_fails(targets: Sequence[Target], sim: SimBatch) -> list[str]:
    """Where the residual lives, in words (workbench part 1's localisation: time windows by test regime,
    error-carrying frequency bands, residual against input amplitude and rate, branches), per record and channel."""
    lines = []
    for tg, y in zip(targets, sim.y):
        uname, u = _input_for_tests(tg)
        unit = tg.record.drive()[1]
        for j, c in enumerate(tg.channels):
            try:
                loc = localise(tg.t, tg.measured[j], y[0, j], u, channel=f"{tg.name}:{c}", unit=tg.units[j],
                               drive_name=uname, drive_unit=unit, segments=tg.record.segments,
                               noise_std=float(tg.sigma[j]), features=model_features(tg.model))
            except ValueError as exc:
                lines.append(f"{tg.name}:{c}: localisation not available ({exc})")
                continue
            lines.append(" ".join(loc.findings))
    return lines


def diagnose(records: Sequence[Record], params: ParameterSet | str = "table2",
             candidates: Sequence[str | type[PhysicalEffect]] | None = None, *, holdout: str = "blocks",
             n_blocks: int = DEFAULT_BLOCKS, max_rate_Hz: float = DEFAULT_MAX_RATE_HZ,
             min_reduction: float = MIN_REDUCTION, workers: int = 1, max_nfev: int = 30, seed: int = 0,
             progress: Callable[[str, CandidateResult | None], None] | None = None,
             batched_jacobian: bool = True) -> Diagnosis:
    """Rank ``candidates`` (default: the library) by how much of the held-out residual each explains.

    ``workers`` > 1 fits candidates concurrently in threads (each simulation single-threaded; the compiled
    integrator releases the GIL). ``batched_jacobian=False`` integrates the Jacobian's columns one at a time
    (the benchmark's baseline). ``progress(name, result)`` is called when a candidate starts (result None)
    and when it is done.
    """
    t_start = time.perf_counter()
    base = params if isinstance(params, ParameterSet) else load_parameter_set(params)
    try:
        classes = resolve_candidates(LIBRARY if candidates is None else candidates)
    except EffectError as exc:
        raise FitError(str(exc)) from None
    present = {e.name for e in base.effects}
    skipped = [c.name for c in classes if c.name in present or c.__module__ + ":" + c.__qualname__ in present]
    classes = [c for c in classes if c.name not in skipped]
    if not classes:
        raise FitError("no candidate effects left to try (every candidate is already in the parameter set)")
    targets = prepare_targets(records, model_factory(base, []), holdout=holdout, n_blocks=n_blocks,
                              max_rate_Hz=max_rate_Hz)
    base_obj = Objective(targets, [tg.model for tg in targets], [])
    t0 = time.perf_counter()
    base_sim = base_obj.simulate(np.zeros((1, 0)), keep_full=True)
    if not base_sim.ok.all():
        raise FitError("the nominal model fails to integrate on the records")
    r0_train = base_obj.residuals(base_sim, "train")[0]
    r0_held = base_obj.residuals(base_sim, "held")[0]
    rss0_held = float(np.dot(r0_held, r0_held))
    timings = {"baseline_s": time.perf_counter() - t0}
    data = guess_data(targets[0], base_sim, targets[0].model)
    threads = 1 if workers > 1 else None

    def one(cls: type[PhysicalEffect]) -> CandidateResult:
        if progress:
            progress(cls.name, None)
        res = fit_candidate(cls, base, targets, data, rss0_held, min_reduction=min_reduction, threads=threads,
                            max_nfev=max_nfev, seed=seed, batched_jacobian=batched_jacobian)
        if progress:
            progress(cls.name, res)
        return res

    if workers > 1:
        # compile (or load) every composition first, serially: the kernels cache is shared
        for cls in classes:
            for tg in targets:
                model_factory(base, [cls])(tg.record).kernels()
        with ThreadPoolExecutor(workers) as pool:
            results = list(pool.map(one, classes))
    else:
        results = [one(c) for c in classes]
    for c in results:
        timings[f"candidate_{c.effect}_s"] = c.wall_s
    ranking = sorted(results, key=lambda c: (not c.accepted, -c.delta_bic_held if c.stable else math.inf))
    winner = ranking[0] if ranking and ranking[0].accepted else None
    base_train, base_held = rms(r0_train), rms(r0_held)
    t1 = time.perf_counter()
    tests_before = run_residual_tests(targets, base_sim)
    tests_after = run_residual_tests(targets, winner.outcome.sim) if winner and winner.outcome else []
    where = where_it_fails(targets, base_sim)
    timings["residual_tests_and_localisation_s"] = time.perf_counter() - t1
    notes = [f"skipped {', '.join(skipped)}: already in the parameter set"] if skipped else []
    if any("estimated" in s for tg in targets for s in tg.sigma_source):
        notes.append("the noise level was estimated from the data (no noise_std in the record metadata): "
                     "errors quoted in σ are only as good as that estimate")
    verdict, message = _verdict(winner, ranking, base_held, where, tests_before, tests_after)
    timings["total_s"] = time.perf_counter() - t_start
    return Diagnosis(verdict, message, winner, ranking, base_train, base_held, channel_scores(targets, base_sim),
                     where, tests_before, tests_after, targets, base_sim, base.name, timings, notes)


def _failed_names(tests: Sequence[ResidualTests]) -> list[str]:
    names: list[str] = []
    for t in tests:
        for x in t.failed:
            if x.title not in names:
                names.append(x.title)
    return names


def _verdict(winner: CandidateResult | None, ranking: Sequence[CandidateResult], base_held: float,
             where: Sequence[str], tests_before: Sequence[ResidualTests],
             tests_after: Sequence[ResidualTests]) -> tuple[str, str]:
    failed_before = _failed_names(tests_before)
    if winner is None:
        best = next((c for c in ranking if c.stable), None)
        if base_held <= AT_NOISE_FLOOR:
            msg = (f"Nothing missing: the nominal model already explains the held-out data to the noise floor "
                   f"({base_held:.3g} σ RMS), and no candidate reduces the held-out error by the required margin")
            if best is not None:
                msg += f" (best: {best.effect}, {100 * best.held_reduction:+.2g} % of the held-out residual energy)"
                if best.delta_bic_held > 10 and best.held_reduction > 0:
                    msg += (f". Note: {best.effect} is significant on the held-out data "
                            f"(ΔBIC {best.delta_bic_held:.3g}) but too small to matter here; a longer record or less "
                            "noise would tell")
            if failed_before:
                msg += f". Residual tests that still fail: {', '.join(failed_before)}"
            return "nothing_missing", msg + "."
        msg = (f"Not explained by the library: the nominal model misses the held-out data by {base_held:.3g} σ RMS, "
               "but no candidate effect removes enough of it on held-out data")
        if best is not None:
            msg += (f" (best: {best.effect}, {100 * best.held_reduction:.3g} % of the residual energy, "
                    f"ΔBIC {best.delta_bic_held:.3g})")
        msg += ". Where it fails: " + " | ".join(where)
        if failed_before:
            msg += f". Failed residual tests: {', '.join(failed_before)}"
        return "unexplained", msg + "."
    runner = next((c for c in ranking if c is not winner and c.accepted), None)
    partial = winner.held_rms_sigma > PARTIAL_ABOVE
    head = "Partly explained by" if partial else "Missing effect:"
    msg = (f"{head} {winner.effect} — {winner.description}. Adding it cuts the held-out residual from "
           f"{base_held:.3g} σ to {winner.held_rms_sigma:.3g} σ RMS ({100 * winner.held_reduction:.3g} % of the "
           f"residual energy; ΔBIC {winner.delta_bic_held:.4g} against the nominal model)")
    if runner is not None:
        msg += (f"; runner-up {runner.effect} ({100 * runner.held_reduction:.3g} %, ΔBIC "
                f"{runner.delta_bic_held:.4g})")
    msg += f". Fitted: {winner.estimates_text()}. Its signature: {winner.signature}"
    if failed_before:
        after = _failed_names(tests_after)
        cleared = [n for n in failed_before if n not in after]
        msg += f" Residual tests failed by the nominal model: {', '.join(failed_before)}"
        msg += f"; with {winner.effect}: " + (f"{', '.join(cleared)} now pass" if cleared else "none clears")
        if after:
            msg += f", still failing: {', '.join(after)}"
        msg += "."
    if partial:
        msg += (f" The fitted model is still {winner.held_rms_sigma:.3g} σ from the held-out data, so this is at best "
                "part of the story: try combining effects (shm fit --add A --add B) or an effect of your own. "
                "Where the nominal model fails: " + " | ".join(where))
        return "partial", msg
    return "missing", msg
