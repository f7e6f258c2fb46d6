"""What is missing from the model? Fit every candidate — library effects *and* core-parameter re-estimations —
score it on held-out data, rank, combine, explain.

Candidates (:mod:`workbench.fit._candidates`): the effects library (:data:`workbench.fit.LIBRARY`) and every
core parameter of Table 2 and small physical groups (:data:`workbench.fit.PARAMETER_CANDIDATES`). For each:

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
(:mod:`workbench.diagnose._forward_selection`).
The verdict (:mod:`workbench.diagnose._verdict`) compares what is left with the
noise floor (:func:`explained`), names a wrong parameter with its value and the ``shm fit`` command, says which
parameters these records cannot tell apart and which test would
(:mod:`workbench.diagnose._identifiability`), and points to
``shm discover`` when the candidates do not suffice.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from board_config import CORE_SCHEMA, ParameterSet, load_parameter_set
from plant import PhysicalEffect
from plant.effect import EffectError
from workbench.compare import ResidualTests, residual_tests
from workbench.diagnose._discovery import discovery_section, discovery_step
from workbench.diagnose._evidence import Judgement
from workbench.diagnose._progress import DiagnoseProgress, SilentProgress
from workbench.diagnose._rules import why_not_named
from workbench.diagnose._settings import FIT_TOP, DiagnoseSettings
from workbench.diagnose._stages import (
    Nominal,
    Selection,
    fitting_stage,
    naming_stage,
    nominal_stage,
    screening_stage,
    selection_stage,
)
from workbench.diagnose._time_change import time_change
from workbench.fit import (
    AT_NOISE_FLOOR,
    LIBRARY,
    PARAMETER_CANDIDATES,
    PREFER_PARAMETER_WITHIN,
    CandidateResult,
    ChannelScore,
    FitError,
    ParameterCandidate,
    SimBatch,
    Target,
    channel_scores,
    explained,
    fit_spec,
    noise_tolerance,
    parameter_candidate,
    resolve_candidates,
    screened_out,
)
from workbench.localise import localise, model_features
from workbench.records import FrfRecord, Record

__all__ = ["AT_NOISE_FLOOR", "FIT_TOP", "CandidateResult", "DiagnoseSettings", "Diagnosis", "diagnose", "explained",
           "fit_spec", "noise_tolerance"]

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
    #: the naming rule's numbers per member judged (:mod:`workbench.diagnose._rules`)
    evidence: list[Any] = field(default_factory=list)
    #: the discovery step run when the library and the parameters fall short (``shm diagnose`` fills it)
    discover: dict[str, Any] = field(default_factory=dict)
    judgement: Judgement | None = None
    #: the split-record refit of a presented cure (:mod:`workbench.diagnose._time_change`; None when not made)
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
             candidates: Sequence[str | type[PhysicalEffect]] | None = None,
             settings: DiagnoseSettings | None = None, **options: Any) -> Diagnosis:
    """Rank ``candidates`` (default: the library and every core-parameter re-estimation; names of effects, of
    core parameters or of parameter groups) by how much of the held-out residual each explains, combine, explain.

    ``settings`` (:class:`workbench.diagnose._settings.DiagnoseSettings`; default the command's) says how;
    keyword ``options`` named like its fields replace single settings (``workers=2``, ``emit_dir=...``).
    ``fit_top``: after screening, fit in full only the best this many of each kind (None: fit all).
    ``workers`` > 1 fits candidates concurrently in threads (each simulation single-threaded; the compiled
    integrator releases the GIL). ``emit_dir``: when the library and the parameters fall short, run the discovery
    step (:mod:`workbench.diagnose._discovery`) and write what it finds there as an effect file (None: no
    discovery). ``reporter`` hears each stage start (:data:`workbench.diagnose._progress.STAGES`).
    """
    s = (settings or DiagnoseSettings()).with_options(options)
    t_start = time.perf_counter()
    rep = s.reporter or SilentProgress()
    rep.stage("nominal model", None, f"{len(records)} record(s)")
    base = load_parameter_set(params)
    classes, pcands = split_candidates(candidates)
    present = {e.name for e in base.effects}
    skipped = [c.name for c in classes if c.name in present or c.__module__ + ":" + c.__qualname__ in present]
    classes = [c for c in classes if c.name not in skipped]
    if not classes and not pcands:
        raise FitError("no candidates left to try (every candidate effect is already in the parameter set)")
    timings: dict[str, float] = {}
    nom = nominal_stage(records, base, s, timings)
    t0 = time.perf_counter()
    scr = screening_stage(nom, classes, pcands, s, rep)
    timings["screening_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    results = fitting_stage(nom, scr, s, rep)
    timings["fits_s"] = time.perf_counter() - t0
    for c in results:
        timings[f"candidate_{c.effect}_s"] = c.wall_s
    ranking = sorted(results, key=rank_key) + [screened_out(x) for x in scr.screened]
    t0 = time.perf_counter()
    sel = selection_stage(choose_winner(ranking), ranking, nom, s, rep, timings, records)
    timings["forward_selection_s"] = time.perf_counter() - t0
    t1 = time.perf_counter()
    naming_stage(sel, results, nom, s)
    timings["naming_rule_s"] = time.perf_counter() - t1
    d = _assemble(nom, sel, ranking, skipped, rep, timings)
    _verdict_and_discovery(d, records, params, nom, sel, s, rep, timings)
    timings["total_s"] = time.perf_counter() - t_start
    return d


def _assemble(nom: Nominal, sel: Selection, ranking: list[CandidateResult], skipped: Sequence[str],
              rep: DiagnoseProgress, timings: dict[str, float]) -> Diagnosis:
    """Residual tests before and after, where the nominal model fails, the notes: the Diagnosis without verdict."""
    rep.stage("residual tests", None, "and where the nominal model fails")
    t1 = time.perf_counter()
    winner, targets, base_sim = sel.winner, nom.targets, nom.base_sim
    tests_before = run_residual_tests(targets, base_sim)
    tests_after = run_residual_tests(targets, winner.outcome.sim) if winner and winner.outcome else []
    where = where_it_fails(targets, base_sim)
    timings["residual_tests_and_localisation_s"] = time.perf_counter() - t1
    notes = [f"skipped {', '.join(skipped)}: already in the parameter set"] if skipped else []
    if any("estimated" in src for tg in targets for src in tg.sigma_source):
        notes.append("the noise level was estimated from the data (no noise_std in the record metadata): "
                     "errors quoted in σ are only as good as that estimate")
    judged = sel.judged
    if judged is not None:
        notes += [f"not named in the verdict: {e.name} — {why_not_named(e)}" for e in judged.evidence
                  if why_not_named(e)]
    notes += sel.notes
    if len(sel.paths) > 1:
        notes.append("the greedy forward selection fell short of the noise floor, so it was started again from "
                     "other candidates (and a re-estimation swapped for an effect); paths tried: "
                     + "; ".join(sel.paths))
    return Diagnosis("", "", winner, ranking, nom.base_train, nom.base_held, channel_scores(targets, base_sim),
                     where, tests_before, tests_after, targets, base_sim, nom.base.name, timings, notes, sel.steps,
                     term_shares=sel.term_shares, without_sigma=sel.without_sigma, selection_paths=sel.paths,
                     best_set=sel.best_set, evidence=judged.evidence if judged else [], judgement=judged)


def _verdict_and_discovery(d: Diagnosis, records: Sequence[Record | FrfRecord], params: ParameterSet | str,
                           nom: Nominal, sel: Selection, s: DiagnoseSettings, rep: DiagnoseProgress,
                           timings: dict[str, float]) -> None:
    """Write the verdict into ``d``; with an ``emit_dir``, check a cure for a change in time and run discovery."""
    from workbench.diagnose._verdict import verdict_for

    rep.stage("verdict")
    t1 = time.perf_counter()
    base = nom.base
    label = s.params_label or (params if isinstance(params, str) else base.name)
    verdict_for(d, base, label)
    timings["verdict_s"] = time.perf_counter() - t1
    if s.emit_dir is None:
        d.discover = discovery_section(None, ran=False, reason="not asked (no directory for an effect file)")
        return
    t1 = time.perf_counter()
    if d.verdict in CURE_VERDICTS and sel.winner is not None:  # a cure presented: constant over the record?
        d.time_change = time_change(sel.winner, base, nom.targets, nom.base_sim, nom.data, nom.rss0_held,
                                    min_reduction=s.min_reduction, threads=nom.threads, max_nfev=s.max_nfev,
                                    seed=s.seed)
    timings["time_change_s"] = time.perf_counter() - t1
    discovery_step(d, records, base, label, s.emit_dir, holdout=s.holdout, n_blocks=s.n_blocks,
                   max_rate_Hz=s.max_rate_Hz, on_progress=s.on_discover, early=sel.early_discovery)


def rank_key(c: CandidateResult) -> tuple:
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
