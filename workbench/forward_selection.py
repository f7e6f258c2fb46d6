"""Two (or three) things wrong at once: forward selection over the candidates.

Starting from the best single candidate, each step *re-ranks the rest with the current set fitted*: every
parameter candidate and the strongest effects are screened again on top of the current set (its fitted values held;
:func:`workbench.candidates.screen_parameters` / :func:`~workbench.candidates.screen_effects`) — what the rest of
the residual needs may have looked useless against the nominal model. The best few of that screen (and the
strongest candidates fitted alone) are each fitted *together* with the current set (every parameter free, starting
from the current values and the screen's), scored on the held-out data against the *current* set (ΔBIC with the
added parameters as penalty), and the best is kept if it clears the margin: ΔBIC_held > 0, and it removes at least
:data:`EXCESS_SHARE_TO_ADD` of what the current set leaves above the noise floor and at least ``min_reduction`` of
its held-out residual energy. Selection stops when nothing clears the margin, when the set explains the held-out data
to the noise floor, or at :data:`MAX_MEMBERS` members; a backward step then drops members the others made redundant.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from board_config import ParameterSet
from workbench.candidate_fit import CandidateResult, explained, fit_spec, score, spec_guess, spec_models
from workbench.candidates import (
    CandidateSpec,
    ScreenResult,
    base_values_of,
    parameter_candidate,
    screen_effects,
    screen_parameters,
)
from workbench.fit import Target

MAX_MEMBERS = 4
#: candidates fitted together with the current set at each step: the best of the re-screen, then the strongest
#: fitted alone
POOL_RESCREENED = 3
POOL_FITTED = 2
#: effects re-screened on top of a current set that holds an effect (each needs a new compiled composition); on
#: top of re-estimations alone, every effect is re-screened (same compositions as alone)
RESCREEN_EFFECTS = 2
EXCESS_SHARE_TO_ADD = 0.2
#: a member is dropped when the set without it leaves at most this factor more held-out residual energy
PRUNE_WITHIN = 1.02


def _touches(spec: CandidateSpec) -> set[str]:
    """What a candidate changes: its effects, its independent parameters, its tied groups (a single parameter may
    join the group that holds it — the group then scales the others — and the backward step can drop the group)."""
    return ({e.name for e in spec.effects} | {n for p in spec.params if not p.tied for n in p.members}
            | {p.name for p in spec.params if p.tied})


def set_values(cand: CandidateResult, base: ParameterSet) -> dict[str, float]:
    """Every model parameter the fitted set ``cand`` changes, by name (tied scales applied to their members)."""
    assert cand.outcome is not None and cand.spec is not None
    est = dict(cand.outcome.values)
    out = {k: v for k, v in est.items()}
    for pc in cand.spec.params:
        if pc.tied:
            s = est.pop(pc.scale_name, 1.0)
            out.pop(pc.scale_name, None)
            for n in pc.members:
                out.setdefault(n, float(base.values[n]) * s)
    return out


def rescreen(current: CandidateResult, specs: Sequence[CandidateSpec], base: ParameterSet,
             targets: Sequence[Target], data: Mapping[str, Any], seed: int = 0) -> list[ScreenResult]:
    """Screen ``specs`` (single candidates) on top of the fitted ``current`` set; best first."""
    assert current.spec is not None
    mine = _touches(current.spec)
    specs = [s for s in specs if not (_touches(s) & mine)]
    values = set_values(current, base)
    base_values = base_values_of(base)
    out: list[ScreenResult] = []
    pcs = [s.params[0] for s in specs if s.kind == "parameter"]
    if pcs:
        out += screen_parameters(targets, pcs, base_values, refine_top=4,
                                 models=spec_models(current.spec, base, targets), overrides=values)
    effs = [s for s in specs if s.kind == "effect"]
    if current.spec.effects:  # new compositions (compiled once per machine): only the strongest few
        effs = effs[:RESCREEN_EFFECTS]
    if effs:
        models = {s.label: spec_models(current.spec.plus(s), base, targets) for s in effs}
        guesses = {}
        for s in effs:
            free, _ = s.free_parameters(base_values)
            guesses[s.label] = spec_guess(s, data, free, base_values)
        out += screen_effects(targets, models, effs, guesses, base_values, seed=seed, overrides=values)
    return sorted(out, key=lambda r: r.train_rms_sigma)


def forward_select(winner: CandidateResult, others: Sequence[CandidateResult], base: ParameterSet,
                   targets: Sequence[Target], data: Mapping[str, Any], rss0_held: float, *, min_reduction: float,
                   threads: int | None, max_nfev: int, seed: int, base_held: float,
                   specs: Sequence[CandidateSpec] = ()) -> tuple[CandidateResult, list[CandidateResult]]:
    """(the final set, the sets accepted in order — the first is ``winner``); see the module docstring.

    ``others``: the other candidates as diagnosed alone (the strongest are tried first among the effects);
    ``specs``: every single candidate that may join (default: those of ``others``)."""
    current = winner
    steps = [winner]
    ranked = sorted((c for c in others if c.spec is not None and c.stable and c.kind != "combination"),
                    key=lambda c: (c.outcome is None, -c.delta_bic_held if c.outcome is not None
                                   else c.screen_train_rms_sigma))
    singles = list(specs) or [c.spec for c in ranked if c.spec is not None]  # (ranked holds only those)
    # effects in the order of their strength alone (the re-screen is limited to the strongest few)
    order = {c.spec.label: i for i, c in enumerate(ranked) if c.spec is not None}
    singles.sort(key=lambda s: order.get(s.label, len(order)))
    fitted_alone = [c for c in ranked if c.outcome is not None and c.status == "fitted" and c.held_reduction > 0]
    while len(current.members) < MAX_MEMBERS and current.spec is not None and current.outcome is not None \
            and not explained(current.held_rms_sigma, base_held, current.n_eff_held):
        mine = _touches(current.spec)
        screened = rescreen(current, singles, base, targets, data, seed=seed)
        tries_specs: list[tuple[CandidateSpec, dict[str, float]]] = []
        for sr in screened[:POOL_RESCREENED]:
            tries_specs.append((sr.spec, dict(sr.start)))
        for c in fitted_alone:
            if len(tries_specs) >= POOL_RESCREENED + POOL_FITTED:
                break
            if c.spec is None or _touches(c.spec) & mine or any(c.spec == s for s, _ in tries_specs):
                continue
            tries_specs.append((c.spec, dict(c.outcome.values) if c.outcome is not None else {}))
        tries = []
        for spec1, own in tries_specs:
            spec = current.spec.plus(spec1)
            start = own | dict(current.outcome.values)
            r = fit_spec(spec, base, targets, data, rss0_held, start=start, min_reduction=min_reduction,
                         threads=threads, max_nfev=max_nfev, seed=seed)
            score(r, current.held_rss, min_reduction, k_ref=len(current.free))
            tries.append(r)
        if not tries:
            break
        best = max(tries, key=lambda r: r.delta_bic_held if r.stable else float("-inf"))
        n_held = current.outcome.n_held
        gain = current.held_rss - best.held_rss
        excess = max(current.held_rss - n_held, 0.0)
        if not (best.accepted and gain >= EXCESS_SHARE_TO_ADD * excess):
            break
        score(best, rss0_held, min_reduction)  # from here on, judged against the nominal model like the others
        current = best
        steps.append(best)
    if len(current.members) > 1:
        pruned = _prune(current, base, targets, data, rss0_held, min_reduction=min_reduction, threads=threads,
                        max_nfev=max_nfev, seed=seed)
        if pruned is not current:
            current = pruned
            steps.append(current)
    return current, steps


def _without(spec: CandidateSpec, name: str) -> CandidateSpec:
    return CandidateSpec(tuple(e for e in spec.effects if e.name != name),
                         tuple(p for p in spec.params if p.name != name),
                         tuple((k, v) for k, v in spec.extras if k != name))


def _prune(current: CandidateResult, base: ParameterSet, targets: Sequence[Target], data: Mapping[str, Any],
           rss0_held: float, **kw: Any) -> CandidateResult:
    """Backward step: drop a member the others made redundant (the set without it explains the held-out data
    within :data:`PRUNE_WITHIN`) — e.g. a parameter taken first that returns to its value once the effects are in."""
    assert current.spec is not None and current.outcome is not None
    # a tied group whose effect one of its members carries alone (the mass group standing in for m3): swap
    for pc in [p for p in current.spec.params if p.tied]:
        best = None
        for n in pc.members:
            single = parameter_candidate(n)
            params = (*(q for q in current.spec.params if q is not pc), single)
            spec = CandidateSpec(current.spec.effects, params, current.spec.extras)
            start = {k: v for k, v in current.outcome.values.items() if k != pc.scale_name}
            start[n] = float(base.values[n]) * current.outcome.values.get(pc.scale_name, 1.0)
            r = fit_spec(spec, base, targets, data, rss0_held, start=start, **kw)
            if r.accepted and r.held_rss <= PRUNE_WITHIN * current.held_rss and (
                    best is None or r.held_rss < best.held_rss):
                best = r
        if best is not None:
            current = best
    for name in current.members:
        if len(current.members) < 2:
            break
        assert current.spec is not None and current.outcome is not None  # an accepted fit keeps both
        spec = _without(current.spec, name)
        r = fit_spec(spec, base, targets, data, rss0_held, start=dict(current.outcome.values), **kw)
        if r.accepted and r.held_rss <= PRUNE_WITHIN * current.held_rss:
            current = r
    return current
