"""Two (or three) things wrong at once: forward selection over the candidates.

Starting from the best single candidate, each step *re-ranks the rest with the current set fitted*: every
parameter candidate and the strongest effects are screened again on top of the current set (its fitted values held;
:func:`workbench.fit.screen_parameters` / :func:`~workbench.fit.screen_effects`) — what the rest of
the residual needs may have looked useless against the nominal model. The best few of that screen (and the
strongest candidates fitted alone) are each fitted *together* with the current set (every parameter free, starting
from the current values and the screen's), scored on the held-out data against the *current* set (ΔBIC with the
added parameters as penalty), and the best is kept if it clears the margin: ΔBIC_held > 0, and it removes at least
:data:`EXCESS_SHARE_TO_ADD` of what the current set leaves above the noise floor and at least ``min_reduction`` of
its held-out residual energy. Selection stops when nothing clears the margin, when the set explains the held-out data
to the noise floor, or at :data:`MAX_MEMBERS` members; a backward step then drops members the others made redundant.

Greedy selection can be led astray by its first pick: on a resonant sweep a re-estimation (the stiffness group, k3,
m3) mimics much of an effect, is taken first, and what is left then looks like nothing the library holds.
:func:`select_set` therefore keeps a small beam: when the greedy set does not reach the noise floor, forward
selection is started again from each of the next :data:`ALTERNATIVE_STARTS` accepted single candidates (effects
first when the greedy start was a re-estimation), and a *swap step* tries replacing each re-estimation of the best
set by the effects that fit best in its place. The final sets are compared on held-out data by ΔBIC against the
nominal model (one ln N_eff per free parameter), so a re-estimation that merely mimics an effect loses to the true
effect when both are fitted with the rest; a set without new physics still wins when it leaves no more than
:data:`~workbench.fit.PREFER_PARAMETER_WITHIN` times the held-out residual energy of the best.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from functools import partial
from typing import Any

from board_config import ParameterSet
from workbench.diagnose._fit_cache import FitCache
from workbench.fit import (
    PREFER_PARAMETER_WITHIN,
    CandidateResult,
    CandidateSpec,
    FitError,
    ScreenResult,
    Target,
    base_values_of,
    noise_tolerance,
    parameter_candidate,
    score,
    screen_effects,
    screen_parameters,
    spec_guess,
    spec_models,
)

MAX_MEMBERS = 4
#: candidates fitted together with the current set at each step: the best of the re-screen, then the strongest
#: fitted alone
POOL_RESCREENED = 3
POOL_FITTED = 2
#: effects re-screened on top of a current set that holds an effect (each needs a new composition, compiled once
#: per machine, ~5 s cold); on top of re-estimations alone, every effect is re-screened (same compositions as
#: alone). As many as the library holds: a weak effect behind a strong one is screened out alone and ranks last by
#: its strength alone (dielectric leakage, 13 σ, behind 1 400 σ of geometric stiffening on a sweep), so a limit
#: by strength never re-screened it and d_ep + C_ep stood in for it
RESCREEN_EFFECTS = 8
EXCESS_SHARE_TO_ADD = 0.2
#: a member is dropped when the set without it leaves at most this factor more held-out residual energy
PRUNE_WITHIN = 1.02
#: further starting points of forward selection when the greedy set is not at the noise floor (the beam's width − 1)
ALTERNATIVE_STARTS = 2
#: effects tried in place of each re-estimation of the best set by the swap step
SWAP_EFFECTS = 3
#: a forward step's tries are first fitted with at most this many evaluations per start and this many screening
#: points (no widening of a range); only the best is fitted in full (each try's full fit, a few hundred simulations
#: of the record, was most of forward selection's time on a 15 s sweep)
TRY_NFEV = 8
TRY_SCREEN = 8
#: fits of one step that do not depend on each other (a forward step's quick tries, the backward step's drop-one
#: fits of one set) run this many at a time in threads — the compiled integrator releases the GIL, and a fit's own
#: single simulations use one core; results are the same as one after another
PARALLEL_FITS = 2


@dataclass
class Selection:
    """What :func:`select_set` chose: the final set, the sets accepted on its path (the first is its start), how
    much each member explains, and every path tried (label of the start → final set and seconds spent)."""

    final: CandidateResult
    steps: list[CandidateResult]
    #: member → the set refitted without it
    without: dict[str, CandidateResult] = field(default_factory=dict)
    tried: list[tuple[str, CandidateResult, float]] = field(default_factory=list)

    def shares(self, rss0_held: float) -> dict[str, float]:
        """Member → share of the held-out residual energy removed by the set that is lost without that member
        (0–1; the shares of independent terms add up to about 1, of terms that overlap to less)."""
        o = self.final.outcome
        if o is None or len(self.final.members) < 2:
            return {}
        removed = rss0_held - o.held_rss
        if removed <= 0:
            return {}
        return {m: min(max((r.held_rss - o.held_rss) / removed, 0.0), 1.0) for m, r in self.without.items()
                if m in self.final.members}


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
                   specs: Sequence[CandidateSpec] = (), without: dict[str, CandidateResult] | None = None,
                   fits: FitCache | None = None) -> tuple[CandidateResult, list[CandidateResult]]:
    """(the final set, the sets accepted in order — the first is ``winner``): greedy forward selection from
    ``winner`` and the backward step; see the module docstring.

    ``others``: the other candidates as diagnosed alone (the strongest are tried first among the effects);
    ``specs``: every single candidate that may join (default: those of ``others``); ``without`` collects the
    backward step's drop-one fits of the final set (see :func:`_prune`); ``fits``: the selection's fits of sets
    (:class:`FitCache`)."""
    fits = fits if fits is not None else FitCache()
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
            and not at_noise_floor(current):
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
        best = _best_try(current, tries_specs, base, targets, data, rss0_held, fits, min_reduction=min_reduction,
                         threads=threads, max_nfev=max_nfev, seed=seed)
        if best is None:
            break
        n_held = current.outcome.n_held
        gain = current.held_rss - best.held_rss
        excess = max(current.held_rss - n_held, 0.0)
        if not (best.accepted and gain >= EXCESS_SHARE_TO_ADD * excess):
            break
        score(best, rss0_held, min_reduction)  # from here on, judged against the nominal model like the others
        current = best
        steps.append(best)
    if len(current.members) > 1:
        pruned = _prune(current, base, targets, data, rss0_held, without, min_reduction=min_reduction,
                        threads=threads, max_nfev=max_nfev, seed=seed, fits=fits)
        if pruned is not current:
            current = pruned
            steps.append(current)
    return current, steps


def _best_try(current: CandidateResult, tries_specs: Sequence[tuple[CandidateSpec, dict[str, float]]],
              base: ParameterSet, targets: Sequence[Target], data: Mapping[str, Any], rss0_held: float,
              fits: FitCache, *, min_reduction: float, max_nfev: int, **kw: Any) -> CandidateResult | None:
    """The best of the tries (the current set plus each candidate, from the candidate's start and the set's values),
    scored against the current set: each fitted quickly first (:data:`TRY_NFEV` evaluations per start,
    :data:`TRY_SCREEN` screening points, no widening), ranked by ΔBIC_held, and only the best fitted in full from
    there — the full fit is what is judged and kept."""
    assert current.spec is not None and current.outcome is not None
    specs = [current.spec.plus(spec1) for spec1, _ in tries_specs]
    starts = [own | dict(current.outcome.values) for _, own in tries_specs]
    _load_models(specs, base, targets)
    quick_kw = dict(kw, min_reduction=min_reduction, max_nfev=min(max_nfev, TRY_NFEV), max_widen=0,
                    n_screen=TRY_SCREEN)
    tried = _in_parallel([partial(fits.fit, spec, base, targets, data, rss0_held, start=start, **quick_kw)
                          for spec, start in zip(specs, starts)])
    quick: list[tuple[CandidateResult, CandidateSpec, dict[str, float]]] = []
    for r, spec, start in zip(tried, specs, starts):
        score(r, current.held_rss, min_reduction, k_ref=len(current.free))
        quick.append((r, spec, start))
    if not quick:
        return None
    r, spec, start = max(quick, key=lambda q: q[0].delta_bic_held if q[0].stable else float("-inf"))
    if TRY_NFEV >= max_nfev:
        return r
    best = fits.fit(spec, base, targets, data, rss0_held, min_reduction=min_reduction, max_nfev=max_nfev,
                    start=start | (dict(r.outcome.values) if r.outcome is not None else {}), **kw)
    score(best, current.held_rss, min_reduction, k_ref=len(current.free))
    return best


def _in_parallel(jobs: Sequence[Callable[[], CandidateResult]]) -> list[CandidateResult]:
    """Run independent fits, :data:`PARALLEL_FITS` at a time (at most one per CPU); results in the jobs' order."""
    n = min(PARALLEL_FITS, os.cpu_count() or 1, len(jobs))
    if n <= 1:
        return [job() for job in jobs]
    with ThreadPoolExecutor(n) as pool:
        return list(pool.map(lambda job: job(), jobs))


