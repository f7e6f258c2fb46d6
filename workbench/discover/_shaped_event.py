"""An event refused for its onset, judged again with the shape of its change (issue 26 point 3).

A change over a finite time, refitted as a ramp that never ends or a step, fails the onset check
(:func:`~workbench.discover._event_check.onset_issue`) though it is an event: k3 lost 20 % over 1 s with a smooth
(cosine) start, on a 15 s sweep, kept as a ramp from 11.61 s — 50 σ held out (the best term constant in time:
138 σ) but 1.53 σ before its onset (the change's slow start) and ever softer after its end; the constant term was
kept and the verdict named free play in section 1. So the event is first given an end (a window: two ramps).

A change that starts slowly and speeds up is not a window either: section 2 losing 18 % as ((t − 6 s)/12 s)² on a
20 s MBIT.a was kept as a ramp from 10.26 s (5.6 σ; the best term constant in time 43.6 σ), given an end 2.95 σ
but "still 2.49 σ before its onset" (the loss before 10 s is the change's own slow start), and the constant term
was kept (43.6 σ). When the window does not make it plausible and the event leaves far less than any term constant
in time (:data:`SHAPE_MARGIN`), it is also refitted as two steps and with fitted time scales (an S-curve, a ramp
that settles, a step that partly recovers: :func:`~workbench.discover._staged_change.change_refit`'s shapes) and
the plausible shape that leaves the whole record lowest makes it an event. Such an event, its window too, is
judged as one whose change may have started before its fitted onset (:func:`shape_issue`): the model with it may
leave before that onset what it leaves over the whole record (a shape that does not fit everywhere misses its slow
start too), not more; its onset is not pinned to the record's edge nor loosely placed (a bound of the refit's
narrow onset range is no issue: the zoom placed it on the whole record). When no shape is plausible, the plain event
far better than any constant term is judged so too. Any other event is judged as before.

The other way round (:func:`shaped_instead`): in a round where an event is evident, a term constant in time may
beat the event's plain step — the root losing 25 % at 4.5 s of a 15 s sweep and 15 % of it back at 9.75 s: the step
of k1 refitted to 56.9 σ, a linear force on mass 1 (a softer root all along) to 50.5 σ, kept, and the search never
came back to the event (49.6 σ at the end). So when the best refit of the round is constant in time and the best
time-gated refit comes near it (:data:`EVENT_NEAR`), the event's shapes are tried too; a plausible shape that fits
clearly better (beyond the twins' tolerance) makes the event lead.

Pure logic on the fit engine's objects; the rounds (:mod:`workbench.discover._rounds`) call
:func:`judged_with_end` and :func:`shaped_instead` and keep the shape's refit in ``progress.ended`` for the
finite-change step.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any

from workbench.discover._event_check import (
    EDGE_SHARE,
    MIN_BEFORE_SAMPLES,
    ONSET_SE_SHARE,
    QUIET_BEFORE_SIGMA,
    before_onset_rms,
    is_timed,
    onset_issue,
    record_span,
)
from workbench.discover._finite_change import WindowFit, whole_rms, window_refit
from workbench.discover._onset_profile import place_onset
from workbench.discover._search import SearchState
from workbench.discover._smooth_change import VARIANTS, smooth_refit
from workbench.discover._staged_change import KIND_WORDS, staged_refit
from workbench.discover._twins import twin_tolerance
from workbench.fit import FitOutcome, Target

#: the other shapes than a window are tried only when the event leaves at most this share of the held-out RMS of
#: the round's best refit constant in time (a sweep's crack soaked up by a step comes near its constant member)
SHAPE_MARGIN = 0.5
#: a round's best time-gated refit within this factor of its best refit constant in time has its shapes tried
EVENT_NEAR = 1.5


def judged_with_end(setup: Any, progress: Any, settings: Any, event: Any, why: str) -> str | None:
    """Why the round's best refit ``event`` (a time-gated term; ``why``: what :func:`onset_issue` found) is no
    plausible event once its change is given a shape — None when, with one, it is one (see the module docstring).
    The plausible shape's refit (``setup``, ``progress``, ``settings``: the rounds' objects) is kept in
    ``progress.ended`` for the finite-change step."""
    trial = SearchState(dict(progress.state.values) | dict(event.outcome.values), [*progress.state.kept, event.index])
    key = setup.terms[event.index].key
    plausible: list[WindowFit] = []
    more = far_better(progress, setup, event)
    progress.shaped = []
    for shape in _shapes(setup, settings, trial, event.index, more):
        fit = shape()
        if fit is None:
            continue
        progress.n_sims += fit.n_sims
        progress.shaped.append(fit)
        gname = setup.names[fit.rise][1] or ""
        issue = (shape_issue(setup.targets, fit.outcome, fit.values, gname) if more
                 else onset_issue(setup.targets, fit.outcome, gname))
        held = fit.outcome.held_rms_sigma
        # judged as a change that may have started before its onset: only a shape that fits clearly better than
        # the plain event (a mass 'lost' at the record's start, kept as two steps 45.98 σ against 46.0 σ, is none)
        better = held * (twin_tolerance(setup.n_held) if more else 1.0) < event.held_rms_sigma
        if issue is None and better:
            plausible.append(fit)
            if fit.kind == "window":
                break
        else:
            settings.say(f"  {key} {_as(fit)} ({held:.4g} σ held-out): " + (issue or "no better"))
    if not plausible:
        gname = setup.names[event.index][1] or ""
        if more and shape_issue(setup.targets, event.outcome, event.outcome.values, gname) is None:
            settings.say(f"  {key} is an event whose change started before its fitted onset: {why}, no more than it "
                         "leaves over the whole record")
            return None
        return why
    fit = min(plausible, key=lambda f: whole_rms(setup.targets, f.outcome))
    settings.say(f"  {key} {_as(fit)} ({fit.outcome.held_rms_sigma:.4g} σ held-out) is an event: {why} — that was "
                 "the change's end or its gradual start")
    progress.ended = fit
    return None


def shape_issue(targets: Sequence[Target], outcome: FitOutcome, values: Mapping[str, float], gname: str
                ) -> str | None:
    """Why a shaped refit ``outcome`` (every value ``values``, its first onset's name ``gname``) is no plausible
    event, in words; None when it is one (see the module docstring)."""
    if gname not in values:
        return None  # no onset: nothing to judge
    t0 = float(values[gname])
    est = next((e for e in outcome.estimates if e.name == gname and not e.at_bound), None)
    start, end = record_span(targets)
    duration = max(end - start, 1e-9)
    if t0 - start < EDGE_SHARE * duration or end - t0 < EDGE_SHARE * duration:
        return f"its onset t = {t0:.4g} s is pinned to the record's edge"
    if est is not None and not (math.isfinite(est.stderr) and est.stderr <= ONSET_SE_SHARE * duration):
        return (f"its onset t = {t0:.4g} ± {est.stderr:.2g} s is not placed within {100 * ONSET_SE_SHARE:.0f} % of "
                "the record")
    quiet, n = before_onset_rms(targets, [y[0] for y in outcome.sim.y], t0)
    limit = max(QUIET_BEFORE_SIGMA, whole_rms(targets, outcome))
    if n < MIN_BEFORE_SAMPLES:
        return f"its onset t = {t0:.4g} s leaves too few samples before it to show the model matched there"
    if quiet > limit:
        return (f"the model with it leaves {quiet:.3g} σ before its onset t = {t0:.4g} s, more than the "
                f"{limit:.3g} σ it leaves over the whole record")
    return None


def shaped_instead(setup: Any, progress: Any, settings: Any, best: Any) -> Any | None:
    """The round's best time-gated refit (a ``BestRefit`` of ``progress.refits``) to lead instead of ``best`` (a
    refit constant in time) when one of its shapes fits clearly better and is plausible (:func:`shape_issue`); the
    shape's refit is kept in ``progress.ended``. None when no time-gated refit comes within :data:`EVENT_NEAR` of
    ``best`` or no shape does better (see the module docstring)."""
    timed = [b for b in progress.refits if is_timed(setup.terms[b.index])]
    event = min(timed, key=lambda b: b.held_rms_sigma, default=None)
    if event is None or event.held_rms_sigma > EVENT_NEAR * best.held_rms_sigma:
        return None
    trial = SearchState(dict(progress.state.values) | dict(event.outcome.values), [*progress.state.kept, event.index])
    fits = [f for shape in _shapes(setup, settings, trial, event.index, True) if (f := shape()) is not None]
    progress.n_sims += sum(f.n_sims for f in fits)
    progress.shaped = fits
    limit = best.held_rms_sigma / twin_tolerance(setup.n_held)
    good = [f for f in fits if f.outcome.held_rms_sigma < limit
            and shape_issue(setup.targets, f.outcome, f.values, setup.names[f.rise][1] or "") is None]
    key, other = setup.terms[event.index].key, setup.terms[best.index].key
    if not good:
        settings.say(f"  {key} ({event.held_rms_sigma:.4g} σ) near {other} ({best.held_rms_sigma:.4g} σ, constant "
                     "in time): no shape of its change fits clearly better")
        return None
    fit = min(good, key=lambda f: whole_rms(setup.targets, f.outcome))
    settings.say(f"  {key} ({event.held_rms_sigma:.4g} σ) {_as(fit)} ({fit.outcome.held_rms_sigma:.4g} σ) explains "
                 f"the records clearly better than {other} ({best.held_rms_sigma:.4g} σ, constant in time): the "
                 "event leads")
    progress.ended = fit
    return event


def far_better(progress: Any, setup: Any, event: Any) -> bool:
    """Whether ``event`` leaves at most :data:`SHAPE_MARGIN` of the held-out RMS of the best refit constant in time
    among ``progress.refits`` (True when there is none)."""
    constant = [b.held_rms_sigma for b in progress.refits if not is_timed(setup.terms[b.index])]
    return not constant or event.held_rms_sigma <= SHAPE_MARGIN * min(constant)


def _shapes(setup: Any, settings: Any, trial: SearchState, kept: int, more: bool
            ) -> list[Callable[[], WindowFit | None]]:
    """The refits to try, in order: the window, then (``more``) two steps and the fitted time scales."""
    args = (setup.targets, setup.models, setup.terms, setup.names, trial, kept)
    t_end, threads, nfev = setup.scales["t"], settings.threads, settings.max_nfev
    out: list[Callable[[], WindowFit | None]] = [lambda: window_refit(*args, t_end, threads, nfev)]
    if more:
        out.append(lambda: staged_refit(*args, [], t_end, threads, nfev))
        out += [lambda v=v: smooth_refit(*args, t_end, threads, nfev, v) for v in VARIANTS]  # type: ignore[misc]
    return out


def _as(fit: WindowFit) -> str:
    return "given an end" if fit.kind == "window" else f"as {KIND_WORDS[fit.kind]}"


#: an event that explains the records alike its twin constant in time leads when neither comes near the noise floor
#: (the constant one leaves more than this, σ held out) and the event looks like one (:func:`event_leads`)
EVENT_LEADS_ABOVE_SIGMA = 3.0


def event_leads(setup: Any, progress: Any, settings: Any, best: Any, alt: Any) -> bool:
    """Whether the round's event ``best`` (a time-gated ``BestRefit``) leads over ``alt``, the member of its
    parameter constant in time that explains the records alike: only when ``alt`` leaves more than
    :data:`EVENT_LEADS_ABOVE_SIGMA` and the event is plausible as one — its onset placed on the whole record, the model
    with it matching the records before it (:func:`~workbench.discover._event_check.onset_issue`). Near the noise
    the constant one keeps the lead (a crack on a sweep is no event). Far from it neither explains the records, and
    a plausible event is the one the later refits can build on (:mod:`workbench.discover._change_pair`): the root
    losing 6 % at 3.75 s and the tip 6 % at 9 s of a 15 s sweep — the tip's step at the first instant 46.7 σ, a
    crack in section 3 open on one side 44.3 σ — kept the crack, and no later round placed either loss (32.5 σ).
    ``setup``, ``progress``, ``settings``: the rounds' objects."""
    if alt.held_rms_sigma <= EVENT_LEADS_ABOVE_SIGMA:
        return False
    place_onset(setup, progress, settings, best)
    return onset_issue(setup.targets, best.outcome, setup.names[best.index][1] or "") is None
