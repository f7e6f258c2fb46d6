"""One candidate fitted and scored: an effect, a re-estimation or a combination (:class:`CandidateSpec`) is fitted
on the training part of the records (ranges widened when a fit ends at a bound), scored on the held-out part
(ΔBIC, reduction) and judged against the noise floor (:func:`explained`). Used by :mod:`workbench.diagnose` and
:mod:`workbench.diagnose._forward_selection`."""

from __future__ import annotations

import math
import threading
import time
from collections import OrderedDict
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from board_config import ParameterSet
from board_config.parameter import Parameter
from plant import PhysicalEffect, PlantModel
from plant.effect import EffectError
from workbench.fit._candidates import (
    CandidateSpec,
    ScreenResult,
    TiedObjective,
    base_values_of,
    neutral_end,
    widen,
)
from workbench.fit._effect_library import guess_values
from workbench.fit._fitting import (
    ChannelScore,
    FitError,
    FitOutcome,
    Target,
    channel_scores,
    check_effect_runs,
    model_factory,
    optimise,
)

MIN_REDUCTION = 0.02
AT_NOISE_FLOOR = 1.25
#: the winner's held-out RMS may exceed the noise floor (1 σ) by this much plus 3 standard deviations of the RMS of
#: white noise over its effective held-out samples (3/√(2 N_eff)) and still be "at the noise floor"
NOISE_TOLERANCE = 0.15
#: ... or leave at most this share of the nominal model's excess held-out energy (RMS² − 1), below this RMS (σ):
#: a true effect found exactly on a record whose remainder is not white (a chaotic-sensitive resonance) is not
#: "partial"
EXCESS_SHARE_EXPLAINED = 0.01
EXPLAINED_CEILING = 3.0
#: a re-estimation is preferred to an effect whose held-out residual energy is not lower by more than this factor
PREFER_PARAMETER_WITHIN = 1.10
#: forward selection starts when the winner leaves more than this (held-out RMS, σ) and is not at the noise floor
FORWARD_ABOVE = 1.5


def noise_tolerance(n_eff: float) -> float:
    """How far above 1 σ a held-out RMS may be and still be noise (see :data:`NOISE_TOLERANCE`)."""
    return NOISE_TOLERANCE + 3.0 / math.sqrt(2.0 * max(n_eff, 1.0))


def explained(held_sigma: float, base_held_sigma: float, n_eff: float) -> bool:
    """Whether a fitted model leaves only noise: within :func:`noise_tolerance` of the floor, or (below
    :data:`EXPLAINED_CEILING`) at most :data:`EXCESS_SHARE_EXPLAINED` of the nominal model's excess energy."""
    if not math.isfinite(held_sigma):
        return False
    if held_sigma <= 1.0 + noise_tolerance(n_eff):
        return True
    excess, base_excess = held_sigma ** 2 - 1.0, base_held_sigma ** 2 - 1.0
    return held_sigma <= EXPLAINED_CEILING and base_excess > 0 and excess <= EXCESS_SHARE_EXPLAINED * base_excess


@dataclass
class CandidateResult:
    """One candidate (an effect, a re-estimation or a combination), fitted and scored."""

    effect: str  # the candidate's label: effect name, parameter (group) name, or "a + b"
    description: str
    origin: str
    signature: str
    free: list[Parameter]
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
    spec: CandidateSpec | None = None
    status: str = "fitted"  # "fitted" | "screened out" | "at bound, unreliable"
    widened: list[str] = field(default_factory=list)
    screen_train_rms_sigma: float = float("nan")
    screen_start: dict[str, float] = field(default_factory=dict)  # best screening point (screened-out candidates)

    @property
    def kind(self) -> str:
        return self.spec.kind if self.spec else "effect"

    @property
    def members(self) -> tuple[str, ...]:
        return self.spec.members if self.spec else (self.effect,)

    @property
    def held_rms_sigma(self) -> float:
        return self.outcome.held_rms_sigma if self.outcome else float("nan")

    @property
    def train_rms_sigma(self) -> float:
        return self.outcome.train_rms_sigma if self.outcome else self.screen_train_rms_sigma

    @property
    def held_rss(self) -> float:
        return self.outcome.held_rss if self.outcome else float("inf")

    def estimates_text(self) -> str:
        if not self.outcome:
            return ""
        return "; ".join(e.describe() for e in self.outcome.estimates)

    def to_dict(self) -> dict[str, Any]:
        o = self.outcome
        return {
            "effect": self.effect, "kind": self.kind, "members": list(self.members),
            "description": self.description, "accepted": self.accepted, "status": self.status,
            "stable": self.stable, "rejection": self.rejection, "held_reduction": self.held_reduction,
            "delta_bic_held": self.delta_bic_held, "n_eff_held": self.n_eff_held, "aic_train": self.aic_train,
            "bic_train": self.bic_train, "train_rms_sigma": self.train_rms_sigma,
            "held_rms_sigma": self.held_rms_sigma, "screen_train_rms_sigma": self.screen_train_rms_sigma,
            "widened": self.widened,
            "free_parameters": [fp.describe() for fp in self.free],
            "estimates": [e.__dict__ for e in o.estimates] if o else [],
            "correlation": o.correlation.tolist() if o else [],
            "channels": [s.__dict__ | {"rms_sigma": s.rms_sigma} for s in self.channels],
            "signature": self.signature, "origin": self.origin, "wall_s": self.wall_s, "simulations": self.n_sims,
            "load_s": self.load_s, "integrator_s": self.sim_s,
            "optimiser": o.message if o else "",
        }


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


