"""Every patch's change in one patch (issue 26: which patch, when the screen chose all three).

The dictionary holds a switched change of the patches' coupling twice: every patch's (``d_ep``) and one patch's own
(``d_ep_i``). Where the three patches move the beam alike, the screen's linearised ranking may keep every patch's
change, smaller, in place of one patch's: blind set 7's patch 2 weak above 150 V of either polarity (15 s sweep) was
kept as "all three patches' authority d_ep is 18.4 % lower above ±170 V", 6.19 σ held out, and patch 2 was never
named.

:func:`patch_step`: after the joint polish and the shape swaps, when the set still leaves more than
3 σ, each kept switched change of every patch is probed as the same change in each one patch (its
switching point, gap or saturation and its instant held, :data:`PATCH_SIZES` times its size: one patch carries what
three did), the every-patch term off; the best :data:`MAX_REFITS` patches are refitted with every kept coefficient
and the shape free, and one is taken when it lowers the held-out error beyond the twins' tolerance.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from workbench.discover._dictionary import Term
from workbench.discover._dictionary_code import since_name
from workbench.discover._gates import TIME_GATES
from workbench.discover._onset import whole_scores
from workbench.discover._rounds import SearchProgress, SearchSettings, SearchSetup
from workbench.discover._term_swap import best_replacement, for_each_kept, take_replacement

#: one patch's change probed at these multiples of every patch's
PATCH_SIZES = (1.0, 2.0, 3.0)
#: patches refitted (the best by their probes)
MAX_REFITS = 2


def patch_step(setup: SearchSetup, progress: SearchProgress, settings: SearchSettings) -> None:
    """Each kept switched change of every patch tried in one patch (see the module docstring)."""
    def applies(k: int) -> bool:
        term = setup.terms[k]
        return term.placement == "damage" and term.param == "d_ep" and term.form not in TIME_GATES

    for_each_kept(setup, progress, applies, lambda k: _one_patch(setup, progress, settings, k))


def one_patch_terms(terms: Sequence[Term], every: Term) -> list[int]:
    """Dictionary indices of the same switched change in each one patch (the first of each patch's shapes)."""
    out: dict[int, int] = {}
    for j, t in enumerate(terms):
        if (t.placement == "damage" and t.param == "d_ep_i" and (t.form, t.signal) == (every.form, every.signal)
                and t.index not in out):
            out[t.index] = j
    return [out[i] for i in sorted(out)]


def moved_values(values: dict[str, float], names: Sequence[tuple[str, str | None]], k: int, j: int,
                 coef: float) -> dict[str, float]:
    """The dictionary values that move kept term ``k``'s change to term ``j`` at ``coef``: ``k`` off, ``j``'s shape
    and instant (if any) ``k``'s."""
    (ck, gk), (cj, gj) = names[k], names[j]
    out = {ck: 0.0, cj: coef}
    if gk is not None and gj is not None:
        out[gj] = values[gk]
    if since_name(k) in values and since_name(j) in values:
        out[since_name(j)] = values[since_name(k)]
    return out


def _one_patch(setup: SearchSetup, progress: SearchProgress, settings: SearchSettings, k: int) -> None:
    """Kept term ``k`` (every patch) moved to the one patch that fits clearly better."""
    state, names = progress.state, setup.names
    coef = float(state.values.get(names[k][0], 0.0))
    cands = [j for j in one_patch_terms(setup.terms, setup.terms[k]) if j not in state.kept]
    if not cands or coef == 0.0:
        return
    probes = [(j, moved_values(state.values, names, k, j, coef * m)) for j in cands for m in PATCH_SIZES]
    scores = np.asarray(whole_scores(setup.targets, setup.models, state.values, [p for _, p in probes],
                                     settings.threads))
    progress.n_sims += len(probes) * len(setup.targets)
    best: dict[int, tuple[float, dict[str, float]]] = {}
    for (j, p), e in zip(probes, scores):
        if np.isfinite(e) and e < best.get(j, (np.inf, p))[0]:
            best[j] = (float(e), p)
    tries = [(j, dict(state.values) | p, ()) for j, (_, p) in sorted(best.items(), key=lambda i: i[1][0])]
    take_replacement(setup, progress, settings, best_replacement(setup, progress, settings, k, tries[:MAX_REFITS]),
                     "patch_place", "in one patch")
