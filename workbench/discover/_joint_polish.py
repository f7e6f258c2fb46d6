"""The joint polish of ``shm discover`` (:func:`polish_step`): after the rounds, when more than one term is kept
and the set still leaves more than the noise, every kept term's coefficient *and* shape is refitted together.

Each round refits its new term's shape with the earlier terms' shapes held where their own rounds left them: a crack
kept in round 1 switching at +20 µm of δ2 stays there while round 2 adds the damping its faces add when they rub,
although the crack's best switching point moves once the damping is in (blind set 6, a 25 % crack in section 2 that
also rubs while open, 15 s sweep: the two kept terms left 5.44 σ held out; the emitted file refitted by ``shm fit
--add``, every shape free, 1.13 σ). The same terms, refitted together, replace the set's values only when the
held-out error falls.
"""

from __future__ import annotations

import time

from workbench.discover._rounds import SearchProgress, SearchSettings, SearchSetup
from workbench.discover._search import free_for, refine
from workbench.fit import Objective, explained

#: the set is polished only when it leaves more than this (σ held out; the verdicts' reach of the noise floor)
ABOVE_SIGMA = 1.5


def polish_step(setup: SearchSetup, progress: SearchProgress, settings: SearchSettings) -> None:
    """Every kept term's coefficient and shape refitted together (more than one kept, above :data:`ABOVE_SIGMA` and
    not explained); the values replace the set's when the held-out error falls."""
    state = progress.state
    if (len(state.kept) < 2 or progress.current_held <= ABOVE_SIGMA
            or explained(progress.current_held, setup.held_before, setup.n_held)):
        return
    t0 = time.perf_counter()
    start = dict(state.values)
    free = [fp for k in state.kept for fp in free_for(setup.terms, setup.names, [k], start, k)]
    robj = Objective(setup.targets, setup.models, free, base_values=start, threads=settings.threads)
    out = refine(robj, start, settings.max_nfev)
    progress.n_sims += robj.n_sims
    progress.timings["refit_s"] += time.perf_counter() - t0
    if not out.ok or out.held_rms_sigma >= progress.current_held:
        return
    keys = [setup.terms[k].key for k in state.kept]
    settings.say(f"joint polish: {' + '.join(keys)}, every shape free: held-out {progress.current_held:.4g} σ → "
                 f"{out.held_rms_sigma:.4g} σ")
    progress.rounds.append({"polish": {"terms": keys, "held_rms_sigma": out.held_rms_sigma,
                                       "set_held_rms_sigma": progress.current_held}})
    state.values = start | out.values
    progress.adopt(out)
