"""A crack opened by another section's bending (issue 26 point 3): a section's stiffness switched by the sign of a
neighbour's deflection or of the kink across a junction it meets (δ_{j+1} − δ_j), not by its own.

On a sweep the sections bend together in the first mode and apart in the others, so the screen linearised at the
nominal model ranks the section's own bilinear spring or the tip's swing first, and the right switch — whose size
must be placed within a few per cent, a resonance moving with it — is never refitted: a crack in section 2 opened
by the kink δ2 − δ1 > 0 (25 % of k2) was kept as a breathing crack opening for δ2 > 35.5 µm (7.3 σ held out; the
kink's own term at the truth's size leaves 0.98 σ, at 20 % or 30 % of k2 over 120 σ). :func:`neighbour_rows`: when
a round's best refit is a section's stiffness switched by a bending signal and leaves more than the noise, the same
section's stiffness switched by each other bending signal — either side, the best few by the screen — is refitted
from the best's size; the rounds keep one only when it fits clearly better
(:func:`workbench.discover._rounds.family_best`) and the refit comes near the noise (:func:`neighbour_may_lead`):
a neighbour's switch that explains only part may stand in for a second effect — a crack in section 2 that claps
(more damping) while shut, its clapping missing in the first round, was kept as opened by the kink δ2 − δ1 (then
4.73 σ with the damping found next; its own breathing crack and the damping 1.06 σ).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from workbench.discover._gates import SIGN_GATES
from workbench.discover._results import ScreenRow

#: neighbours are refitted only for a best that leaves more than this (σ held out): at the noise there is nothing
#: to tell
ABOVE_SIGMA = 1.5
#: at most this many neighbours are refitted (the best by the screen)
MAX_NEIGHBOURS = 3
#: a neighbour's switch replaces the round's best only when its refit leaves at most this (σ held out)
LEAD_SIGMA = 2.0


def bending(signal: str) -> bool:
    """A signal that bends the beam: a section's deflection, a kink across a junction, a mass's displacement."""
    return signal.startswith(("delta", "kink")) or (signal.startswith("z") and not signal.startswith("zd"))


def is_neighbour(term: Any) -> bool:
    """Whether ``term`` is a section's stiffness switched by another section's deflection or a junction's kink."""
    return (term.placement == "damage" and term.param == "k"
            and (term.signal.startswith("kink") or (term.signal.startswith("delta")
                                                    and term.signal != f"delta{term.index + 1}")))


def neighbour_may_lead(term: Any, held_rms_sigma: float) -> bool:
    """Whether a refit of ``term`` leaving ``held_rms_sigma`` may replace a round's best: any term but a neighbour's
    switch, and that only near the noise (:data:`LEAD_SIGMA`)."""
    return not is_neighbour(term) or held_rms_sigma <= LEAD_SIGMA


def neighbour_candidates(terms: Sequence[Any], rows: Sequence[ScreenRow], best_index: int, done: set[str]
                         ) -> list[int]:
    """Dictionary indices of the best term's section stiffness switched sharply by another bending signal, either
    side, in the screen's order (``rows``; unscreened last), not refitted yet (``done``: keys)."""
    best = terms[best_index]
    if best.placement != "damage" or best.param != "k" or not bending(best.signal):
        return []
    rank = {r.term.key: i for i, r in reversed(list(enumerate(rows)))}
    cands = [k for k, t in enumerate(terms)
             if t.placement == "damage" and (t.param, t.index) == (best.param, best.index) and t.form in SIGN_GATES
             and bending(t.signal) and t.signal != best.signal and t.key not in done]
    return sorted(cands, key=lambda k: rank.get(terms[k].key, math.inf))


def neighbour_rows(setup: Any, best: Any, rows: Sequence[ScreenRow], done: set[str]) -> list[ScreenRow]:
    """Rows to refit for the round's ``best`` refit (a ``BestRefit``; ``setup``: the rounds' ``SearchSetup``): the
    best :data:`MAX_NEIGHBOURS` of :func:`neighbour_candidates`, starting at the best's size and a switch at 0."""
    if best.held_rms_sigma <= ABOVE_SIGMA:
        return []
    coef = float(best.outcome.values.get(setup.names[best.index][0], 0.0))
    if coef == 0.0:
        return []
    cands = neighbour_candidates(setup.terms, rows, best.index, done)[:MAX_NEIGHBOURS]
    return [ScreenRow(setup.terms[k], coef, math.inf, math.inf, shape=0.0, placed=True) for k in cands]
