"""The rounds of ``shm discover``'s forward selection as named stages (:func:`search_round`): the sensitivity batch
(:func:`sensitivities`), the held-out linear screen (:func:`linear_screen`), the fast path that confirms a screen
already at the noise floor on the full model (:func:`fast_path`), the nonlinear probes and onsets
(:func:`probe_screen`), the refits (:func:`refit_term`, :func:`refit_best`), a time event checked against the
members of its parameter constant in time and for plausibility (:func:`plausible_best`) and keeping the best
(:func:`keep_best`), a kept term refitted as what it may be (:mod:`workbench.discover._kept_change`); then the
backward step (:mod:`workbench.discover._backward`) and the terms the records cannot tell apart
(:func:`~workbench.discover._twins.twins_of`). :func:`workbench.discover._pipeline.discover` prepares the search
(:class:`SearchSetup`), runs the rounds on a :class:`SearchProgress` and judges what they kept.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from board_config.parameter import freed
from plant import PlantModel
from workbench.discover._dictionary import Term
from workbench.discover._event_check import (
    damage_lead,
    invariant_siblings,
    is_timed,
    onset_issue,
    place_rows,
    refit_twins,
)
from workbench.discover._finite_change import WindowFit
from workbench.discover._gate_shape import shape_rows
from workbench.discover._gates import TIME_GATES
from workbench.discover._kept_change import refine_kept
from workbench.discover._onset import change_point, event_onset, onset_probe, onset_scan, with_onsets
from workbench.discover._onset_profile import onset_held_blind, place_onset
from workbench.discover._pair_screen import screen_matrices
from workbench.discover._results import DiscoverError, ScreenRow, excess_share_removed, noise_free_match
from workbench.discover._search import (
    SearchState,
    free_for,
    nonlinear_check,
    other_delay_order,
    refine,
    refit_list,
)
from workbench.discover._section_reading import section_rows
from workbench.discover._shaped_event import event_leads, judged_with_end, shaped_instead
from workbench.discover._twins import place_switch_family, switch_family, twin_tolerance, twins_of
from workbench.fit import FitOutcome, Objective, Target, explained, noise_tolerance, rms

#: a term is kept when its refit removes at least this share of the held-out energy left above the noise
MIN_SHARE = 0.25
#: integrator tolerance of the sensitivity batch (tighter than the fits: differences of near-equal runs)
SENS_RTOL = 1e-7
#: on the fast path, up to this many further rows that also reach the noise floor on the screen are refitted too
FAST_ALSO = 3


@dataclass(frozen=True)
class SearchSetup:
    """What every round searches with: the records cut into targets, the dictionary's terms and parameter names,
    the models holding the dictionary effect, each signal's scale (SI), each term's sensitivity step ``eps`` and
    the nominal model's residuals (σ) with the number of held-out samples."""

    targets: list[Target]
    models: list[PlantModel]
    terms: list[Term]
    names: list[tuple[str, str | None]]
    scales: dict[str, float]
    eps: np.ndarray
    n_held: int
    train_before: float
    held_before: float


@dataclass(frozen=True)
class SearchSettings:
    """How the rounds search (see :func:`workbench.discover._pipeline.discover`'s arguments)."""

    n_refit: int
    max_nfev: int
    threads: int | None
    expect_change: bool
    say: Callable[[str], None]


