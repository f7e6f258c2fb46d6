"""The stages of :func:`workbench.diagnose.diagnose`: the nominal model, screening, full fits, forward selection
and the naming rule, each a function of what the stages before it produced."""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from board_config import ParameterSet
from plant import PhysicalEffect
from workbench.diagnose._discovery import DISCOVER_FIRST_ABOVE_SIGMA, damage_cure, discovery_first
from workbench.diagnose._evidence import Judgement, judge_winner
from workbench.diagnose._progress import DiagnoseProgress
from workbench.diagnose._settings import DiagnoseSettings
from workbench.discover import event_onset
from workbench.fit import (
    FORWARD_ABOVE,
    CandidateResult,
    CandidateSpec,
    FitError,
    Objective,
    ParameterCandidate,
    ScreenResult,
    SimBatch,
    Target,
    base_values_of,
    fit_spec,
    guess_data,
    model_factory,
    prepare_targets,
    rms,
    screen_effects,
    screen_parameters,
    spec_guess,
    spec_models,
)
from workbench.records import FrfRecord, Record


@dataclass
class Nominal:
    """The nominal model on the records: targets, its simulation and residuals (residuals in noise units)."""

    base: ParameterSet
    targets: list[Target]
    base_values: dict[str, float]
    base_obj: Objective
    base_sim: SimBatch
    r0_train: np.ndarray
    rss0_held: float
    data: Mapping[str, Any]
    threads: int | None
    base_train: float
    base_held: float


def nominal_stage(records: Sequence[Record | FrfRecord], base: ParameterSet, s: DiagnoseSettings,
                  timings: dict[str, float]) -> Nominal:
    """Prepare the targets and run the nominal model once (a failed integration is a :class:`FitError`)."""
    targets = prepare_targets(records, model_factory(base, []), holdout=s.holdout, n_blocks=s.n_blocks,
                              max_rate_Hz=s.max_rate_Hz)
    base_obj = Objective(targets, [tg.model for tg in targets], [])
    t0 = time.perf_counter()
    base_sim = base_obj.simulate(np.zeros((1, 0)), keep_full=True)
    if not base_sim.ok.all():
        raise FitError("the nominal model fails to integrate on the records")
    r0_train = base_obj.residuals(base_sim, "train")[0]
    r0_held = base_obj.residuals(base_sim, "held")[0]
    timings["baseline_s"] = time.perf_counter() - t0
    return Nominal(base, list(targets), base_values_of(base), base_obj, base_sim, r0_train,
                   float(np.dot(r0_held, r0_held)), guess_data(targets[0], base_sim, targets[0].model),
                   1 if s.workers > 1 else None, rms(r0_train), rms(r0_held))


@dataclass
class Screening:
    """What screening keeps for the full fits, and what it leaves out."""

    todo: list[CandidateSpec]
    screened: list[ScreenResult] = field(default_factory=list)
    starts: dict[str, dict[str, float]] = field(default_factory=dict)
    screen_rms: dict[str, float] = field(default_factory=dict)


def screening_stage(nom: Nominal, classes: Sequence[type[PhysicalEffect]], pcands: Sequence[ParameterCandidate],
                    s: DiagnoseSettings, rep: DiagnoseProgress) -> Screening:
    """Screen effects (guess + small hypercube) and parameters (one batched step); keep the best ``fit_top``."""
    effect_specs = [CandidateSpec(effects=(c,)) for c in classes]
    param_specs = [CandidateSpec(params=(p,)) for p in pcands]
    out = Screening([])
    fit_top = s.fit_top
    if fit_top is not None and len(effect_specs) > fit_top:
        rep.stage("screening effects", len(effect_specs))
        emodels = {sp.label: spec_models(sp, nom.base, nom.targets) for sp in effect_specs}
        guesses = {}
        for sp in effect_specs:
            free, _ = sp.free_parameters(nom.base_values)
            guesses[sp.label] = spec_guess(sp, nom.data, free, nom.base_values)
        scr = screen_effects(nom.targets, emodels, effect_specs, guesses, nom.base_values, seed=s.seed,
                             on_screened=rep.advance)
        scr.sort(key=lambda r: r.train_rms_sigma)
        effect_specs = [r.spec for r in scr[:fit_top]]
        out.screened += scr[fit_top:]
        out.starts.update({r.spec.label: r.start for r in scr[:fit_top]})
        out.screen_rms.update({r.spec.label: r.train_rms_sigma for r in scr})
    if param_specs:
        rep.stage("screening parameters", None, f"{len(param_specs)} candidates in one batch")
        scr = screen_parameters(nom.targets, list(pcands), nom.base_values, threads=None)
        scr.sort(key=lambda r: r.train_rms_sigma)
        top = len(scr) if fit_top is None else fit_top
        # a screen that does not beat the nominal model at all says "not this parameter"
        keep = (scr if fit_top is None else
                [r for r in scr[:top] if r.train_rms_sigma < r.nominal_train_rms_sigma * (1 - 1e-3)] or scr[:1])
        param_specs = [r.spec for r in keep]
        out.screened += [r for r in scr if r not in keep]
        out.starts.update({r.spec.label: r.start for r in keep})
        out.screen_rms.update({r.spec.label: r.train_rms_sigma for r in scr})
    out.todo = effect_specs + param_specs
    return out


