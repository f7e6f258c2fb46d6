"""A one-sided force on a mass read as damage of a section (issue 26 point 3): a section whose stiffness changes
past a switching point of its own deflection — a crack closing on wedged debris, a crack opening past a gap — acts
on a record that excites one mode (an MBIT) as a one-sided force on the mass at the section's end does (contact with
a stop, a support that lets go). The search keeps whichever its screen ranks first; the force's screen is probed at
its thresholds, the section's switch only at zero (its switching point is refitted, from zero), so the force wins
and the section's reading is never refitted: a tip crack stiffer past δ3 < −0.3 mm on MBIT.a was said "a one-sided
force on mass 3 (the tip) … acting only when z3 < −897 µm: contact with a stop", the other masses its twins, section 3
never named (blind sets 2 and 3, twice).

:func:`section_rows`: when the round keeps such a force and it nearly explains the records, each section's stiffness
switched on the same side of its own deflection, its switching point mapped from the force's threshold by the two
signals' scales, is probed on the full model at a few sizes and switching points and returned as rows for a refit
(placed at the best probe) when it comes near; :func:`workbench.discover._twins.place_first` then names a reading of
another kind among the twins.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from workbench.discover._event_check import PLACE_NEAR
from workbench.discover._onset import whole_record_rms
from workbench.discover._results import ScreenRow
from workbench.discover._search import probe_batch
from workbench.discover._twins import PLACE_BELOW_SIGMA

#: the one-sided forms of a force on a mass, and the side of the section's switch each maps to
ONE_SIDED = {"pos": "on_pos", "neg": "on_neg"}
#: relative stiffness changes a section's switch is probed at (a loss and a gain: a crack opening, a wedge closing)
SIZES = (-0.6, -0.45, -0.3, -0.2, -0.1, 0.1, 0.2, 0.4, 0.8)
#: the mapped switching point is probed at these multiples
POINTS = (0.6, 1.0, 1.5)
#: at most this many sections' readings are refitted (the best by their probes)
MAX_READINGS = 2
#: a probe comes near when it leaves at most PLACE_NEAR × the force's held-out RMS, or this share of the held-out
#: RMS the round started from: the sizes are a coarse grid, and on a large effect a size 15 % off leaves tens of σ
#: (a crack past a gap at δ3 > 0.6 mm losing 35 %, MBIT.a, 147 σ: probed at its point and −30 %, 30 σ; refitted,
#: the refit places it)
NEAR_SHARE = 0.25


def mapped_point(form: str, threshold: float, scale_from: float, scale_to: float) -> float:
    """The section's switching point (m of its deflection) for a force ``form`` ("pos": z > G, "neg": z < −G) of
    ``threshold`` G on a mass signal of scale ``scale_from``, read on a deflection of scale ``scale_to``."""
    at = abs(threshold) * scale_to / max(scale_from, 1e-300)
    return at if form == "pos" else -at


def section_rows(setup: Any, progress: Any, settings: Any, best: Any, done: set[str]) -> list[ScreenRow]:
    """Rows of the sections' own switched stiffness for the round's ``best`` refit (a ``BestRefit``) when it is a
    one-sided force on a mass that leaves at most :data:`PLACE_BELOW_SIGMA`: each section's switch on the force's
    side, probed at :data:`SIZES` × :data:`POINTS` of the mapped switching point, kept (placed at its best probe)
    when that comes near (:data:`NEAR_SHARE`); not refitted yet (``done``: keys).
    ``setup``, ``progress``, ``settings``: the rounds' objects."""
    term = setup.terms[best.index]
    gname = setup.names[best.index][1]
    if term.placement != "force_mass" or term.form not in ONE_SIDED or gname is None \
            or best.held_rms_sigma > PLACE_BELOW_SIGMA:
        return []
    threshold = float(best.outcome.values.get(gname, term.shape))
    side = ONE_SIDED[term.form]
    cands = [k for k, t in enumerate(setup.terms) if t.placement == "damage" and t.param == "k" and t.form == side
             and t.signal == f"delta{t.index + 1}" and t.key not in done and t.shape_range is not None]
    trials: list[tuple[int, float, float]] = []
    for k in cands:
        t = setup.terms[k]
        lo, hi = t.shape_range
        at = mapped_point(term.form, threshold, setup.scales.get(term.signal, 1.0), setup.scales.get(t.signal, 1.0))
        trials += [(k, c, min(max(m * at, lo), hi)) for c in SIZES for m in POINTS]
    if not trials:
        return []
    settings_ = [{setup.names[k][0]: c, str(setup.names[k][1]): g} for k, c, g in trials]
    held, train, ok = probe_batch(setup.targets, setup.models, progress.state.values, settings_, settings.threads)
    progress.n_sims += len(trials) * len(setup.targets)
    whole = np.where(ok, whole_record_rms(setup.targets, held, train), np.inf)
    limit = max(PLACE_NEAR * max(best.held_rms_sigma, 1.0), NEAR_SHARE * progress.current_held)
    rows: dict[int, tuple[float, ScreenRow]] = {}
    for (k, c, g), e, h in zip(trials, whole, held):
        if math.isfinite(e) and h <= limit and e < rows.get(k, (math.inf, None))[0]:
            rows[k] = (float(e), ScreenRow(setup.terms[k], c, float(h), math.inf, shape=g, placed=True))
    out = [r for _, r in sorted(rows.values(), key=lambda er: er[0])]
    if out:
        settings.say(f"  {term.key} read as a section's own switch: {len(out)} within {limit:.3g} σ ("
                     + ", ".join(f"{r.term.key} {r.held_rms_sigma:.3g} σ" for r in out) + ")")
    return out[:MAX_READINGS]