@dataclass
class SearchProgress:
    """What the rounds have kept so far: the current model (``state``), the kept parameters' standard errors, its
    residuals (σ), the refit that kept the last term, the first round's screen, the per-round log, each kept term's
    twins, the timings (s) and the simulations run."""

    state: SearchState
    current_train: float
    current_held: float
    n_sims: int
    timings: dict[str, float]
    stderr: dict[str, float] = field(default_factory=dict)
    outcome: FitOutcome | None = None
    screen_rows: list[ScreenRow] = field(default_factory=list)
    rounds: list[dict[str, Any]] = field(default_factory=list)
    twins: dict[int, list[dict[str, Any]]] = field(default_factory=dict)
    #: every refit of the current round (the time-gated term chosen first is checked against them)
    refits: list[BestRefit] = field(default_factory=list)
    #: the event judged with an end this round (:func:`~workbench.discover._shaped_event.judged_with_end`)
    ended: WindowFit | None = None
    #: every shape of that event refitted while it was judged (:mod:`workbench.discover._shaped_event`): the
    #: finite-change step does not refit them again
    shaped: list[WindowFit] = field(default_factory=list)
    #: the first round's sensitivity batch (the pair step screens its pairs, :mod:`workbench.discover._pair_refit`)
    first_batch: SensitivityBatch | None = None

    def adopt(self, outcome: FitOutcome) -> None:
        """Take ``outcome`` as the current refit: its standard errors, residuals (σ) and the outcome itself (the
        caller has already set the kept terms and their values)."""
        self.stderr.update({e.name: e.stderr for e in outcome.estimates})
        self.current_train, self.current_held = outcome.train_rms_sigma, outcome.held_rms_sigma
        self.outcome = outcome


@dataclass(frozen=True)
class SensitivityBatch:
    """The measured channels of the current model (member 0) and with each candidate term ``cand[j]`` switched on
    by its ``eps`` (member j + 1), per target; ``ok``: which members integrated."""

    cand: list[int]
    ys: list[np.ndarray]
    ok: np.ndarray


@dataclass(frozen=True)
class BestRefit:
    """The refit with the lowest held-out RMS (σ) so far, and its term's index in the dictionary."""

    held_rms_sigma: float
    index: int
    outcome: FitOutcome


def sensitivities(setup: SearchSetup, progress: SearchProgress, settings: SearchSettings) -> SensitivityBatch:
    """One batch: member 0 is the current model, member k + 1 switches candidate term k on with eps_k."""
    terms, names, eps, values = setup.terms, setup.names, setup.eps, progress.state.values
    cand = [k for k in range(len(terms)) if k not in progress.state.kept]
    names_free = [freed(names[k][0], terms[k].unit, -1e300, 1e300, False, "discover") for k in cand]
    obj = Objective(setup.targets, setup.models, names_free, base_values=values, rtol=SENS_RTOL,
                    threads=settings.threads)
    # unit box of a linear [-1e300, 1e300] range: u = 0.5 + v / 2e300 — set the values directly instead
    P_rows = []
    for i in range(len(setup.targets)):
        P = np.tile(obj._p0[i], (len(cand) + 1, 1))
        for j, k in enumerate(cand):
            P[j + 1, obj._cols[i][j]] += eps[k]
        P_rows.append(P)
    ys, ok = [], np.ones(len(cand) + 1, bool)
    for tg, m, P in zip(setup.targets, setup.models, P_rows):
        res = m.simulate(tg.inputs, t_out=tg.t, params=P, rtol=SENS_RTOL, threads=settings.threads,
                         max_steps=Objective.max_steps(tg))
        y = res.y[:, :, tg.out_idx(m)].transpose(0, 2, 1)
        ok &= (res.status == 0) & np.all(np.isfinite(y), axis=(1, 2))
        ys.append(y)
    progress.n_sims += (len(cand) + 1) * len(setup.targets)
    return SensitivityBatch(cand, ys, ok)


def linear_screen(setup: SearchSetup, batch: SensitivityBatch) -> list[ScreenRow]:
    """Each candidate's coefficient by least squares on the training blocks, ranked by the held-out residual left."""
    cand = batch.cand
    m = screen_matrices(setup.targets, batch.ys, setup.eps[cand])
    r_tr_v, r_he_v, Xtr, Xhe = m.r_train, m.r_held, m.x_train, m.x_held
    rows = []
    for j, k in enumerate(cand):
        if not batch.ok[j + 1]:
            continue
        x = Xtr[j]
        den = float(x @ x)
        if not den > 0 or not np.isfinite(den):
            continue
        a = float(x @ r_tr_v) / den
        rows.append(ScreenRow(setup.terms[k], a, rms(r_he_v - a * Xhe[j]), rms(r_tr_v - a * x)))
    rows.sort(key=lambda r: r.held_rms_sigma)
    return rows


