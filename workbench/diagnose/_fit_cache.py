"""Fits of candidate sets made during one forward selection (:mod:`workbench.diagnose._forward_selection`), kept
by what the set holds so that a set met again is fitted once."""

from __future__ import annotations

import copy
from collections.abc import Mapping, Sequence
from typing import Any

from board_config import ParameterSet
from workbench.fit import CandidateResult, CandidateSpec, Target, fit_spec, score

#: screening points of a set's full fit: every set is fitted from a start that is already a fit (the current set's
#: values with the added member's screened or fitted values, or a quick try's end), so the full fit refines rather
#: than searches the box (the library's single candidates keep the wide design, N_SCREEN_MIN and up)
SET_SCREEN = 16


class FitCache:
    """Fits of candidate sets made during one selection, by what the set holds (its effects, parameters and extras):
    the beam's paths, the backward step's drop-one fits and the swap meet the same sets again (the set before a
    path's last addition is one of its drop-one fits; two paths that add the same two members in either order end in
    the same set). A set is fitted once; each use gets a copy scored against the nominal model."""

    def __init__(self) -> None:
        self.fits: dict[tuple, CandidateResult] = {}
        self.hits = 0

    @staticmethod
    def key(spec: CandidateSpec, effort: Mapping[str, Any] | None = None) -> tuple:
        """What the set holds, and how hard it is fitted (a quick try is not a full fit)."""
        effort = effort or {}
        return (frozenset(e.name for e in spec.effects), frozenset((p.name, p.tied) for p in spec.params),
                frozenset(spec.extras), tuple(sorted((k, effort[k]) for k in ("max_nfev", "max_widen", "n_screen")
                                                     if k in effort)))

    def fit(self, spec: CandidateSpec, base: ParameterSet, targets: Sequence[Target], data: Mapping[str, Any],
            rss0_held: float, *, start: Mapping[str, float], min_reduction: float, **kw: Any) -> CandidateResult:
        """:func:`~workbench.fit.fit_spec` of ``spec`` (from ``start`` the first time it is met; screened with
        :data:`SET_SCREEN` points unless told otherwise)."""
        kw.setdefault("n_screen", SET_SCREEN)
        k = self.key(spec, kw)
        if k in self.fits:
            self.hits += 1
            r = copy.copy(self.fits[k])
            if r.outcome is not None:
                score(r, rss0_held, min_reduction)
            return r
        r = fit_spec(spec, base, targets, data, rss0_held, start=dict(start), min_reduction=min_reduction, **kw)
        self.fits[k] = copy.copy(r)
        return r
