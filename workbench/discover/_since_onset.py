"""A kept switch that began during the record (issue 26: damage of two kinds at once, a side *and* an instant).

A crack that appears at an instant and then breathes, or a patch whose one polarity goes weak mid-test (an electrode
finger cracks), is a switched change — open on one side of the motion or the drive — that holds only from that
instant on. The dictionary's switched terms span the whole record, so the search keeps the switch diluted over it:
blind set 7's tip patch weak for v_c3 > 0 from 6 s of a 15 s sweep was kept as patch 3 weak on that side all along
and left 21.9 σ. Every switched damage term of :data:`~workbench.discover._gates.SINCE_PARAMS` carries the instant
its change began (``s_NN``, from before any record: the term unchanged).

:func:`since_step`: after the joint polish and the shape swaps, when the set still leaves more than
3 σ, each kept switched term is probed begun at :data:`SINCE_AT` of the record — its coefficient
scaled up by the share of the record it then misses (the whole-record fit spread the change over all of it) and
half way to that — on the whole record's RMS; the best :data:`MAX_REFITS` instants (apart by more than one grid
step) are refitted with every kept coefficient, the term's shape and the instant free within a grid step either
way. The instant is taken when it lowers the held-out error beyond the twins' tolerance: a change that held all
along keeps its whole record.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from board_config.parameter import Parameter, freed
from workbench.discover._dictionary_code import since_name, since_placed
from workbench.discover._finite_change import whole_rms
from workbench.discover._onset import whole_scores
from workbench.discover._onset_profile import placed_on_whole
from workbench.discover._rounds import SearchProgress, SearchSettings, SearchSetup
from workbench.discover._term_swap import best_replacement, for_each_kept, take_replacement

#: instants probed, fractions of the record (the refit moves the best a grid step either way)
SINCE_AT = tuple(np.round(np.arange(0.05, 0.951, 0.05), 3))
#: at most this many instants of one kept term are refitted (the best by their probes, apart by a grid step)
MAX_REFITS = 2


def since_step(setup: SearchSetup, progress: SearchProgress, settings: SearchSettings) -> None:
    """Each kept switched term tried as begun at an instant of the record (see the module docstring)."""
    duration = float(setup.scales.get("t", 0.0))
    if duration > 0.0:
        for_each_kept(setup, progress, lambda k: whole_record(progress.state.values, k),
                      lambda k: _since_one(setup, progress, settings, k, duration))


def whole_record(values: Mapping[str, float], k: int) -> bool:
    """Whether dictionary term ``k`` may begin at an instant and still spans the whole record."""
    return since_name(k) in values and not since_placed(values, k)


def probe_grid(coef: float, duration_s: float) -> list[tuple[float, float]]:
    """(instant s, coefficient) of every probe: at each of :data:`SINCE_AT`, the whole-record coefficient ``coef``
    scaled by the share of the record the change then misses, D/(D − T), and by its square root."""
    out = []
    for f in SINCE_AT:
        gain = 1.0 / (1.0 - f)
        out += [(f * duration_s, coef * gain), (f * duration_s, coef * float(np.sqrt(gain)))]
    return out


def best_instants(grid: Sequence[tuple[float, float]], scores: np.ndarray, step_s: float
                  ) -> list[tuple[float, float]]:
    """The best :data:`MAX_REFITS` probes (instant, coefficient) by ``scores`` (whole-record RMS, inf where a probe
    failed), each more than ``step_s`` from a better one."""
    out: list[tuple[float, float]] = []
    for i in np.argsort(scores, kind="stable"):
        if not np.isfinite(scores[i]) or len(out) == MAX_REFITS:
            break
        if all(abs(grid[i][0] - t) > step_s * 1.01 for t, _ in out):
            out.append(grid[i])
    return out


def since_free(name: str, at_s: float, step_s: float, duration_s: float) -> Parameter:
    """The instant's free parameter: within a grid step of ``at_s``, inside the record."""
    return freed(name, "s", max(at_s - step_s, 0.0), min(at_s + step_s, duration_s), False, "discover")


def _since_one(setup: SearchSetup, progress: SearchProgress, settings: SearchSettings, k: int,
               duration: float) -> None:
    """Kept term ``k`` begun at its best instant when that fits clearly better than the whole record."""
    state, (cname, _) = progress.state, setup.names[k]
    coef = float(state.values.get(cname, 0.0))
    if coef == 0.0:
        return
    sname, step = since_name(k), duration * (SINCE_AT[1] - SINCE_AT[0])
    grid = probe_grid(coef, duration)
    scores = np.asarray(whole_scores(setup.targets, setup.models, state.values,
                                     [{cname: c, sname: t} for t, c in grid], settings.threads))
    progress.n_sims += len(grid) * len(setup.targets)
    tries = [(k, dict(state.values) | {cname: c, sname: at}, [since_free(sname, at, step, duration)])
             for at, c in best_instants(grid, scores, step)]
    best = best_replacement(setup, progress, settings, k, tries)
    if best is None:
        return
    at = float(best.outcome.values.get(sname, best.start[sname]))
    if take_replacement(setup, progress, settings, best, "since_instant", f"begun at t = {at:.4g} s",
                        {"since_s": at}):  # the whole-record twins no longer explain the records alike
        place_instant(setup, progress, settings, k)


def place_instant(setup: SearchSetup, progress: SearchProgress, settings: SearchSettings, k: int) -> None:
    """Kept term ``k``'s instant moved to where the whole record's RMS is lowest (:func:`~workbench.discover.
    _onset_profile.placed_on_whole`: least squares hardly moves a sharp switch-on — blind set 7's patch weak from
    6.0 s kept at its probe's 6.034 s), then the set refitted there (sizes and ``k``'s shape; a crack from 6.75 s
    kept from 6.689 s left 3.82 σ, the refit at the placed instant says what the set leaves there)."""
    if progress.outcome is None:
        return
    name, values = since_name(k), progress.state.values
    at, _, n = placed_on_whole(setup.targets, setup.models, values, name, whole_rms(setup.targets, progress.outcome),
                               settings.threads)
    progress.n_sims += n
    if at == values[name]:
        return
    values[name] = at
    progress.stderr.pop(name, None)  # the refit's standard error was about the instant it started from
    found = best_replacement(setup, progress, settings, k, [(k, dict(values), ())])
    if found is not None:
        progress.state.values = values | {p: v for p, v in found.outcome.values.items() if p != name}
        progress.adopt(found.outcome)