def refit_term(setup: SearchSetup, progress: SearchProgress, settings: SearchSettings,
               row: ScreenRow) -> FitOutcome | None:
    """``row``'s term refitted on the full nonlinear model with the kept terms (None when the refit fails)."""
    terms, names, targets, models = setup.terms, setup.names, setup.targets, setup.models
    state, threads, max_nfev = progress.state, settings.threads, settings.max_nfev
    k = terms.index(row.term)
    start = dict(state.values)
    start[names[k][0]] = row.coef
    if row.placed and names[k][1] is not None and row.shape is not None:  # its instant known: start there
        start[str(names[k][1])] = row.shape
    elif row.term.form in TIME_GATES:  # an onset time: start the refit from a scan around its onset
        span = (0.0, setup.scales["t"])  # the record, or before it for the ramp begun before the record
        if row.term.before_record and row.term.shape_range is not None:
            span = row.term.shape_range
        scan, n_probes = onset_scan(row, names[k], targets, models, state.values, span, threads)
        start.update(scan)
        progress.n_sims += n_probes * len(targets)
    free = free_for(terms, names, [*state.kept, k], start, k)
    robj = Objective(targets, models, free, base_values=state.values, threads=threads)
    out = refine(robj, start, max_nfev)
    progress.n_sims += robj.n_sims
    if not out.ok:
        return None
    out, n_placed = onset_held_blind(setup, state, k, out, threads, max_nfev)  # an onset the training blocks
    progress.n_sims += n_placed  # cannot see, placed on the whole record
    # a coefficient at its range bound: widen once (the linearised start underestimated it)
    if any(e.at_bound and e.name.startswith("a_") for e in out.estimates):
        start2 = dict(start) | out.values
        free2 = free_for(terms, names, [*state.kept, k], start2, k)
        robj2 = Objective(targets, models, free2, base_values=state.values, threads=threads)
        out2 = refine(robj2, start2, max_nfev)
        progress.n_sims += robj2.n_sims
        if out2.ok and out2.train_rms_sigma < out.train_rms_sigma:
            out = out2
    return out


def _tried(row: ScreenRow, out: FitOutcome) -> dict[str, Any]:
    return {"term": row.term.key, "held_rms_sigma": out.held_rms_sigma, "train_rms_sigma": out.train_rms_sigma}


def fast_path(setup: SearchSetup, progress: SearchProgress, settings: SearchSettings, rows: list[ScreenRow],
              tried: list[dict[str, Any]]) -> BestRefit | None:
    """The linearised screen already reaches the noise floor with one term: confirm it on the full model before
    probing every term nonlinearly — the best row, for a delay the best row of its other Padé order (the linearised
    screen barely tells them apart; a strong delay needs the second order), and the next rows that also explain the
    records on the screen: a term acting through the (hysteretic) structure is linearised less exactly than one in
    the measurement, so its refit, not its screen value, says whether it is a twin. Refits are logged in ``tried``."""
    held_before, n_held = setup.held_before, setup.n_held
    also = [r for r in rows[1:1 + FAST_ALSO] if explained(r.held_rms_sigma, held_before, n_held)]
    todo: list[ScreenRow] = []
    for row in [rows[0], *other_delay_order(rows, rows[0]), *also]:
        if all(row is not r for r in todo):
            todo.append(row)
    best: BestRefit | None = None
    for row in todo:
        out = refit_term(setup, progress, settings, row)
        if out is not None and explained(out.held_rms_sigma, held_before, n_held):
            tried.append(_tried(row, out))
            progress.refits.append(BestRefit(out.held_rms_sigma, setup.terms.index(row.term), out))
            if best is None or out.held_rms_sigma < best.held_rms_sigma:
                best = BestRefit(out.held_rms_sigma, setup.terms.index(row.term), out)
    return best