def _load_models(specs: Sequence[CandidateSpec], base: ParameterSet, targets: Sequence[Target]) -> None:
    """Build (compile or load) the compositions of ``specs`` one after another before they are fitted in
    threads (a failure is left for the fit to report)."""
    for spec in specs:
        if targets and spec.effects:
            try:
                spec_models(spec, base, targets)
            except FitError:
                pass


def _without(spec: CandidateSpec, name: str) -> CandidateSpec:
    return CandidateSpec(tuple(e for e in spec.effects if e.name != name),
                         tuple(p for p in spec.params if p.name != name),
                         tuple((k, v) for k, v in spec.extras if k != name))


def _prune(current: CandidateResult, base: ParameterSet, targets: Sequence[Target], data: Mapping[str, Any],
           rss0_held: float, without: dict[str, CandidateResult] | None = None, fits: FitCache | None = None,
           **kw: Any) -> CandidateResult:
    """Backward step: drop a member the others made redundant (the set without it explains the held-out data
    within :data:`PRUNE_WITHIN`) — e.g. a parameter taken first that returns to its value once the effects are in.
    ``without`` collects, per member of the returned set, the set refitted without it (when that fit was made on the
    returned set)."""
    fits = fits if fits is not None else FitCache()
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
            r = fits.fit(spec, base, targets, data, rss0_held, start=start, **kw)
            if r.accepted and r.held_rss <= PRUNE_WITHIN * current.held_rss and (
                    best is None or r.held_rss < best.held_rss):
                best = r
        if best is not None:
            current = best
    drops: dict[str, tuple[CandidateResult, CandidateResult]] = {}  # member -> (the set it was dropped from, fit)
    names = list(current.members)
    for i, name in enumerate(names):
        if len(current.members) < 2:
            break
        assert current.spec is not None and current.outcome is not None  # an accepted fit keeps both
        spec = _without(current.spec, name)
        _ahead(current, names[i:], base, targets, data, rss0_held, fits, **kw)
        r = fits.fit(spec, base, targets, data, rss0_held, start=dict(current.outcome.values), **kw)
        drops[name] = (current, r)
        if r.accepted and r.held_rss <= PRUNE_WITHIN * current.held_rss:
            current = r
    if without is not None:
        without.update({n: r for n, (of, r) in drops.items() if of is current and n in current.members})
    return current


