"""The numbers :mod:`workbench.diagnose._rules` judges, measured on the records, and the set a verdict may name.

For the best set forward selection found (or the best single candidate), every member gets a
:class:`~workbench.diagnose._rules.MemberEvidence`: identifiable (finite standard errors; a re-estimation pinned to
:data:`~workbench.diagnose._rules.MAX_REL_SE` and not mimicked by another core parameter,
:func:`workbench.diagnose._identifiability.confusions`; an effect at least two standard errors from absent), at a bound,
the RMS change of the prediction when it is undone in the fitted set (one simulation per member), and the cost of
its removal (the drop-one fit: the set refitted without it; the nominal model for a single member). When a member
fails, the members that pass are refitted together (:func:`judge`) and judged again, so the verdict names only
what the records show and quotes the held-out error of exactly what it names.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from board_config import ParameterSet
from plant import PhysicalEffect
from workbench.diagnose._rules import MAX_REL_SE, MemberEvidence, nameable
from workbench.fit import (
    CandidateResult,
    CandidateSpec,
    Objective,
    ParameterEstimate,
    Target,
    noise_tolerance,
    rms,
    spec_models,
)

#: rounds of "drop the members that fail, refit the rest, judge again" (a set of four can lose one a round)
MAX_ROUNDS = 4


@dataclass
class Judgement:
    """What a verdict may name: ``named`` (the set of the members that pass, fitted together; None when none
    does), the evidence of every member judged (the best set's first), and the confusions found on the way."""

    named: CandidateResult | None
    evidence: list[MemberEvidence]
    #: parameter -> (the other core parameter that mimics it, ρ, relative s.e. with both free)
    confused: dict[str, tuple[str, float, float]] = field(default_factory=dict)
    confusions: list[Any] = field(default_factory=list)
    closest: dict[str, tuple] = field(default_factory=dict)

    def shares(self, rss0_held: float) -> tuple[dict[str, float], dict[str, float]]:
        """(member -> share of what the named set removes that is lost without it, member -> held-out RMS (σ) of
        the set refitted without it), for a named set of two or more members."""
        c = self.named
        if c is None or c.outcome is None or len(c.members) < 2:
            return {}, {}
        n = c.outcome.n_held
        held = c.held_rms_sigma
        removed = rss0_held - c.held_rss
        ev = {e.name: e for e in self.evidence}
        without_sigma = {m: held + ev[m].drop_cost_sigma for m in c.members if m in ev}
        shares = {m: min(max((w * w - held * held) * n / removed, 0.0), 1.0) if removed > 0 else 0.0
                  for m, w in without_sigma.items() if math.isfinite(w)}
        return shares, without_sigma


def singular(cand: CandidateResult) -> bool:
    """Whether the fit of ``cand`` could not assign any parameter a finite standard error (its information matrix
    is singular as a whole: :func:`workbench.fit._optimiser` then marks every estimate "not identifiable")."""
    o = cand.outcome
    return o is not None and bool(o.estimates) and not any(math.isfinite(e.stderr) for e in o.estimates)


def neutral_values(cls: type[PhysicalEffect]) -> dict[str, float]:
    """The values that switch effect ``cls`` off (declared on its parameters: their ``neutral``)."""
    return cls.neutral_values()


def _member_names(spec: CandidateSpec, member: str) -> set[str]:
    """The names of the fitted estimates that belong to ``member`` of ``spec``."""
    for pc in spec.params:
        if pc.name == member:
            return {pc.scale_name} if pc.tied else set(pc.members)
    for cls in spec.effects:
        if cls.name == member:
            return {p.name for p in cls.own_parameters()} | set(spec.extra_for(cls))
    return set()


def member_estimates(cand: CandidateResult, member: str) -> list[ParameterEstimate]:
    assert cand.outcome is not None and cand.spec is not None
    names = _member_names(cand.spec, member)
    return [e for e in cand.outcome.estimates if e.name in names]


def core_values(cand: CandidateResult, base: ParameterSet) -> dict[str, float]:
    """Every model parameter the fitted set changes, by name (tied scale factors applied to their members)."""
    assert cand.outcome is not None and cand.spec is not None
    est = dict(cand.outcome.values)
    for pc in cand.spec.params:
        if pc.tied:
            s = est.pop(pc.scale_name, 1.0)
            for n in pc.members:
                est.setdefault(n, float(base.values[n]) * s)
    return est


def not_identifiable_because(cand: CandidateResult, member: str,
                             confused: Mapping[str, tuple[str, float, float]],
                             stderr: Mapping[str, float] | None = None) -> str:
    """'' when ``member`` of the fitted ``cand`` is identifiable on the records, else why not. ``stderr``: standard
    errors measured directly (:func:`direct_stderr`) for estimates the fit left without one."""
    assert cand.spec is not None
    est = [replace(e, stderr=stderr[e.name]) if stderr and e.name in stderr and not math.isfinite(e.stderr) else e
           for e in member_estimates(cand, member)]
    bad = [e.name for e in est if not math.isfinite(e.stderr)]
    if bad:
        return f"{', '.join(bad)}: no finite standard error"
    pcs = [pc for pc in cand.spec.params if pc.name == member]
    if pcs:
        for e in est:
            if e.value != 0 and abs(e.stderr / e.value) > MAX_REL_SE:
                return f"{e.name} known only to ±{100 * abs(e.stderr / e.value):.3g} %"
        for n in pcs[0].members:
            if n in confused:
                b, rho, se = confused[n]
                return f"{n} is mimicked by {b}, ρ = {rho:+.2f}; with both free ±{100 * se:.2g} %"
        return ""
    cls = next(c for c in cand.spec.effects if c.name == member)
    neutral = neutral_values(cls)
    strengths = [e for e in est if e.name in neutral]
    if strengths and not any(abs(e.value - neutral[e.name]) > 2.0 * e.stderr for e in strengths):
        return "within two standard errors of absent (" + ", ".join(e.describe() for e in strengths) + ")"
    return ""


#: relative step of the direct sensitivities of parameters the fit left without a standard error
DIRECT_STEP = 0.01


def direct_stderr(cand: CandidateResult, base: ParameterSet, targets: Sequence[Target],
                  names: Sequence[str]) -> dict[str, float]:
    """Standard errors of the estimates of the fitted ``cand``, measured on the records when its fit left some
    without one: the fit judges its information matrix in the parameters' own units, where a set of a stiffness
    (5·10⁴ m⁻²) and a conductance (5·10⁻⁵ S) looks singular although each is pinned. Here one simulation per
    parameter stepped by :data:`DIRECT_STEP` of its value gives the training residual's sensitivity to ln(value),
    the columns are normalised, and the joint covariance s² (JᵀJ)⁻¹ (s: the training RMS, at least 1 σ) gives each
    one's standard error with the others free; a direction the records do not see gets ∞. Only ``names`` are
    returned (every estimate of the set is stepped: the others are free too)."""
    assert cand.spec is not None and cand.outcome is not None
    models = spec_models(cand.spec, base, targets)
    values = core_values(cand, base)
    obj = Objective(targets, models, [], base_values=values)
    r0 = obj.residuals(obj.simulate(np.zeros((1, 0))), "train")[0]
    s = max(float(cand.outcome.train_rms_sigma), 1.0)
    est = [e.name for e in cand.outcome.estimates if e.name in values]
    cols, steps = [], []
    for n in est:
        v = values[n]
        h = DIRECT_STEP * abs(v) if v != 0 else DIRECT_STEP
        o = Objective(targets, models, [], base_values={**values, n: v + h})
        sim = o.simulate(np.zeros((1, 0)))
        cols.append((o.residuals(sim, "train")[0] - r0) / h if sim.ok.all() else np.zeros_like(r0))
        steps.append(h)
    if not cols:
        return {}
    J = np.array(cols).T  # (samples, k), per unit of each parameter
    norm = np.linalg.norm(J, axis=0)
    se = np.full(len(est), math.inf)
    seen = norm > 0
    if seen.any():
        Jn = J[:, seen] / norm[seen]
        info = Jn.T @ Jn
        if np.linalg.cond(info) < 1e12:
            se[seen] = s * np.sqrt(np.diag(np.linalg.inv(info))) / norm[seen]
    return {n: float(x) for n, x in zip(est, se) if n in names}


def prediction_changes(cand: CandidateResult, base: ParameterSet, targets: Sequence[Target],
                       base_residual_all: np.ndarray) -> dict[str, float]:
    """Member -> RMS (σ, all samples) of the change of the prediction when the member is undone in the fitted set
    (re-estimated parameters back to the parameter set's values, an effect to its neutral values; nothing refitted).
    A single member is compared with the nominal model (``base_residual_all``: its weighted residual)."""
    assert cand.spec is not None and cand.outcome is not None
    spec = cand.spec
    models = spec_models(spec, base, targets)
    values = core_values(cand, base)
    full = Objective(targets, models, [], base_values=values)
    r_set = full.residuals(full.simulate(np.zeros((1, 0))), "all")[0]
    if len(spec.members) == 1:
        return {spec.members[0]: rms(r_set - base_residual_all)}
    out: dict[str, float] = {}
    for member in spec.members:
        undone = dict(values)
        pc = next((p for p in spec.params if p.name == member), None)
        if pc is not None:
            for n in pc.members:
                undone[n] = float(base.values[n])
        else:
            cls = next(c for c in spec.effects if c.name == member)
            neutral = neutral_values(cls)
            if not neutral:
                out[member] = math.inf  # cannot be switched off in place: judged by its drop-one fit alone
                continue
            undone.update(neutral)
        obj = Objective(targets, models, [], base_values=undone)
        sim = obj.simulate(np.zeros((1, 0)))
        out[member] = rms(obj.residuals(sim, "all")[0] - r_set) if sim.ok.all() else math.inf
    return out


def without(spec: CandidateSpec, member: str) -> CandidateSpec:
    return CandidateSpec(tuple(e for e in spec.effects if e.name != member),
                         tuple(p for p in spec.params if p.name != member),
                         tuple((k, v) for k, v in spec.extras if k != member))


def evidence_of(cand: CandidateResult, base: ParameterSet, targets: Sequence[Target], base_held: float,
                base_residual_all: np.ndarray, drop_one: Callable[[CandidateSpec, CandidateResult], CandidateResult],
                confused: Mapping[str, tuple[str, float, float]]) -> list[MemberEvidence]:
    """The evidence of every member of the fitted ``cand``; ``drop_one(spec, start)`` returns the fit of ``spec``
    (the set without one member) started from ``start``."""
    assert cand.spec is not None and cand.outcome is not None
    changes = prediction_changes(cand, base, targets, base_residual_all)
    missing = [e.name for e in cand.outcome.estimates if not math.isfinite(e.stderr)]
    direct = direct_stderr(cand, base, targets, missing) if missing else {}
    if direct:  # the fit's own estimate failed numerically: report the measured one (verdict, --json, report)
        cand.outcome.estimates = [replace(e, stderr=direct[e.name], interval_low=math.nan, interval_high=math.nan)
                                  if e.name in direct else e for e in cand.outcome.estimates]
    tol = noise_tolerance(cand.n_eff_held)
    out = []
    for member in cand.spec.members:
        if len(cand.spec.members) == 1:
            held_without = base_held
        else:
            r = drop_one(without(cand.spec, member), cand)
            held_without = r.held_rms_sigma if r.outcome is not None and r.stable else math.inf
        why = not_identifiable_because(cand, member, confused, direct)
        kind = "parameter" if any(p.name == member for p in cand.spec.params) else "effect"
        out.append(MemberEvidence(member, kind, not why, any(e.at_bound for e in member_estimates(cand, member))
                                  or cand.status != "fitted", changes[member],
                                  held_without - cand.held_rms_sigma, tol, why))
    return out


def judge(best: CandidateResult, base: ParameterSet, targets: Sequence[Target], base_held: float,
          base_residual_all: np.ndarray, fit: Callable[[CandidateSpec, Mapping[str, float]], CandidateResult],
          known: Sequence[CandidateResult] = (),
          confusions_of: Callable[[Mapping[str, float], Sequence[str]], tuple[list, dict]] | None = None
          ) -> Judgement:
    """Judge the members of ``best`` (:mod:`workbench.diagnose._rules`); while some fail, refit those that pass
    together (``fit(spec, start)``; fits already made — ``known`` — are reused) and judge that set.
    ``confusions_of(fitted core values, names)`` is
    :func:`workbench.diagnose._identifiability.confusions` on the records."""
    cache: dict[frozenset[str], CandidateResult] = {}
    for c in known:
        if c.spec is not None and c.outcome is not None:
            cache.setdefault(frozenset(c.spec.members), c)

    def fitted(spec: CandidateSpec, start: CandidateResult) -> CandidateResult:
        key = frozenset(spec.members)
        if key not in cache:
            assert start.outcome is not None
            cache[key] = fit(spec, dict(start.outcome.values))
        return cache[key]

    j = Judgement(None, [])
    cand: CandidateResult | None = best
    for _ in range(MAX_ROUNDS):
        if cand is None or cand.spec is None or cand.outcome is None:
            break
        about = [n for pc in cand.spec.params for n in pc.members if n not in j.confused]
        if about and confusions_of is not None:
            conf, closest = confusions_of(core_values(cand, base), about)
            j.confusions += conf
            j.closest |= closest
            for c in conf:
                j.confused.setdefault(c.a, (c.b, c.rho, c.rel_se))
        ev = evidence_of(cand, base, targets, base_held, base_residual_all, fitted, j.confused)
        j.evidence = [*ev, *(e for e in j.evidence if e.name not in cand.spec.members)]
        keep = [e.name for e in ev if nameable(e)]
        if len(keep) == len(ev):
            j.named = cand
            break
        if not keep and len(ev) > 1 and singular(cand):
            # the set's covariance is singular (every standard error infinite): the set is not identifiable, its
            # members may be — drop the one whose removal costs least and judge the rest refitted
            cheapest = min(ev, key=lambda e: e.drop_cost_sigma)
            keep = [e.name for e in ev if e is not cheapest]
        if not keep:
            break
        sub = CandidateSpec(tuple(c for c in cand.spec.effects if c.name in keep),
                            tuple(p for p in cand.spec.params if p.name in keep),
                            tuple((k, v) for k, v in cand.spec.extras if k in keep))
        nxt = fitted(sub, cand)
        cand = nxt if nxt.accepted else None
    return j


def judge_winner(best: CandidateResult, base: ParameterSet, targets: Sequence[Target], base_held: float,
                 base_residual_all: np.ndarray, known: Sequence[CandidateResult], data: Mapping[str, Any],
                 rss0_held: float, **fit_kw: Any) -> Judgement:
    """:func:`judge` with diagnose's fits (:func:`workbench.fit.fit_spec` with ``fit_kw``) and
    :func:`workbench.diagnose._identifiability.confusions` on the records."""
    from workbench.diagnose._identifiability import confusions
    from workbench.fit import fit_spec

    def fit(spec: CandidateSpec, start: Mapping[str, float]) -> CandidateResult:
        own = {k: v for k, v in start.items()}
        return fit_spec(spec, base, targets, data, rss0_held, start=own, **fit_kw)

    def confusions_of(fitted: Mapping[str, float], about: Sequence[str]) -> tuple[list, dict]:
        try:
            return confusions(targets, base, fitted, about)
        except (ValueError, KeyError):  # a short or odd record: judged without it
            return [], {}

    return judge(best, base, targets, base_held, base_residual_all, fit, known, confusions_of)