def probe_screen(setup: SearchSetup, progress: SearchProgress, settings: SearchSettings, rows: list[ScreenRow],
                 batch: SensitivityBatch) -> tuple[list[ScreenRow], list[ScreenRow]]:
    """The screen re-ranked on the full model (probes of the hard forms), and the time-gated rows probed where the
    residual changes its level (a damage event)."""
    onset_rows = onset_screen(setup, progress, settings, rows, batch)
    return nonlinear_screen(setup, progress, settings, rows), onset_rows


def onset_screen(setup: SearchSetup, progress: SearchProgress, settings: SearchSettings, rows: list[ScreenRow],
                 batch: SensitivityBatch) -> list[ScreenRow]:
    """The time-gated rows probed on the full model where the current model's residual changes its level."""
    targets = setup.targets
    t_hat = max((change_point(tg.t, (tg.measured - y[0]) / tg.sigma[:, None]) for tg, y in zip(targets, batch.ys)),
                key=lambda cp: cp[1])[0]
    onset_rows, n_probes = onset_probe(rows, dict(zip(setup.terms, setup.names)), targets, setup.models,
                                       progress.state.values, t_hat, setup.scales["t"], settings.threads)
    progress.n_sims += n_probes * len(targets)
    return onset_rows


def nonlinear_screen(setup: SearchSetup, progress: SearchProgress, settings: SearchSettings,
                     rows: list[ScreenRow]) -> list[ScreenRow]:
    """The linear screen's rows re-ranked on the full model (:func:`nonlinear_check`)."""
    rows, n_probes = nonlinear_check(rows, setup.terms, setup.targets, setup.models, progress.state.values,
                                     setup.names, settings.threads)
    progress.n_sims += n_probes * len(setup.targets)
    return rows


def event_evident(setup: SearchSetup, batch: SensitivityBatch) -> bool:
    """Whether the current model matches a record to the noise until an instant inside it and misses it after
    (:func:`~workbench.discover._onset.event_onset`): a damage event, whose time-gated terms are refitted first."""
    return any(event_onset(tg.t, (tg.measured - y[0]) / tg.sigma[:, None]) is not None
               for tg, y in zip(setup.targets, batch.ys))


def event_first(setup: SearchSetup, progress: SearchProgress, settings: SearchSettings, rows: list[ScreenRow],
                batch: SensitivityBatch, tried: list[dict[str, Any]],
                by_screen: bool = False) -> tuple[list[ScreenRow], BestRefit | None]:
    """The round's probes and refits when an event is evident (:func:`event_evident`): the time-gated rows probed
    at the residual's onset and refitted first; only when none of them reaches the noise floor are the other rows
    probed on the full model and refitted (in the order :func:`with_onsets` gives them, the time-gated rows last,
    already refitted). The same term is kept as with every row probed first and the time-gated rows refitted last,
    unless a term constant in time reaches the noise floor too (then the refit list's first such term was kept,
    now the event); what it saves on a damage event is the nonlinear probes of every row and the refits of the
    constant terms (on a 15 s sweep with a k2 loss: 35 refits and ~330 probes of the record). When another
    refitted time-gated term comes within the twins' tolerance, or the twins are judged by the screen
    (``by_screen``: the fast path was tried first), the rows are probed on the full model all the same (the twins
    are named from them, in their order)."""
    timed = with_onsets([], onset_screen(setup, progress, settings, rows, batch), first=True)
    best = refit_best(setup, progress, settings, timed, tried)
    if best is not None and best.held_rms_sigma <= 1.0 + noise_tolerance(setup.n_held):
        # another refit within the twins' tolerance: its twins are named in the order of the rows probed on
        # the full model (:func:`twins_of`), so probe them as the full path would
        chosen = setup.terms[best.index].key
        limit = max(best.held_rms_sigma, 1.0) * twin_tolerance(setup.n_held)
        if by_screen or any(t["term"] != chosen and t["held_rms_sigma"] <= limit for t in tried):
            rows = nonlinear_screen(setup, progress, settings, rows)
        return rows, best
    rows = nonlinear_screen(setup, progress, settings, rows)
    rest = with_onsets(refit_list(rows, settings.n_refit), [], first=False)
    more = refit_best(setup, progress, settings, rest, tried)
    if more is not None and (best is None or more.held_rms_sigma < best.held_rms_sigma):
        best = more
    return rows, best