def _ahead(current: CandidateResult, names: Sequence[str], base: ParameterSet, targets: Sequence[Target],
           data: Mapping[str, Any], rss0_held: float, fits: FitCache, **kw: Any) -> None:
    """Fit the drop-one sets of ``current`` for the next :data:`PARALLEL_FITS` of ``names`` (members still in
    it) together, into ``fits``: the backward step then meets them there. Only as many as run at once, so a drop
    that changes the set wastes at most the others of its batch."""
    assert current.spec is not None and current.outcome is not None
    specs = [_without(current.spec, n) for n in names if n in current.members][:PARALLEL_FITS]
    todo = [sp for sp in specs if FitCache.key(sp, kw) not in fits.fits]
    if len(todo) < 2 or min(PARALLEL_FITS, os.cpu_count() or 1) < 2:
        return
    start = dict(current.outcome.values)
    _load_models(todo, base, targets)
    _in_parallel([partial(fits.fit, sp, base, targets, data, rss0_held, start=start, **kw) for sp in todo])


def at_noise_floor(c: CandidateResult) -> bool:
    """Whether a set leaves only white noise (:func:`~workbench.fit.noise_tolerance`): the stricter half of
    :func:`~workbench.fit.explained`. A set that leaves a small *share* of a large residual (2.7 σ of
    1000 σ on a sweep) is explained for the verdict, but the rest may still be a second effect worth a search."""
    return c.held_rms_sigma <= 1.0 + noise_tolerance(c.n_eff_held)