def fitting_stage(nom: Nominal, scr: Screening, s: DiagnoseSettings, rep: DiagnoseProgress
                  ) -> list[CandidateResult]:
    """Fit every kept candidate in full (in threads when ``workers`` > 1), then the fuller variants of contenders."""
    rss0_train = float(np.dot(nom.r0_train, nom.r0_train))

    def one(spec: CandidateSpec) -> CandidateResult:
        if s.progress:
            s.progress(spec.label, None)
        start = scr.starts.get(spec.label) if spec.params else None
        res = fit_spec(spec, nom.base, nom.targets, nom.data, nom.rss0_held, start=start,
                       min_reduction=s.min_reduction, threads=nom.threads, max_nfev=s.max_nfev, seed=s.seed,
                       batched_jacobian=s.batched_jacobian, n_screen=2 if spec.params and start else None,
                       rss0_train=rss0_train)
        res.screen_train_rms_sigma = scr.screen_rms.get(spec.label, float("nan"))
        if s.progress:
            s.progress(spec.label, res)
        rep.advance(spec.label)
        return res

    rep.stage("fitting candidates", len(scr.todo))
    if s.workers > 1:
        for spec in scr.todo:  # compile (or load) every composition first, serially: the kernels cache is shared
            spec_models(spec, nom.base, nom.targets)
        with ThreadPoolExecutor(s.workers) as pool:
            results = list(pool.map(one, scr.todo))
    else:
        results = [one(sp) for sp in scr.todo]
    # library effects that can free more parameters (laser spot position): fit the fuller variant too when the
    # effect is a contender; the held-out score decides whether the evidence calls for it
    variants = []
    for r in results:
        if r.spec is not None and r.kind == "effect" and r.stable and r.accepted:
            cls = r.spec.effects[0]
            extra = cls.on_request_fit_names()
            if extra:
                v = CandidateSpec(effects=(cls,), extras=((cls.name, extra),))
                variants.append(one_variant(v, r, nom, s))
    return results + variants


def one_variant(spec: CandidateSpec, plain: CandidateResult, nom: Nominal, s: DiagnoseSettings) -> CandidateResult:
    """Fit the fuller variant ``spec`` of an accepted effect, started from the plain fit's values."""
    start = dict(plain.outcome.values) if plain.outcome else None
    return fit_spec(spec, nom.base, nom.targets, nom.data, nom.rss0_held, start=start,
                    min_reduction=s.min_reduction, threads=nom.threads, max_nfev=s.max_nfev, seed=s.seed,
                    batched_jacobian=s.batched_jacobian)


@dataclass
class Selection:
    """The best set after forward selection and the naming rule, with what the verdict reports of it."""

    winner: CandidateResult | None
    best_set: CandidateResult | None = None
    steps: list[CandidateResult] = field(default_factory=list)
    drop_one_fits: list[CandidateResult] = field(default_factory=list)
    term_shares: dict[str, float] = field(default_factory=dict)
    without_sigma: dict[str, float] = field(default_factory=dict)
    paths: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    judged: Judgement | None = None
    #: the discovery run during forward selection (:func:`workbench.diagnose._discovery.discovery_first`), or None
    early_discovery: Any = None