def refit_best(setup: SearchSetup, progress: SearchProgress, settings: SearchSettings, todo: list[ScreenRow],
               tried: list[dict[str, Any]]) -> BestRefit | None:
    """The best few refitted on the full nonlinear model, until one reaches the noise floor (logged in ``tried``)."""
    best: BestRefit | None = None
    for row in todo:
        k = setup.terms.index(row.term)
        out = refit_term(setup, progress, settings, row)
        if out is None:
            continue
        tried.append(_tried(row, out))
        progress.refits.append(BestRefit(out.held_rms_sigma, k, out))
        if best is None or out.held_rms_sigma < best.held_rms_sigma:
            best = BestRefit(out.held_rms_sigma, k, out)
        if out.held_rms_sigma <= 1.0 + noise_tolerance(setup.n_held):  # at the noise floor: nothing can do better
            break
    return best


def plausible_best(setup: SearchSetup, progress: SearchProgress, settings: SearchSettings, best: BestRefit | None,
                   rows: list[ScreenRow], tried: list[dict[str, Any]], evident: bool = False
                   ) -> tuple[BestRefit | None, BestRefit | None]:
    """A time-gated best refit leads only when it is plausible and better (:mod:`workbench.discover._event_check`):
    the members of its parameter constant in time are refitted too (logged in ``tried``) and the best one within
    the twins' tolerance is kept instead; an event short of the noise floor that does not look like one gives way
    to the round's best refit constant in time (or to nothing). In a round where an event is ``evident``, a best
    refit constant in time gives way to the round's event when a shape of its change fits clearly better
    (:func:`~workbench.discover._shaped_event.shaped_instead`). Returns the refit to keep and the event it
    displaced as a twin (else None)."""
    if best is not None and evident and not is_timed(setup.terms[best.index]):
        best = shaped_instead(setup, progress, settings, best) or best  # an event's shape may fit clearly better
        if is_timed(setup.terms[best.index]):
            return best, None
    if best is None or not is_timed(setup.terms[best.index]):
        return best, None
    term = setup.terms[best.index]
    done = {t["term"] for t in tried}
    for row in invariant_siblings(rows, term):
        if row.term.key not in done:
            refit_best(setup, progress, settings, [row], tried)
    constant = [b for b in progress.refits if not is_timed(setup.terms[b.index])]
    limit = max(best.held_rms_sigma, 1.0) * twin_tolerance(setup.n_held)
    close = [b for b in constant if (setup.terms[b.index].param, setup.terms[b.index].index)
             == (term.param, term.index) and b.held_rms_sigma <= limit]
    if close:
        alt = min(close, key=lambda b: b.held_rms_sigma)
        twin = best.held_rms_sigma <= max(alt.held_rms_sigma, 1.0) * twin_tolerance(setup.n_held)
        if twin and event_leads(setup, progress, settings, best, alt):
            settings.say(f"  {term.key} ({best.held_rms_sigma:.4g} σ) and {setup.terms[alt.index].key} "
                         f"({alt.held_rms_sigma:.4g} σ, constant in time) explain the records alike, neither near the "
                         "noise: the event leads (the model matches before its onset), the other named as its twin")
            return best, alt
        settings.say(f"  {term.key} ({best.held_rms_sigma:.4g} σ) and {setup.terms[alt.index].key} "
                     f"({alt.held_rms_sigma:.4g} σ, constant in time) "
                     + ("explain the records alike: the constant one is kept, the event named as what the records "
                        "cannot tell it from" if twin else "— the one constant in time explains more: it is kept"))
        return alt, (best if twin else None)
    if best.held_rms_sigma <= 1.0 + noise_tolerance(setup.n_held):
        return best, None
    place_onset(setup, progress, settings, best)  # its standard error from the whole record, not the training
    why = onset_issue(setup.targets, best.outcome, setup.names[best.index][1] or "")
    if why is not None:
        why = judged_with_end(setup, progress, settings, best, why)
    if why is None:
        return best, None
    fallback = min(constant, key=lambda b: b.held_rms_sigma, default=None)
    settings.say(f"  {term.key} ({best.held_rms_sigma:.4g} σ) is not named as an event: {why}"
                 + (f"; the best refit constant in time is kept instead: {setup.terms[fallback.index].key}"
                    if fallback is not None else ""))
    return fallback, None


