"""An event that acts on one side of the motion or the drive (issue 26: damage of two kinds at once).

A crack that appears at an instant and then breathes, or a patch whose one polarity goes weak mid-test, changes the
records from an instant on — so the rounds keep it as a step of its parameter at that instant, about half its size
(the change acts on one side only): blind set 7's tip patch weak for v_c3 > 0 from 6 s of a 15 s sweep was kept as
"authority d_ep of patch 3 dropped by 26.1 % at t = 6.13 s" and a second term, 15 σ held out. The step has the
parameter, the place and the instant; what it lacks is the side.

:func:`side_step`: after the joint polish and the shape swaps, when the set still leaves more than
3 σ, each kept step of a parameter of :data:`~workbench.discover._gates.SINCE_PARAMS` is probed as
each switched term of its parameter and place begun at the step's instant or up to :data:`SIDE_BEFORE_S` before it
(the switched change :data:`SIDE_SIZES` times the step's — on one side of a motion about half the time, it must be
larger), alone: the terms kept beside the step made up for what the step missed, and with the step gone they only
mislead (there, patch 2's authority 3 % higher for negative voltage: patch 3's positive side from 6.03 s probed
34.9 σ beside it, 1 σ alone at 30 %). The best
:data:`MAX_SIDES` by their probes are probed over their shapes (:func:`~workbench.discover._gate_shape.best_shapes`)
and the best :data:`MAX_REFITS` refitted with every kept coefficient, the switch's shape and its instant (within
:data:`SIDE_ONSET_S`) free. One is taken when it lowers the held-out error beyond the twins' tolerance: a step that
is a step (or a record that never shows the other side) keeps its step.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from workbench.discover._dictionary import Term
from workbench.discover._dictionary_code import carries_since, since_name
from workbench.discover._gate_shape import best_shapes
from workbench.discover._gates import SINCE_PARAMS
from workbench.discover._onset import whole_scores
from workbench.discover._rounds import SearchProgress, SearchSettings, SearchSetup
from workbench.discover._since_onset import place_instant, since_free
from workbench.discover._term_swap import best_replacement, for_each_kept, take_replacement

#: the switched change probed at these multiples of the step's change (a one-sided change acts about half the time)
SIDE_SIZES = (1.0, 1.4, 2.0)
#: switched terms probed over their shapes (the best by their first probe), and refitted (the best by their shapes)
MAX_SIDES = 4
MAX_REFITS = 2
#: instants a switched change is probed at, from the step's (s): a change on one side shows first when the motion
#: or the drive is next on that side, so the step is kept at or after the instant the change began (blind set 7's
#: patch 3 weak for v_c3 > 0 from 6.0 s of a sweep: its step at 6.13 s)
SIDE_BEFORE_S = (0.0, -0.1, -0.2, -0.3)
#: the refit moves the switch's instant at most this far from its best probe's (s)
SIDE_ONSET_S = 0.15


def side_step(setup: SearchSetup, progress: SearchProgress, settings: SearchSettings) -> None:
    """Each kept step tried as a switched change begun at its instant (see the module docstring)."""
    def applies(k: int) -> bool:
        term = setup.terms[k]
        return term.placement == "damage" and term.form == "on_step" and term.param in SINCE_PARAMS

    if setup.scales.get("t", 0.0) > 0.0:
        for_each_kept(setup, progress, applies, lambda k: _side_one(setup, progress, settings, k))


def side_candidates(terms: Sequence[Term], step: Term) -> list[int]:
    """Dictionary indices of the switched terms of ``step``'s parameter and place that may begin at an instant."""
    return [j for j, t in enumerate(terms) if carries_since(t) and (t.param, t.index) == (step.param, step.index)]


def first_probes(setup: SearchSetup, cands: Sequence[int], coef: float, at: float) -> list[dict[str, float]]:
    """Each candidate at its dictionary shape, :data:`SIDE_SIZES` × ``coef`` and begun at :data:`SIDE_BEFORE_S`
    from ``at`` (s; not before the record)."""
    out = []
    for j in cands:
        cname, gname = setup.names[j]
        shape = {str(gname): setup.terms[j].shape} if gname is not None else {}
        out += [{cname: coef * m, since_name(j): max(at + d, 0.0)} | shape for m in SIDE_SIZES
                for d in SIDE_BEFORE_S]
    return out


def best_candidates(cands: Sequence[int], probes: Sequence[dict[str, float]], scores: np.ndarray,
                    n: int) -> list[tuple[int, float]]:
    """The ``n`` candidates with the lowest finite score over their probes, each with its best probe's instant."""
    per = np.asarray(scores, float).reshape(len(cands), -1)
    out = []
    for i in np.argsort(per.min(axis=1), kind="stable")[:n]:
        if np.isfinite(per[i].min()):
            j = cands[i]
            out.append((j, probes[i * per.shape[1] + int(per[i].argmin())][since_name(j)]))
    return out


def _side_one(setup: SearchSetup, progress: SearchProgress, settings: SearchSettings, k: int) -> None:
    """Kept step ``k`` replaced by a switched change begun at its instant when that fits clearly better."""
    state, names = progress.state, setup.names
    cname, gname = names[k]
    coef, at = float(state.values.get(cname, 0.0)), float(state.values.get(str(gname), 0.0))
    cands = [j for j in side_candidates(setup.terms, setup.terms[k]) if j not in state.kept]
    if not cands or coef == 0.0:
        return
    alone = dict(state.values) | {names[i][0]: 0.0 for i in state.kept}
    probes = first_probes(setup, cands, coef, at)
    scores = np.asarray(whole_scores(setup.targets, setup.models, alone, probes, settings.threads))
    progress.n_sims += len(scores) * len(setup.targets)
    found: list[tuple[float, tuple[int, float, float], float]] = []  # (RMS, trial, instant)
    for j, since in best_candidates(cands, probes, scores, MAX_SIDES):
        base = alone | {since_name(j): since}
        found += [(e, trial, since) for e, trial in best_shapes(setup, progress, settings, [j], 1.5 * coef,
                                                                 base).values()]
    tries = []
    for _, (j, c, g), since in sorted(found, key=lambda f: f[0])[:MAX_REFITS]:
        start = dict(state.values) | {cname: 0.0, names[j][0]: c, since_name(j): since}
        start |= {str(names[j][1]): g} if names[j][1] else {}
        tries.append((j, start, [since_free(since_name(j), since, SIDE_ONSET_S, float(setup.scales["t"]))]))
    side = best_replacement(setup, progress, settings, k, tries)
    if take_replacement(setup, progress, settings, side, "event_side", "on one side from its instant") and side:
        place_instant(setup, progress, settings, side.index)
