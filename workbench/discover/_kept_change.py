"""What the term a round just kept becomes when the model with it still leaves more than the noise (issue 26 point
3): a time-gated term given an end, two steps or a fitted time scale (:func:`~workbench.discover._staged_change.
change_refit`), a switch given a fitted edge (:func:`~workbench.discover._switch_edge.switch_edge_refit`). The
refit replaces the kept term when it removes a share of the excess left (not only past ``explained``'s 1 % of the
excess: a damping that grew ×3 over 2 s, kept as a step, left 2.31 σ and was 'found')."""

from __future__ import annotations

import time
from typing import Any

from workbench.discover._change_kinds import kind_split_change
from workbench.discover._change_pair import pair_change
from workbench.discover._change_place import place_change, placeable
from workbench.discover._change_split import split_change
from workbench.discover._event_check import is_timed
from workbench.discover._finite_change import WindowFit, keep_window
from workbench.discover._gates import SIGN_GATES, TIME_GATES
from workbench.discover._results import excess_share_removed
from workbench.discover._staged_change import change_refit
from workbench.discover._switch_edge import switch_edge_refit
from workbench.fit import noise_tolerance

#: how each kind of refit is said in the progress lines
HOW = {"stages": "as two steps (", "stages3": "as three steps (", "smooth": "with a fitted edge (",
       "settle": "settling (", "recover": "then settling (", "accelerate": "accelerating (",
       "window": "given an end (two ramps, ", "edge": "with a fitted edge ("}


def refine_kept(setup: Any, progress: Any, settings: Any, min_share: float) -> None:
    """The term just kept (the last of ``progress.state.kept``) refitted as what it may be when it leaves more than
    the noise; kept in its place when the refit removes ``min_share`` of the excess left — then, when the change
    still leaves more than the noise, tried in two places at once (:func:`~workbench.discover._change_split.
    split_change`). ``setup``, ``progress``, ``settings``: the rounds' objects."""
    placed = _refine(setup, progress, settings, min_share)
    t0 = time.perf_counter()
    k = progress.state.kept[-1]
    term = setup.terms[k]
    if not placed and placeable(term) and (not is_timed(term) or not _twin_elsewhere(progress.twins.get(k, []), term)):
        place_change(setup, progress, settings)  # a gate on a voltage: its place, refined or not, at the noise too;
        # a change in time whose round refitted no other place of its parameter (it was chosen as the kind of
        # another parameter's event: sections 1 and 2 losing 7 % at once on MBIT.a, said as section 1's loss with
        # the patches' authority as twins, section 2 never refitted)
    pair_change(setup, progress, settings, min_share)  # far from the noise: two steps in two places, two instants
    split_change(setup, progress, settings, min_share)
    kind_split_change(setup, progress, settings, min_share)  # far from the noise: another kind in two places
    progress.timings["refit_s"] += time.perf_counter() - t0


def _twin_elsewhere(twins: list[dict[str, Any]], term: Any) -> bool:
    """Whether ``twins`` hold ``term``'s parameter in another place (section, mass, patch)."""
    return any(t.get("param") == term.param and t.get("index", -1) not in (-1, term.index) for t in twins)


def _refine(setup: Any, progress: Any, settings: Any, min_share: float) -> bool:
    ended, progress.ended = progress.ended, None  # an event's shape, refitted already when it was judged
    shaped, progress.shaped = progress.shaped, []  # and every shape refitted then
    if progress.current_held <= 1.0 + noise_tolerance(setup.n_held):
        return False  # at the noise floor: nothing to refine (a patch's gate is still placed: its twins named)
    t0 = time.perf_counter()
    k = progress.state.kept[-1]
    term = setup.terms[k]
    fit: WindowFit | None = None
    if term.form in TIME_GATES:
        done: list[WindowFit] = []
        for f in [*([ended] if ended is not None else []), *shaped]:
            if f.replaced == k and all(f is not g for g in done):
                done.append(f)
        fit = change_refit(setup, progress, settings, k, done)
    elif term.form in SIGN_GATES:
        fit = switch_edge_refit(setup.targets, setup.models, setup.terms, setup.names, progress.state, k,
                                setup.scales.get(term.signal, 0.0), settings.threads, settings.max_nfev)
        progress.n_sims += 0 if fit is None else fit.n_sims
    progress.timings["refit_s"] += time.perf_counter() - t0
    if fit is None:
        return False
    h = fit.outcome.held_rms_sigma
    gain = excess_share_removed(progress.current_held, h, noise_tolerance(setup.n_held))
    keep = gain is not None and gain >= min_share and h < progress.current_held
    settings.say(f"  {term.key} {HOW[fit.kind]}{h:.4g} σ held-out): " + ("kept in its place" if keep else "not kept"))
    progress.rounds.append({"finite_change": {"term": term.key, "held_rms_sigma": h, "kept": keep}})
    if keep:
        keep_window(progress.state, progress.stderr, progress.twins, fit)
        progress.current_train, progress.current_held = fit.outcome.train_rms_sigma, h
        progress.outcome = fit.outcome
        place_change(setup, progress, settings)  # the refined change's place, when the records leave it open
    return keep