def selection_stage(winner: CandidateResult | None, ranking: Sequence[CandidateResult], nom: Nominal,
                    s: DiagnoseSettings, rep: DiagnoseProgress, timings: dict[str, float],
                    records: Sequence[Record | FrfRecord] = ()) -> Selection:
    """Forward selection whenever the winner leaves more than FORWARD_ABOVE σ, even when that is a tiny share of a
    large residual ("explained" for the verdict): on a sweep a second effect can hide in the last 2 σ. With a
    discovery step to follow (``s.emit_dir``), the greedy path alone when the records show an event inside them;
    the greedy path and the first other start only when they leave far more than the noise and the discovery, run
    then, finds a cure of damage forms (:func:`workbench.diagnose._discovery.damage_cure`)."""
    from workbench.diagnose._forward_selection import select_set

    sel = Selection(winner)
    if winner is None or not s.combine or winner.held_rms_sigma <= FORWARD_ABOVE:
        return sel
    rep.stage("combinations", None, f"forward selection from {winner.effect}")
    # an event inside the record, with the discovery step to follow: no constant library set is the answer,
    # so the greedy path alone (the beam and the swap were most of the step's time on a 15 s sweep)
    onset = (None if s.emit_dir is None else
             next((t for tg, y in zip(nom.targets, nom.base_sim.y)
                   if (t := event_onset(tg.t, (tg.measured - y[0]) / tg.sigma[:, None])) is not None), None))
    found = select_set(winner, [c for c in ranking if c is not winner], nom.base, nom.targets, nom.data,
                       nom.rss0_held, min_reduction=s.min_reduction, threads=nom.threads, max_nfev=s.max_nfev,
                       seed=s.seed, base_held=nom.base_held, beam=onset is None,
                       beam_unless=_discover_first(sel, records, nom, s) if records and s.emit_dir else None)
    early = sel.early_discovery
    if early is not None and damage_cure(early):
        sel.notes.append(f"forward selection stopped after its greedy path and first other start: the best set left "
                         f"{found.final.held_rms_sigma:.4g} σ held out, and the discovery step, run then, explains the "
                         f"records with damage forms ({early.held_after:.4g} σ)")
    elif early is not None:
        sel.notes.append("the discovery step ran after forward selection's greedy path and first other start (the "
                         f"best set left more than {DISCOVER_FIRST_ABOVE_SIGMA:g} σ held out); what it found is no "
                         f"cure of damage forms ({early.held_after:.4g} σ), so the beam went on")
    if onset is not None:
        sel.notes.append(f"forward selection took the greedy path only: the nominal model matches the records "
                         f"to the noise until t ≈ {onset:.4g} s (an event inside the record, for the "
                         "discovery step)")
    sel.winner, sel.steps = found.final, found.steps
    sel.term_shares = found.shares(nom.rss0_held)
    sel.without_sigma = {m: r.held_rms_sigma for m, r in found.without.items() if m in sel.winner.members}
    sel.drop_one_fits = list(found.without.values())
    for label, final, wall in found.tried:
        sel.paths.append(f"from {label}: {final.effect} ({final.held_rms_sigma:.3g} σ, ΔBIC "
                         f"{final.delta_bic_held:.4g}, {wall:.3g} s)")
        timings[f"forward_selection_from_{label}_s"] = wall
    return sel


def _discover_first(sel: Selection, records: Sequence[Record | FrfRecord], nom: Nominal,
                    s: DiagnoseSettings) -> Callable[[CandidateResult], bool]:
    """Forward selection's question after its greedy path and first other start: is the beam's further search moot?
    When the best set so far leaves more than :data:`~workbench.diagnose._discovery.DISCOVER_FIRST_ABOVE_SIGMA`,
    the discovery step runs now (kept in ``sel`` for the verdict) and the answer is whether it found a cure of damage
    forms."""

    def moot(best: CandidateResult) -> bool:
        if best.held_rms_sigma <= DISCOVER_FIRST_ABOVE_SIGMA:
            return False
        sel.early_discovery = discovery_first(records, nom.base, best.held_rms_sigma, holdout=s.holdout,
                                              n_blocks=s.n_blocks, max_rate_Hz=s.max_rate_Hz,
                                              on_progress=s.on_discover)
        return sel.early_discovery is not None and damage_cure(sel.early_discovery)

    return moot


def naming_stage(sel: Selection, results: Sequence[CandidateResult], nom: Nominal, s: DiagnoseSettings) -> None:
    """What the verdict may name of the best set (:mod:`workbench.diagnose._rules`); updates ``sel`` in place."""
    sel.best_set = sel.winner
    if sel.winner is None:
        return
    judged = judge_winner(sel.winner, nom.base, nom.targets, nom.base_held,
                          nom.base_obj.residuals(nom.base_sim, "all")[0],
                          [*results, *sel.steps, *sel.drop_one_fits], nom.data, nom.rss0_held,
                          min_reduction=s.min_reduction, threads=nom.threads, max_nfev=s.max_nfev, seed=s.seed)
    sel.judged = judged
    sel.winner = winner = judged.named
    if winner is not sel.best_set:
        sel.steps = [st for st in sel.steps if winner is not None and set(st.members) <= set(winner.members)]
        sel.term_shares, sel.without_sigma = judged.shares(nom.rss0_held)