def family_best(setup: SearchSetup, progress: SearchProgress, settings: SearchSettings, best: BestRefit,
                rows: list[ScreenRow], tried: list[dict[str, Any]]) -> BestRefit:
    """The best refit's switching family (:func:`~workbench.discover._twins.switch_family`), then an event's change
    at the same instant elsewhere (:func:`~workbench.discover._event_check.place_family`), refitted too (logged in
    ``tried``), and another parameter changing at that instant (its kind family): one of them replaces it only when it
    fits clearly better — beyond the twins' tolerance — or, within it, when only it moves its parameter the way
    damage does (:func:`~workbench.discover._event_check.damage_lead`); last, the same change with another gate
    shape (:func:`~workbench.discover._gate_shape.shape_rows`)."""
    for family in (lambda b: switch_family(setup.terms[b.index], rows, {t["term"] for t in tried}),
                   lambda b: place_switch_family(setup.terms[b.index], rows, {t["term"] for t in tried},
                                                 b.held_rms_sigma),
                   lambda b: place_rows(setup, progress, settings, b, {t["term"] for t in tried}),
                   lambda b: place_rows(setup, progress, settings, b, {t["term"] for t in tried}, kinds=True),
                   lambda b: section_rows(setup, progress, settings, b, {t["term"] for t in tried}),
                   lambda b: shape_rows(setup, progress, settings, b)):
        more = refit_best(setup, progress, settings, rows_, tried) if (rows_ := family(best)) else None
        if more is not None and more.held_rms_sigma * twin_tolerance(setup.n_held) < best.held_rms_sigma:
            best = more
    return damage_lead(setup, progress, settings, best)


def keep_best(setup: SearchSetup, progress: SearchProgress, settings: SearchSettings, best: BestRefit,
              rows: list[ScreenRow], tried: list[dict[str, Any]], linearised: bool,
              displaced: BestRefit | None = None) -> bool:
    """Keep the round's best refit when it removes at least :data:`MIN_SHARE` of the excess over the noise (its
    twins named; ``displaced``: the event it was kept instead of, named first); False when it does not and the
    search stops."""
    best = family_best(setup, progress, settings, best, rows, tried)
    place_onset(setup, progress, settings, best)
    h_new, k_new, out = best.held_rms_sigma, best.index, best.outcome
    term = setup.terms[k_new]
    twins = twins_of(term, h_new, rows, tried, setup.n_held, setup.scales, linearised=linearised)
    progress.twins[k_new] = refit_twins(setup, progress, twins, displaced, term)
    gain = excess_share_removed(progress.current_held, h_new, noise_tolerance(setup.n_held))
    settings.say(f"  best refit: {term.key}: held-out {progress.current_held:.4g} σ → {h_new:.4g} σ "
                 + (f"({100 * gain:.0f} % of the excess removed)" if gain is not None else
                    "(no excess over the noise)"))
    if gain is None or gain < MIN_SHARE or h_new >= progress.current_held:
        return False
    progress.state.kept.append(k_new)
    progress.state.values.update(out.values)
    progress.adopt(out)
    return True


