"""The backward step of ``shm discover``'s forward selection (:func:`backward_step`): after the rounds, a later
kept term alone may explain more than the set its first pick led to."""

from __future__ import annotations

import math
import time

from workbench.discover._rounds import SearchProgress, SearchSettings, SearchSetup
from workbench.discover._search import free_for, probe_batch, refine
from workbench.fit import Objective, explained, noise_tolerance


def backward_step(setup: SearchSetup, progress: SearchProgress, settings: SearchSettings) -> None:
    """A later term alone may explain more than the set its first pick led to (a strong stop at the tip was first
    taken for a clearance in section 3, and the stop found second carried the record alone): the set is replaced by
    the first kept term after the first that alone leaves less held-out error."""
    state, names, terms = progress.state, setup.names, setup.terms
    if not (len(state.kept) > 1 and progress.current_held > 1.0 + noise_tolerance(setup.n_held)):
        return
    t0 = time.perf_counter()
    for k in state.kept[1:]:
        start = dict(state.values) | {names[j][0]: 0.0 for j in state.kept if j != k}
        robj = Objective(setup.targets, setup.models, free_for(terms, names, [k], start, k), base_values=start,
                         threads=settings.threads)
        alone = refine(robj, start, settings.max_nfev)
        progress.n_sims += robj.n_sims
        if alone.ok and alone.held_rms_sigma < progress.current_held:
            settings.say(f"backward step: {terms[k].key} alone leaves {alone.held_rms_sigma:.4g} σ held-out, the "
                         f"set {progress.current_held:.4g} σ: the set is replaced by it")
            progress.rounds.append({"backward": {"kept_alone": terms[k].key, "held_rms_sigma": alone.held_rms_sigma,
                                                 "set_held_rms_sigma": progress.current_held}})
            state.kept = [k]
            state.values = start | alone.values
            progress.adopt(alone)
            break
    progress.timings["refit_s"] += time.perf_counter() - t0


#: a kept term is idle when the set without it, the others refitted, leaves a held-out error the records cannot tell
#: from the set's — within the held-out RMS's own statistical spread, 3/√(2 n) of it: a first pick the later terms
#: made redundant. MBIT.a, a root loss begun before the record: round 1 kept a drive saturation, round 2 the loss,
#: whose joint refit shrank the saturation to −0.025 % — the set without it, refitted, 0.9863 σ against 0.9839 σ
#: (0.24 %; the spread of MBIT.a's 2 501 held-out samples: 4.2 %, a 15 s sweep's 1 875: 4.9 %, MBIT.b's 375: 11 %)
#: — and that near-nothing led the verdict's first sentence
IDLE_SPREAD = 3.0
#: the set without the least missed term is refitted only when, unrefitted, it is within this factor of that limit
IDLE_PROBE_FACTOR = 1.25


def drop_idle(setup: SearchSetup, progress: SearchProgress, settings: SearchSettings) -> None:
    """Kept terms the records no longer need dropped, one at a time while more than one is kept and the set explains
    the records (the spread is the noise's: above it the residual is the model's error, 219 σ on the
    not-in-the-library challenge's strong tip stop, and a share of it says nothing of the noise): each kept term's
    coefficient set to 0 on the full model (one batch), the set refitted without the least missed one (when that
    alone stays within :data:`IDLE_PROBE_FACTOR` of the limit), and that term dropped when the refit leaves the
    held-out error within the statistical spread of the set's (:data:`IDLE_SPREAD`)."""
    state, names, terms = progress.state, setup.names, setup.terms
    t0 = time.perf_counter()
    while len(state.kept) > 1 and explained(progress.current_held, setup.held_before, setup.n_held):
        held, _, ok = probe_batch(setup.targets, setup.models, state.values,
                                  [{names[k][0]: 0.0} for k in state.kept], settings.threads)
        progress.n_sims += len(state.kept) * len(setup.targets)
        limit = progress.current_held * (1.0 + IDLE_SPREAD / math.sqrt(2.0 * max(setup.n_held, 1)))
        least = min((i for i in range(len(state.kept)) if ok[i]), key=lambda i: held[i], default=None)
        if least is None or held[least] > IDLE_PROBE_FACTOR * limit:  # clearly missed: no refit would bring it back
            break
        k = state.kept[least]
        rest = [j for j in state.kept if j != k]
        start = dict(state.values) | {names[k][0]: 0.0}
        robj = Objective(setup.targets, setup.models, free_for(terms, names, rest, start, None), base_values=start,
                         threads=settings.threads)
        without = refine(robj, start, settings.max_nfev)
        progress.n_sims += robj.n_sims
        if not (without.ok and without.held_rms_sigma <= limit):
            break
        settings.say(f"idle term: {terms[k].key} — without it (the others refitted) {without.held_rms_sigma:.4g} σ "
                     f"held-out, with it {progress.current_held:.4g} σ: dropped")
        progress.rounds.append({"idle_dropped": {"term": terms[k].key, "held_rms_sigma": without.held_rms_sigma,
                                                 "set_held_rms_sigma": progress.current_held}})
        state.kept = rest
        state.values = start | without.values
        progress.twins.pop(k, None)
        progress.adopt(without)
    progress.timings["refit_s"] += time.perf_counter() - t0
