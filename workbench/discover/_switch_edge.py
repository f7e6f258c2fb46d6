"""A switch with a fitted edge (issue 26 point 3): a sign gate that switches off zero *and* over a finite range —
a crack whose rough faces close progressively past an opening, a patch that weakens over a band of drive.

The dictionary's sign gates switch at a fitted point with a sharp edge, its smooth gates over a fitted width but at
zero; a switch off zero with an edge of its own is neither: couple 2 losing 30 % of its authority above +80 V of
drive, over a 15 V edge, was kept as the sharp switch (2.24 σ held out). Every sign gate carries its edge width as a
dictionary parameter (``h_NN``, default the sharp width of :data:`~workbench.discover._gates.SIGN_WIDTH`), so when a
kept switch leaves more than the noise, :func:`switch_edge_refit` probes edge widths at its switching point, zooms
the best over the whole record and refits size, switching point and width.

Pure logic on the fit engine's objects; :mod:`workbench.discover._kept_change` keeps the result.
"""

from __future__ import annotations

from collections.abc import Sequence

from board_config.parameter import Parameter, freed
from plant import PlantModel
from workbench.discover._dictionary import Term
from workbench.discover._dictionary_code import width_name
from workbench.discover._finite_change import WindowFit, others_free
from workbench.discover._onset import MAX_LOSS
from workbench.discover._search import SearchState, refine
from workbench.discover._smooth_change import Edge, EdgeProbe, zoom_edge
from workbench.fit import Objective, Target

#: edge widths probed (fractions of the switching signal's scale, its 99th percentile of |value|) and the size of
#: the change as multiples of the sharp switch's (a gradual switch gives up part of its effect near the point)
EDGE_WIDTHS = (0.01, 0.03, 0.08, 0.2)
EDGE_TOTALS = (1.0, 1.3)
#: how far the switching point may move in the zoom and the refit (fractions of the signal's scale)
POINT_FREE = 0.3


def candidate_switch_edges(coef: float, point: float, scale: float) -> list[Edge]:
    """Edges to probe from a kept sharp switch of size ``coef`` at ``point`` on a signal of ``scale`` (SI)."""
    return [Edge(point, w * scale, coef * m) for w in EDGE_WIDTHS for m in EDGE_TOTALS]


def switch_bounds(term: Term, point: float, scale: float) -> tuple[float, float]:
    """Where the switching point may lie: ± :data:`POINT_FREE` of the scale around ``point``, within the term's own
    range widened by that much."""
    lo, hi = term.shape_range or (-scale, scale)
    d = POINT_FREE * scale
    return max(point - d, lo - d), min(point + d, hi + d)


def switch_free(terms: Sequence[Term], names: Sequence[tuple[str, str | None]], state: SearchState,
                start: dict[str, float], kept: int, bounds: tuple[float, float]) -> list[Parameter]:
    """Free parameters of the refit: the other kept terms' coefficients (±1.5 × their size), the switch's size (±2
    × it, a loss never past ``MAX_LOSS``), its switching point (within ``bounds``) and its edge width (a factor of
    three either way, in log)."""
    out = others_free(terms, names, state, start, (kept, kept), kept)
    cname, gname = names[kept]
    c, g, w = start[cname], start[str(gname)], start[width_name(kept)]
    lo = max(c - 2.0 * abs(c), MAX_LOSS) if terms[kept].unit == "1" else c - 2.0 * abs(c)
    out.append(freed(cname, terms[kept].unit, lo, c + 2.0 * abs(c), False, "discover"))
    out.append(freed(str(gname), terms[kept].shape_unit, min(bounds[0], g), max(bounds[1], g), False, "discover"))
    out.append(freed(width_name(kept), terms[kept].shape_unit, w / 3.0, w * 3.0, True, "discover"))
    return out


def switch_edge_refit(targets: Sequence[Target], models: Sequence[PlantModel], terms: Sequence[Term],
                      names: Sequence[tuple[str, str | None]], state: SearchState, kept: int, scale: float,
                      threads: int | None, max_nfev: int) -> WindowFit | None:
    """The kept sign gate ``kept`` (dictionary index) with a fitted edge: the edges of
    :func:`candidate_switch_edges` probed on the full model, the best zoomed and refitted (:func:`switch_free`).
    None when the term is no sign gate with a switching point, the signal has no scale or nothing integrates."""
    term = terms[kept]
    cname, gname = names[kept]
    if term.form not in ("on_pos", "on_neg") or gname is None or not scale > 0.0:
        return None
    coef, point = float(state.values[cname]), float(state.values[gname])
    bounds = switch_bounds(term, point, scale)
    probe = EdgeProbe(targets, models, dict(state.values), (cname, gname, width_name(kept)), threads, term.form,
                      bounds=bounds)
    zoomed = zoom_edge(probe, candidate_switch_edges(coef, point, scale), 0.0)
    if zoomed is None:
        return None
    edge, _, n = zoomed
    start = probe.values | probe.setting(edge)
    obj = Objective(targets, models, switch_free(terms, names, state, start, kept, bounds), base_values=start,
                    threads=threads)
    out = refine(obj, start, max_nfev)
    if not out.ok:
        return None
    return WindowFit(kept, kept, kept, out, start | out.values, n * len(targets) + obj.n_sims, kind="edge")