def search_round(setup: SearchSetup, progress: SearchProgress, settings: SearchSettings, round_no: int) -> bool:
    """One round of forward selection: sensitivities, screen, probes, refits, keep the best; False when the search
    stops (explained, at the noise floor, nothing kept, or the current model fails to integrate)."""
    held_before, n_held, timings = setup.held_before, setup.n_held, progress.timings
    if explained(progress.current_held, held_before, n_held) and round_no > 0:
        return False
    if held_before <= 1.0 + noise_tolerance(n_held) or noise_free_match(setup.targets, held_before):
        return False  # at the noise floor (or a noise-free record matched numerically): among 200 terms one fits noise
    t0 = time.perf_counter()
    progress.refits, progress.ended, progress.shaped = [], None, []
    batch = sensitivities(setup, progress, settings)
    if not batch.ok[0]:
        if round_no == 0:
            raise DiscoverError("the current model fails to integrate on the records")
        # the model with the kept terms integrated in the refit but not at the sensitivities' tighter tolerance
        # (a stiff hard-form term): keep what was found, say why the search stopped
        settings.say(f"round {round_no + 1}: the model with the kept terms fails to integrate at rtol "
                     f"{SENS_RTOL:g}; the search stops with what it kept")
        progress.rounds.append({"stopped": f"the model with the kept terms fails to integrate at rtol {SENS_RTOL:g}"})
        return False
    rows = linear_screen(setup, batch)
    best: BestRefit | None = None
    tried: list[dict[str, Any]] = []
    fast = bool(rows) and explained(rows[0].held_rms_sigma, held_before, n_held) and not settings.expect_change
    if fast:
        t1 = time.perf_counter()
        best = fast_path(setup, progress, settings, rows, tried)
        timings["refit_s"] += time.perf_counter() - t1
    onset_rows: list[ScreenRow] = []
    how = "by the linearised screen, confirmed on the full model"
    event = best is None and not settings.expect_change and event_evident(setup, batch)
    if event:  # the probes and refits interleave (their time is counted as the screen's)
        rows, best = event_first(setup, progress, settings, rows, batch, tried, by_screen=fast)
        how = "an event inside the record: the time-gated terms probed at its onset and refitted first; best"
    elif best is None:
        rows, onset_rows = probe_screen(setup, progress, settings, rows, batch)
        how = "on the full model at the screened coefficients"
    timings["screen_s"] += time.perf_counter() - t0
    if round_no == 0:
        progress.screen_rows, progress.first_batch = rows[:12], batch
    settings.say(f"round {round_no + 1}: screened {len(rows)} terms in {time.perf_counter() - t0:.2g} s; best "
                 f"{how} (held-out): " + ", ".join(f"{r.term.key} {r.held_rms_sigma:.3g} σ" for r in rows[:4]))
    t0 = time.perf_counter()
    if best is None and not event:
        todo = with_onsets(refit_list(rows, settings.n_refit), onset_rows, first=settings.expect_change)
        best = refit_best(setup, progress, settings, todo, tried)
    best, displaced = plausible_best(setup, progress, settings, best, rows, tried, evident=event)
    timings["refit_s"] += time.perf_counter() - t0
    progress.rounds.append({"screened": [(r.term.key, r.held_rms_sigma) for r in rows[:settings.n_refit]],
                            "refitted": tried})
    if best is None:
        return False
    kept = keep_best(setup, progress, settings, best, rows, tried, linearised=fast, displaced=displaced)
    if kept:
        refine_kept(setup, progress, settings, MIN_SHARE)
    return kept