def score(cand: CandidateResult, rss_ref: float, min_reduction: float, k_ref: int = 0) -> None:
    """Held-out reduction and ΔBIC of ``cand`` against a reference with held-out RSS ``rss_ref`` and ``k_ref``
    free parameters (the nominal model: 0); training AIC/BIC; accepted or not."""
    o = cand.outcome
    assert o is not None
    k = len(cand.free) - k_ref
    rho = min(max(o.rho1_held, 0.0), 0.99)
    n_eff = max(o.n_held * (1 - rho) / (1 + rho), k + 2.0)
    cand.n_eff_held = n_eff
    if rss_ref > 0:
        cand.held_reduction = 1.0 - o.held_rss / rss_ref
        cand.delta_bic_held = n_eff * math.log(rss_ref / max(o.held_rss, 1e-300)) - max(k, 0) * math.log(n_eff)
    else:  # the reference leaves nothing on the held-out data: nothing to gain (was a math domain error)
        cand.held_reduction, cand.delta_bic_held = float("nan"), -math.inf
    n = max(o.n_train, 1)
    ll = n * math.log(max(o.train_rss, 1e-300) / n)
    cand.aic_train = ll + 2 * len(cand.free)
    cand.bic_train = ll + len(cand.free) * math.log(n)
    cand.accepted = (cand.stable and cand.status == "fitted" and cand.delta_bic_held > 0
                     and cand.held_reduction >= min_reduction)


_score = score


def _describe_spec(spec: CandidateSpec) -> tuple[str, str, str]:
    if spec.kind == "effect":
        cls = spec.effects[0]
        return cls.description, cls.origin, cls.signature
    if spec.kind == "parameter":
        pc = spec.params[0]
        return (f"re-estimate {pc.description} ({', '.join(pc.members)})", "the parameter set",
                "the same model with a different value")
    return ("combination: " + " + ".join(spec.members), "several causes at once", "")


#: the models of the last few compositions, by parameter set, effects and targets (each by identity): forward
#: selection meets the same composition in its re-screen, its quick tries, their full fits and the backward step,
#: and building one (its source and cache key) took ~0.1 s a time — 62 builds on a 15 s sweep. A model is read
#: only (parameters are passed to each simulation), so one object serves every fit of its composition.
_MODELS: OrderedDict[tuple, tuple[ParameterSet, tuple[Target, ...], list[PlantModel]]] = OrderedDict()
_MODELS_KEPT = 32
_MODELS_LOCK = threading.Lock()


def spec_models(spec: CandidateSpec, base: ParameterSet, targets: Sequence[Target]) -> list[PlantModel]:
    """The models of ``spec`` per target (the nominal ones when it adds no effect)."""
    if not spec.effects:
        return [tg.model for tg in targets]
    key = (id(base), spec.effects, tuple(id(tg) for tg in targets))
    with _MODELS_LOCK:
        kept = _MODELS.get(key)
        if kept is not None and kept[0] is base and all(a is b for a, b in zip(kept[1], targets)):
            _MODELS.move_to_end(key)
            return list(kept[2])
    build = model_factory(base, list(spec.effects))
    try:
        models = [build(tg.record) for tg in targets]
        for m in models:
            m.kernels()
    except EffectError as exc:
        raise FitError(str(exc)) from None
    with _MODELS_LOCK:
        _MODELS[key] = (base, tuple(targets), models)
        while len(_MODELS) > _MODELS_KEPT:
            _MODELS.popitem(last=False)
    return list(models)


def spec_guess(spec: CandidateSpec, data: Mapping[str, Any], free: Sequence[Parameter],
               base_values: Mapping[str, float]) -> dict[str, float]:
    guess: dict[str, float] = {}
    for cls in spec.effects:
        mine = [fp for fp in free if fp.owner == cls.name]
        try:
            guess.update(guess_values(cls, data, mine))
        except EffectError as exc:
            raise FitError(str(exc)) from None
    for fp in free:
        if fp.name not in guess:
            guess[fp.name] = 1.0 if fp.unit == "1" and fp.owner in {p.name for p in spec.params} else \
                float(base_values.get(fp.name, fp.from_unit(0.5)))
    return guess