def _strength_order(cands: Sequence[CandidateResult]) -> list[CandidateResult]:
    """Fitted and accepted first (by ΔBIC_held), then the rest by their screening error."""
    return sorted((c for c in cands if c.spec is not None and c.stable and c.kind != "combination"),
                  key=lambda c: (not c.accepted, c.outcome is None,
                                 -c.delta_bic_held if c.outcome is not None else c.screen_train_rms_sigma))


def alternative_starts(winner: CandidateResult, others: Sequence[CandidateResult],
                       n: int = ALTERNATIVE_STARTS) -> list[CandidateResult]:
    """The next ``n`` accepted single candidates to start forward selection from, none touching the winner:
    effects first when the winner is a re-estimation (the mimic a sweep allows), else by ΔBIC_held."""
    assert winner.spec is not None
    used = _touches(winner.spec)
    pool = [c for c in others if c.accepted and c.status == "fitted" and c.outcome is not None
            and c.spec is not None and c.kind in ("effect", "parameter")]
    pool.sort(key=lambda c: (winner.kind == "parameter" and c.kind != "effect", -c.delta_bic_held))
    out: list[CandidateResult] = []
    for c in pool:
        assert c.spec is not None
        if _touches(c.spec) & used:
            continue
        out.append(c)
        used |= _touches(c.spec)
        if len(out) >= n:
            break
    return out


def better(a: CandidateResult, b: CandidateResult) -> CandidateResult:
    """The set to keep of ``a`` (the incumbent) and ``b``: a set without new physics that leaves no more than
    :data:`PREFER_PARAMETER_WITHIN` times the other's held-out residual energy wins; otherwise ``b`` must beat ``a``
    on ΔBIC_held against the nominal model (its extra parameters penalised) *and* leave less than
    1/:data:`PREFER_PARAMETER_WITHIN` of its held-out residual energy."""
    if b.outcome is None or not b.accepted:
        return a
    if a.outcome is None or not a.accepted:
        return b
    # (a plain incumbent within the margin needs no rule of its own: the last rule already keeps it)
    a_plain, b_plain = a.spec is not None and not a.spec.effects, b.spec is not None and not b.spec.effects
    if b_plain and not a_plain and b.held_rss <= PREFER_PARAMETER_WITHIN * a.held_rss:
        return b
    if b.delta_bic_held > a.delta_bic_held and b.held_rss * PREFER_PARAMETER_WITHIN < a.held_rss:
        return b
    return a


def select_set(winner: CandidateResult, others: Sequence[CandidateResult], base: ParameterSet,
               targets: Sequence[Target], data: Mapping[str, Any], rss0_held: float, *, min_reduction: float,
               threads: int | None, max_nfev: int, seed: int, base_held: float, beam: bool = True,
               beam_unless: Callable[[CandidateResult], bool] | None = None) -> Selection:
    """Forward selection with a small beam and a swap step (see the module docstring): the greedy path from
    ``winner``; when it does not reach the noise floor, the paths from :func:`alternative_starts`, then the swap
    of each re-estimation of the best set for the effects that fit best in its place. Stops as soon as a set
    explains the held-out data to the noise floor. ``beam=False``: the greedy path alone — the caller knows no
    constant library set can explain the records (a damage event inside the record, which discovery looks for);
    ``beam_unless(best set so far)``, asked once after the greedy path and the first other start (the one a mimicking
    re-estimation hides: an effect), True: no further paths and no swap (the physics beyond the library already
    explains the records)."""
    kw: dict[str, Any] = dict(min_reduction=min_reduction, threads=threads, max_nfev=max_nfev, seed=seed,
                              fits=FitCache())
    everyone = [winner, *others]
    tried: list[tuple[str, CandidateResult, float]] = []

    def path(start: CandidateResult, before: Sequence[CandidateResult] = ()) -> Selection:
        t0 = time.perf_counter()
        without: dict[str, CandidateResult] = {}
        rest = [c for c in everyone if c is not start]
        final, steps = forward_select(start, rest, base, targets, data, rss0_held, base_held=base_held,
                                      without=without, **kw)
        tried.append((start.effect, final, time.perf_counter() - t0))
        return Selection(final, [*before, *steps], without)

    best = path(winner)
    if beam and not at_noise_floor(best.final):
        starts = alternative_starts(winner, others)
        for start in starts[:1]:
            best = _keep_better(best, path(start))
        if beam_unless is not None and not at_noise_floor(best.final):  # asked once, after the first other path
            beam = not beam_unless(best.final)
        for start in starts[1:] if beam else ():
            if at_noise_floor(best.final):
                break
            best = _keep_better(best, path(start))
    if beam and not at_noise_floor(best.final):
        swapped = _swap(best, everyone, base, targets, data, rss0_held, **kw)
        if swapped is not None and better(best.final, swapped) is swapped:
            best = path(swapped, best.steps)
    if len(best.final.members) > 1 and set(best.without) != set(best.final.members):
        _fill_without(best, base, targets, data, rss0_held, **kw)
    best.tried = tried
    return best


