"""What is missing from the model? Fit every candidate — library effects *and* core-parameter re-estimations —
score it on held-out data, rank, combine, explain.

Candidates (:mod:`workbench.candidates`): the effects library (:data:`workbench.effect_library.LIBRARY`) and every
core parameter of Table 2 and small physical groups (:data:`workbench.candidates.PARAMETER_CANDIDATES`). For each:

1. *screen* it cheaply (parameters: one batched Jacobian and a Gauss–Newton step with probes; effects: the
   effect's guess and a small Latin hypercube) and fit in full only the most promising (``fit_top`` of each kind);
2. fit its few parameters on the *training* part of the records (:func:`workbench.fit.optimise`: batched
   multi-start ``least_squares``); a fit that ends at its range bound is refitted with the range widened up to
   the parameter's own bounds — still at a bound that cannot move, it loses its claim ("at bound, unreliable");
3. score it on the *held-out* part: the reduction of the held-out residual energy against the nominal model,
   and a BIC-penalised held-out log-likelihood ratio

       ΔBIC_held = N_eff · ln(RSS₀/RSS) − k · ln(N_eff),   N_eff = N (1 − ρ₁)/(1 + ρ₁),

   with RSS in noise units, k the candidate's free parameters and ρ₁ the lag-1 autocorrelation of the
   candidate's held-out residual; training AIC/BIC are reported beside it;
4. reject it when its free run diverges or goes flat; accept it when it is stable, ΔBIC_held > 0 and it removes
   at least ``min_reduction`` (2 %) of the held-out residual energy.

The accepted candidates are ranked by ΔBIC_held. When a re-estimation explains the held-out data as well as the
best effect (:data:`PREFER_PARAMETER_WITHIN`), the re-estimation wins: no new physics is needed. When the winner
leaves more than :data:`FORWARD_ABOVE` σ, forward selection adds the candidate that best explains the rest, with a
small beam of other starting points and a swap step when the greedy set falls short
(:mod:`workbench.forward_selection`). The verdict (:mod:`workbench.diagnose_verdict`) compares what is left with the
noise floor (:func:`explained`), names a wrong parameter with its value and the ``shm fit`` command, says which
parameters these records cannot tell apart and which test would (:mod:`workbench.identifiability`), and points to
``shm discover`` when the candidates do not suffice.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from board_config import CORE_SCHEMA, ParameterSet, load_parameter_set
from plant import PhysicalEffect
from plant.effect import EffectError
from workbench.candidate_fit import (
    AT_NOISE_FLOOR,
    FORWARD_ABOVE,
    MIN_REDUCTION,
    PREFER_PARAMETER_WITHIN,
    CandidateResult,
    explained,
    fit_spec,
    noise_tolerance,
    screened_out,
    spec_guess,
    spec_models,
)
from workbench.candidates import (
    PARAMETER_CANDIDATES,
    CandidateSpec,
    ParameterCandidate,
    ScreenResult,
    base_values_of,
    parameter_candidate,
    screen_effects,
    screen_parameters,
)
from workbench.diagnose_discovery import discovery_section, discovery_step
from workbench.diagnose_evidence import Judgement, judge_winner
from workbench.diagnose_progress import DiagnoseProgress, SilentProgress
from workbench.diagnose_rules import why_not_named
from workbench.diagnose_time_change import time_change
from workbench.discover_onset import event_onset
from workbench.effect_library import LIBRARY, resolve_candidates
from workbench.fit import (
    DEFAULT_BLOCKS,
    DEFAULT_MAX_RATE_HZ,
    ChannelScore,
    FitError,
    Objective,
    SimBatch,
    Target,
    channel_scores,
    guess_data,
    model_factory,
    prepare_targets,
    rms,
)
from workbench.localisation import localise, model_features
from workbench.records import FrfRecord, Record
from workbench.residual_tests import ResidualTests, residual_tests

__all__ = ["AT_NOISE_FLOOR", "CandidateResult", "Diagnosis", "diagnose", "explained", "fit_spec",
           "noise_tolerance"]

#: candidates of each kind fitted in full after screening (None: all)
FIT_TOP = 3
#: verdicts that present a cure: checked for a change during the record before they are believed
CURE_VERDICTS = ("wrong_parameter", "missing", "combination")


@dataclass
class Diagnosis:
    """The ranked candidates and the verdict in words."""

    verdict: str  # "missing" | "wrong_parameter" | "combination" | "partial" | "nothing_missing" | "unexplained"
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
    steps: list[CandidateResult] = field(default_factory=list)  # forward selection: the sets tried in order
    identifiability: list[str] = field(default_factory=list)
    fit_command: str = ""
    next_command: str = ""
    #: a combination: member -> share of the held-out residual energy the set removes that is lost without it
    term_shares: dict[str, float] = field(default_factory=dict)
    #: a combination: member -> held-out RMS (σ) of the set refitted without it
    without_sigma: dict[str, float] = field(default_factory=dict)
    #: forward selection's paths tried (greedy first, then the beam's other starts and the swap), in words
    selection_paths: list[str] = field(default_factory=list)
    #: the best set selection found, before the naming rule (``winner`` is what the verdict may name of it)
    best_set: CandidateResult | None = None
    #: the naming rule's numbers per member judged (:mod:`workbench.diagnose_rules`)
    evidence: list[Any] = field(default_factory=list)
    #: the discovery step run when the library and the parameters fall short (``shm diagnose`` fills it)
    discover: dict[str, Any] = field(default_factory=dict)
    judgement: Judgement | None = None
    #: the split-record refit of a presented cure (:mod:`workbench.diagnose_time_change`; None when not made)
    time_change: Any = None

    @property
    def ranked_names(self) -> list[str]:
        return [c.effect for c in self.ranking]

    @property
    def found(self) -> tuple[str, ...]:
        """Names (effects and parameter candidates) the diagnosis blames, in the order forward selection found
        them; empty when nothing is."""
        if not self.winner:
            return ()
        out: list[str] = []
        for step in [*self.steps, self.winner]:
            out += [m for m in step.members if m not in out and m in self.winner.members]
        return tuple(out)

    def to_dict(self) -> dict[str, Any]:
        return {
            "verdict": self.verdict, "message": self.message,
            "winner": self.winner.effect if self.winner else None,
            "winner_kind": self.winner.kind if self.winner else None,
            "found": list(self.found),
            "fit_command": self.fit_command, "next_command": self.next_command,
            "identifiability": self.identifiability,
            "ranking": [c.to_dict() for c in self.ranking],
            "forward_selection": [c.to_dict() for c in self.steps],
            "term_shares": self.term_shares, "held_rms_sigma_without": self.without_sigma,
            "selection_paths": self.selection_paths,
            "best_set": self.best_set.effect if self.best_set else None,
            "best_set_held_rms_sigma": self.best_set.held_rms_sigma if self.best_set else None,
            "members": [e.__dict__ | {"named": not why_not_named(e), "why_not_named": why_not_named(e)}
                        for e in self.evidence],
            "discover": self.discover,
            "time_change": self.time_change.to_dict() if self.time_change is not None else None,
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


def split_candidates(candidates: Sequence[str | type[PhysicalEffect]] | None
                     ) -> tuple[list[type[PhysicalEffect]], list[ParameterCandidate]]:
    """Effect classes and parameter candidates from names (default: the library and every parameter candidate)."""
    if candidates is None:
        specs: Sequence[str | type[PhysicalEffect]] = LIBRARY
        params = list(PARAMETER_CANDIDATES)
    else:
        specs, params = [], []
        for c in candidates:
            if isinstance(c, str) and (c in CORE_SCHEMA or c in {p.name for p in PARAMETER_CANDIDATES}):
                params.append(parameter_candidate(c))
            else:
                specs.append(c)
    try:
        classes = resolve_candidates(specs)
    except EffectError as exc:
        raise FitError(str(exc)) from None
    return classes, params


def diagnose(records: Sequence[Record | FrfRecord], params: ParameterSet | str = "table2",
             candidates: Sequence[str | type[PhysicalEffect]] | None = None, *, holdout: str = "blocks",
             n_blocks: int = DEFAULT_BLOCKS, max_rate_Hz: float = DEFAULT_MAX_RATE_HZ,
             min_reduction: float = MIN_REDUCTION, workers: int = 1, max_nfev: int = 30, seed: int = 0,
             progress: Callable[[str, CandidateResult | None], None] | None = None,
             batched_jacobian: bool = True, fit_top: int | None = FIT_TOP, combine: bool = True,
             params_label: str | None = None, reporter: DiagnoseProgress | None = None,
             emit_dir: str | Path | None = None, on_discover: Callable[[str], None] | None = None) -> Diagnosis:
    """Rank ``candidates`` (default: the library and every core-parameter re-estimation; names of effects, of
    core parameters or of parameter groups) by how much of the held-out residual each explains, combine, explain.

    ``fit_top``: after screening, fit in full only the best this many of each kind (None: fit all).
    ``workers`` > 1 fits candidates concurrently in threads (each simulation single-threaded; the compiled
    integrator releases the GIL). ``batched_jacobian=False`` integrates the Jacobian's columns one at a time
    (the benchmark's baseline). ``progress(name, result)`` is called when a candidate starts (result None)
    and when it is done. ``params_label``: how the fit command names the parameter set (default its name).
    ``emit_dir``: when the library and the parameters fall short, run the discovery step
    (:mod:`workbench.diagnose_discovery`) and write what it finds there as an effect file (None: no discovery;
    ``on_discover(message)`` hears its progress).
    ``reporter`` hears each stage start (:data:`workbench.diagnose_progress.STAGES`) and each unit of work done.
    """
    from workbench.diagnose_verdict import verdict_for
    from workbench.forward_selection import select_set

    t_start = time.perf_counter()
    rep = reporter or SilentProgress()
    rep.stage("nominal model", None, f"{len(records)} record(s)")
    base = load_parameter_set(params)
    classes, pcands = split_candidates(candidates)
    present = {e.name for e in base.effects}
    skipped = [c.name for c in classes if c.name in present or c.__module__ + ":" + c.__qualname__ in present]
    classes = [c for c in classes if c.name not in skipped]
    if not classes and not pcands:
        raise FitError("no candidates left to try (every candidate effect is already in the parameter set)")
    targets = prepare_targets(records, model_factory(base, []), holdout=holdout, n_blocks=n_blocks,
                              max_rate_Hz=max_rate_Hz)
    base_values = base_values_of(base)
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
    base_train, base_held = rms(r0_train), rms(r0_held)

    # --- screening -------------------------------------------------------------------------------------------
    t0 = time.perf_counter()
    effect_specs = [CandidateSpec(effects=(c,)) for c in classes]
    param_specs = [CandidateSpec(params=(p,)) for p in pcands]
    screened: list[ScreenResult] = []
    starts: dict[str, dict[str, float]] = {}
    screen_rms: dict[str, float] = {}
    if fit_top is not None and len(effect_specs) > fit_top:
        rep.stage("screening effects", len(effect_specs))
        emodels = {s.label: spec_models(s, base, targets) for s in effect_specs}
        guesses = {}
        for s in effect_specs:
            free, _ = s.free_parameters(base_values)
            guesses[s.label] = spec_guess(s, data, free, base_values)
        scr = screen_effects(targets, emodels, effect_specs, guesses, base_values, seed=seed,
                             on_screened=rep.advance)
        scr.sort(key=lambda r: r.train_rms_sigma)
        effect_specs = [r.spec for r in scr[:fit_top]]
        screened += scr[fit_top:]
        starts.update({r.spec.label: r.start for r in scr[:fit_top]})
        screen_rms.update({r.spec.label: r.train_rms_sigma for r in scr})
    if param_specs:
        rep.stage("screening parameters", None, f"{len(param_specs)} candidates in one batch")
        scr = screen_parameters(targets, pcands, base_values, threads=None)
        scr.sort(key=lambda r: r.train_rms_sigma)
        top = len(scr) if fit_top is None else fit_top
        # a screen that does not beat the nominal model at all says "not this parameter"
        keep = (scr if fit_top is None else
                [r for r in scr[:top] if r.train_rms_sigma < r.nominal_train_rms_sigma * (1 - 1e-3)] or scr[:1])
        param_specs = [r.spec for r in keep]
        screened += [r for r in scr if r not in keep]
        starts.update({r.spec.label: r.start for r in keep})
        screen_rms.update({r.spec.label: r.train_rms_sigma for r in scr})
    timings["screening_s"] = time.perf_counter() - t0

    # --- full fits -------------------------------------------------------------------------------------------
    def one(spec: CandidateSpec) -> CandidateResult:
        if progress:
            progress(spec.label, None)
        start = starts.get(spec.label) if spec.params else None
        res = fit_spec(spec, base, targets, data, rss0_held, start=start, min_reduction=min_reduction,
                       threads=threads, max_nfev=max_nfev, seed=seed, batched_jacobian=batched_jacobian,
                       n_screen=2 if spec.params and start else None, rss0_train=float(np.dot(r0_train, r0_train)))
        res.screen_train_rms_sigma = screen_rms.get(spec.label, float("nan"))
        if progress:
            progress(spec.label, res)
        rep.advance(spec.label)
        return res

    todo = effect_specs + param_specs
    rep.stage("fitting candidates", len(todo))
    t0 = time.perf_counter()
    if workers > 1:
        for spec in todo:  # compile (or load) every composition first, serially: the kernels cache is shared
            spec_models(spec, base, targets)
        with ThreadPoolExecutor(workers) as pool:
            results = list(pool.map(one, todo))
    else:
        results = [one(s) for s in todo]
    # library effects that can free more parameters (laser spot position): fit the fuller variant too when the
    # effect is a contender; the held-out score decides whether the evidence calls for it
    variants = []
    for r in results:
        if r.spec is not None and r.kind == "effect" and r.stable and r.accepted:
            cls = r.spec.effects[0]
            extra = cls.on_request_fit_names()
            if extra:
                v = CandidateSpec(effects=(cls,), extras=((cls.name, extra),))
                variants.append(one_variant(v, r, base, targets, data, rss0_held, min_reduction, threads, max_nfev,
                                            seed, batched_jacobian))
    results += variants
    timings["fits_s"] = time.perf_counter() - t0
    for c in results:
        timings[f"candidate_{c.effect}_s"] = c.wall_s
    ranking = sorted(results, key=_rank_key) + [screened_out(s) for s in screened]
    winner = choose_winner(ranking)
    steps: list[CandidateResult] = []
    drop_one_fits: list[CandidateResult] = []
    term_shares: dict[str, float] = {}
    without_sigma: dict[str, float] = {}
    paths: list[str] = []
    notes_early: list[str] = []
    t0 = time.perf_counter()
    # forward selection whenever the winner leaves more than FORWARD_ABOVE σ, even when that is a tiny share of a
    # large residual ("explained" for the verdict): on a sweep a second effect can hide in the last 2 σ
    if winner is not None and combine and winner.held_rms_sigma > FORWARD_ABOVE:
        rep.stage("combinations", None, f"forward selection from {winner.effect}")
        # an event inside the record, with the discovery step to follow: no constant library set is the answer,
        # so the greedy path alone (the beam and the swap were most of the step's time on a 15 s sweep)
        onset = (None if emit_dir is None else
                 next((t for tg, y in zip(targets, base_sim.y)
                       if (t := event_onset(tg.t, (tg.measured - y[0]) / tg.sigma[:, None])) is not None), None))
        sel = select_set(winner, [c for c in ranking if c is not winner], base, targets, data, rss0_held,
                         min_reduction=min_reduction, threads=threads, max_nfev=max_nfev, seed=seed,
                         base_held=base_held, beam=onset is None)
        if onset is not None:
            notes_early.append(f"forward selection took the greedy path only: the nominal model matches the records "
                               f"to the noise until t ≈ {onset:.4g} s (an event inside the record, for the "
                               "discovery step)")
        winner, steps = sel.final, sel.steps
        term_shares = sel.shares(rss0_held)
        without_sigma = {m: r.held_rms_sigma for m, r in sel.without.items() if m in winner.members}
        drop_one_fits = list(sel.without.values())
        for label, final, wall in sel.tried:
            paths.append(f"from {label}: {final.effect} ({final.held_rms_sigma:.3g} σ, ΔBIC "
                         f"{final.delta_bic_held:.4g}, {wall:.3g} s)")
            timings[f"forward_selection_from_{label}_s"] = wall
    timings["forward_selection_s"] = time.perf_counter() - t0
    best_set = winner
    judged: Judgement | None = None
    t1 = time.perf_counter()
    if winner is not None:  # what the verdict may name of the best set (workbench.diagnose_rules)
        judged = judge_winner(winner, base, targets, base_held, base_obj.residuals(base_sim, "all")[0],
                              [*results, *steps, *drop_one_fits], data, rss0_held, min_reduction=min_reduction,
                              threads=threads, max_nfev=max_nfev, seed=seed)
        winner = judged.named
        if winner is not best_set:
            steps = [s for s in steps if winner is not None and set(s.members) <= set(winner.members)]
            term_shares, without_sigma = judged.shares(rss0_held)
    timings["naming_rule_s"] = time.perf_counter() - t1
    rep.stage("residual tests", None, "and where the nominal model fails")
    t1 = time.perf_counter()
    tests_before = run_residual_tests(targets, base_sim)
    tests_after = run_residual_tests(targets, winner.outcome.sim) if winner and winner.outcome else []
    where = where_it_fails(targets, base_sim)
    timings["residual_tests_and_localisation_s"] = time.perf_counter() - t1
    notes = [f"skipped {', '.join(skipped)}: already in the parameter set"] if skipped else []
    if any("estimated" in s for tg in targets for s in tg.sigma_source):
        notes.append("the noise level was estimated from the data (no noise_std in the record metadata): "
                     "errors quoted in σ are only as good as that estimate")
    if judged is not None:
        notes += [f"not named in the verdict: {e.name} — {why_not_named(e)}" for e in judged.evidence
                  if why_not_named(e)]
    notes += notes_early
    if len(paths) > 1:
        notes.append("the greedy forward selection fell short of the noise floor, so it was started again from "
                     "other candidates (and a re-estimation swapped for an effect); paths tried: " + "; ".join(paths))
    d = Diagnosis("", "", winner, ranking, base_train, base_held, channel_scores(targets, base_sim), where,
                  tests_before, tests_after, targets, base_sim, base.name, timings, notes, steps,
                  term_shares=term_shares, without_sigma=without_sigma, selection_paths=paths,
                  best_set=best_set, evidence=judged.evidence if judged else [], judgement=judged)
    rep.stage("verdict")
    t1 = time.perf_counter()
    label = params_label or (params if isinstance(params, str) else base.name)
    verdict_for(d, base, label)
    timings["verdict_s"] = time.perf_counter() - t1
    if emit_dir is not None:
        t1 = time.perf_counter()
        if d.verdict in CURE_VERDICTS and winner is not None:  # a cure presented: constant over the record?
            d.time_change = time_change(winner, base, targets, base_sim, data, rss0_held,
                                        min_reduction=min_reduction, threads=threads, max_nfev=max_nfev, seed=seed)
        timings["time_change_s"] = time.perf_counter() - t1
        discovery_step(d, records, base, label, emit_dir, holdout=holdout, n_blocks=n_blocks,
                       max_rate_Hz=max_rate_Hz, on_progress=on_discover)
    else:
        d.discover = discovery_section(None, ran=False, reason="not asked (no directory for an effect file)")
    timings["total_s"] = time.perf_counter() - t_start
    return d


def one_variant(spec: CandidateSpec, plain: CandidateResult, base: ParameterSet, targets: Sequence[Target],
                data: Mapping[str, Any], rss0_held: float, min_reduction: float, threads: int | None,
                max_nfev: int, seed: int, batched_jacobian: bool) -> CandidateResult:
    start = dict(plain.outcome.values) if plain.outcome else None
    return fit_spec(spec, base, targets, data, rss0_held, start=start, min_reduction=min_reduction, threads=threads,
                    max_nfev=max_nfev, seed=seed, batched_jacobian=batched_jacobian)


def _rank_key(c: CandidateResult) -> tuple:
    return (not c.accepted, -c.delta_bic_held if c.stable and c.outcome else math.inf)


def choose_winner(ranking: Sequence[CandidateResult]) -> CandidateResult | None:
    """The best accepted candidate, except that a re-estimation explaining the held-out data as well as the best
    effect (its residual energy within :data:`PREFER_PARAMETER_WITHIN`) wins: no new physics needed."""
    acc = [c for c in ranking if c.accepted]
    if not acc:
        return None
    best = acc[0]
    par = next((c for c in acc if c.kind == "parameter"), None)  # best itself when it is a re-estimation
    if par is not None and par.held_rss <= PREFER_PARAMETER_WITHIN * best.held_rss:
        return par
    return best