def fit_spec(spec: CandidateSpec, base: ParameterSet, targets: Sequence[Target], data: Mapping[str, Any],
             rss0_held: float, *, start: Mapping[str, float] | None = None, min_reduction: float = MIN_REDUCTION,
             threads: int | None = None, max_nfev: int = 30, seed: int = 0, batched_jacobian: bool = True,
             n_screen: int | None = None, max_widen: int = 2, rss0_train: float | None = None,
             on_iteration: Callable[[Any], None] | None = None) -> CandidateResult:
    """Fit one candidate on the training part, widen a range its fit ends at, and score it on the held-out part."""
    t0 = time.perf_counter()
    base_values = base_values_of(base)
    description, origin, signature = _describe_spec(spec)
    models = spec_models(spec, base, targets)
    load_s = time.perf_counter() - t0
    for cls in spec.effects:
        check_effect_runs(models[0], cls, targets[0])
    ranges: dict[str, Parameter] = {}
    free, ties = spec.free_parameters(base_values, ranges)
    guess = spec_guess(spec, data, free, base_values)
    guess.update(start or {})
    owner_cls = {cls.name: cls for cls in spec.effects}
    widened: list[str] = []
    unreliable = ""
    sims = 0
    sim_s = 0.0
    for attempt in range(max_widen + 1):
        obj = TiedObjective(targets, models, free, ties, threads=threads)
        outcome = optimise(obj, guess, max_nfev=max_nfev, seed=seed, on_iteration=on_iteration,
                           batched_jacobian=batched_jacobian, n_screen=n_screen)
        sims += outcome.n_sims
        sim_s += obj.sim_wall_s
        hit = []
        for fp, e, u in zip(free, outcome.estimates, outcome.u):
            if not e.at_bound:
                continue
            lo_neutral, hi_neutral = neutral_end(fp, owner_cls.get(fp.owner))
            at_upper = u >= 0.5
            if (at_upper and hi_neutral) or (not at_upper and lo_neutral):
                continue  # at the effect's neutral value: "absent", not "beyond the range"
            hit.append((fp, at_upper, e.value))
        helps = rss0_train is None or outcome.train_rss < (1.0 - min_reduction) * rss0_train
        if not hit or not outcome.ok or not helps:
            unreliable = ""  # nothing at a bound, or a candidate that does not help anyway: no point widening
            break
        new = {}
        for fp, at_upper, value in hit:
            w = widen(fp, at_upper, owner_cls.get(fp.owner), value)
            if w is not None:
                new[fp.name] = w
        unreliable = ", ".join(f"{fp.name} at {value:.4g} {fp.unit}" for fp, _, value in hit)
        if not new or attempt == max_widen:
            break
        widened.extend(f"{n}: [{w.lower:g}, {w.upper:g}] {w.unit}" for n, w in new.items())
        ranges.update(new)
        free, ties = spec.free_parameters(base_values, ranges)
        guess = outcome.values
    cand = CandidateResult(spec.label, description, origin, signature, free, outcome, spec=spec, widened=widened)
    cand.rejection = _stability(outcome, targets)
    cand.stable = not cand.rejection
    if unreliable and cand.stable:
        cand.status = "at bound, unreliable"
        cand.rejection = f"at bound, unreliable: {unreliable} (the parameter's own bounds)"
    if outcome.ok:
        cand.channels = channel_scores(targets, outcome.sim)
    score(cand, rss0_held, min_reduction)
    cand.wall_s = time.perf_counter() - t0
    cand.n_sims = sims
    cand.load_s = load_s
    cand.sim_s = sim_s
    return cand


def fit_candidate(cls: type[PhysicalEffect], params: ParameterSet, targets: Sequence[Target], data: dict[str, Any],
                  rss0_held: float, **kw: Any) -> CandidateResult:
    """Fit one candidate effect on the training part and score it on the held-out part."""
    return fit_spec(CandidateSpec(effects=(cls,)), params, targets, data, rss0_held, **kw)


def screened_out(s: ScreenResult) -> CandidateResult:
    description, origin, signature = _describe_spec(s.spec)
    c = CandidateResult(s.spec.label, description, origin, signature, [], None, spec=s.spec, status="screened out",
                        screen_train_rms_sigma=s.train_rms_sigma, n_sims=s.n_sims, screen_start=dict(s.start))
    c.stable = math.isfinite(s.train_rms_sigma)
    c.rejection = f"screened out (training {s.train_rms_sigma:.3g} σ at its best screening point)"
    return c