def _keep_better(best: Selection, other: Selection) -> Selection:
    """``other`` when its final set is :func:`better` than ``best``'s, else ``best``."""
    return other if better(best.final, other.final) is other.final else best


def _swap(sel: Selection, everyone: Sequence[CandidateResult], base: ParameterSet, targets: Sequence[Target],
          data: Mapping[str, Any], rss0_held: float, fits: FitCache, *, max_nfev: int, **kw: Any
          ) -> CandidateResult | None:
    """Swap step: each re-estimation of the set replaced by each of the :data:`SWAP_EFFECTS` strongest effects
    (alone) that do not touch the rest, fitted together with the rest; the best such set (or None). Like a forward
    step's tries, the swaps are fitted quickly first, :data:`PARALLEL_FITS` at a time, and only the best of them
    (by :func:`better`) is fitted in full — the full fit is what is returned and judged."""
    cur = sel.final
    if cur.spec is None or cur.outcome is None or len(cur.members) < 2:
        return None
    effects = [c for c in _strength_order(everyone) if c.kind == "effect"]
    swaps: list[tuple[CandidateSpec, dict[str, float]]] = []
    for pc in cur.spec.params:
        rest = _without(cur.spec, pc.name)
        n = 0
        for c in effects:
            assert c.spec is not None
            if _touches(c.spec) & _touches(rest):
                continue
            n += 1
            if n > SWAP_EFFECTS:
                break
            own = dict(c.outcome.values) if c.outcome is not None else dict(c.screen_start)
            swaps.append((rest.plus(c.spec), own | {k: v for k, v in cur.outcome.values.items()
                                                    if k not in {*pc.members, pc.scale_name}}))
    _load_models([spec for spec, _ in swaps], base, targets)
    quick_kw = dict(kw, max_nfev=min(max_nfev, TRY_NFEV), max_widen=0, n_screen=TRY_SCREEN)
    tried = _in_parallel([partial(fits.fit, spec, base, targets, data, rss0_held, start=start, **quick_kw)
                          for spec, start in swaps])
    best: tuple[CandidateResult, CandidateSpec, dict[str, float]] | None = None
    for r, (spec, start) in zip(tried, swaps):
        if r.accepted and (best is None or better(best[0], r) is r):
            best = (r, spec, start)
    if best is None or TRY_NFEV >= max_nfev:
        return best[0] if best is not None else None
    r, spec, start = best
    full = fits.fit(spec, base, targets, data, rss0_held, max_nfev=max_nfev,
                    start=start | (dict(r.outcome.values) if r.outcome is not None else {}), **kw)
    return full if full.accepted else None


def _fill_without(sel: Selection, base: ParameterSet, targets: Sequence[Target], data: Mapping[str, Any],
                  rss0_held: float, fits: FitCache, **kw: Any) -> None:
    """The drop-one fits of the final set that the backward step did not leave (how much each member explains)."""
    cur = sel.final
    assert cur.spec is not None and cur.outcome is not None
    for name in cur.members:
        if name not in sel.without:
            sel.without[name] = fits.fit(_without(cur.spec, name), base, targets, data, rss0_held,
                                         start=dict(cur.outcome.values), **kw)
