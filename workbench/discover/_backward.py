"""The backward step of ``shm discover``'s forward selection (:func:`backward_step`): after the rounds, a later
kept term alone may explain more than the set its first pick led to."""

from __future__ import annotations

import time

from workbench.discover._rounds import SearchProgress, SearchSettings, SearchSetup
from workbench.discover._search import free_for, refine
from workbench.fit import Objective, noise_tolerance


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
            progress.stderr.update({e.name: e.stderr for e in alone.estimates})
            progress.current_train, progress.current_held = alone.train_rms_sigma, alone.held_rms_sigma
            progress.outcome = alone
            break
    progress.timings["refit_s"] += time.perf_counter() - t0
