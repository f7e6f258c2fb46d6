"""Find what changes, then trend it: when the default re-estimation (k3, α_h, β_h) does not explain a visit, ask
the workbench which parameters or effects changed, and re-estimate those on every visit.

A visit calls for it (:func:`excess_trigger`) when the default fit leaves more than the noise — a held-out RMS above
:data:`EXCESS_SIGMA` σ *and* above :data:`EXCESS_SIGMA` × the first visit's (a board visit's records leave ≈ 1.8 σ
at entry into service already) — or when one of its estimates ran to its fit bound (the parameters moved the way no
change of theirs can explain: a leaking patch drove k3 to +200 % on the test lives). Then
:func:`workbench.diagnose.diagnose` runs **once**, on the latest visit that shows it, against the first visit's
fitted set as the base (entry into service, not the nominal table), with the candidates limited to the section
stiffnesses, the hysteresis parameters and the library effect the patches grow in service, their leakage
(:data:`CANDIDATES`; ≈ 2 s per diagnosis). What it names becomes the re-estimation set
(:func:`reestimation_set`): a core parameter is freed, an effect is added with its own parameters freed (G_leak
for dielectric leakage). Each visit is then re-estimated with that set and each freed parameter trended — an
effect's parameter in its own unit (it has no nominal value to be relative to), a core parameter relative to the
nominal set (the monitor's trip boundary is in those terms).
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from studies.health.estimate import DEFAULT_FREE, VisitEstimates

#: held-out RMS (σ) above which the default fit leaves more than the noise (and above this × the first visit's)
EXCESS_SIGMA = 1.5
#: what diagnose may name: section stiffnesses, hysteresis, and the library effect a patch grows in service (its
#: leakage). Each further effect costs its own model (root_compliance and piezo_creep took the diagnosis of one
#: visit from 1.7 s to 80 s on the loaded machine, most of it compiling); add one here with its entry in
#: EFFECT_PARAMETERS
CANDIDATES: tuple[str, ...] = ("k1", "k2", "k3", "alpha_h", "beta_h", "dielectric_leakage")
#: an effect's parameters: the upper end searched for the monitor's trip limit (SI) and a repeatability floor
EFFECT_PARAMETERS: dict[str, dict[str, dict[str, float]]] = {
    "dielectric_leakage": {"G_leak": {"upper": 2.0e-3, "floor": 1.0e-7}},
}


def excess_trigger(ests: Sequence[VisitEstimates]) -> tuple[int, str] | None:
    """(index, reason) of the latest visit whose default fit leaves more than the noise or ran to a bound."""
    first = ests[0].held_rms_sigma
    limit = EXCESS_SIGMA * max(first if math.isfinite(first) else 1.0, 1.0)
    for i in range(len(ests) - 1, -1, -1):
        e = ests[i]
        bound = [x.name for x in e.estimates if x.at_bound]
        if bound:
            return i, (f"{', '.join(bound)} ran to {'its' if len(bound) == 1 else 'their'} fit bound (a change these "
                       "parameters cannot explain)")
        if e.held_rms_sigma > limit:
            return i, (f"the default fit leaves {e.held_rms_sigma:.2f} σ held-out residual (more than "
                       f"{limit:.2f} σ: {EXCESS_SIGMA:g} × max(1, the first visit's {first:.2f} σ))")
    return None


def reestimation_set(named: Sequence[str]) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """(effects to add, parameters to free) for what diagnose named; the defaults when it named nothing usable."""
    from board_config.parameter_sets import CORE_PARAMETER_NAMES

    effects = tuple(n for n in named if n in EFFECT_PARAMETERS)
    core = tuple(n for n in named if n in CORE_PARAMETER_NAMES)
    free = core + tuple(p for e in effects for p in EFFECT_PARAMETERS[e])
    return (effects, free) if free else ((), DEFAULT_FREE)


def base_values(first_estimates: VisitEstimates) -> dict[str, float]:
    """The first visit's fitted core values (SI) — the base the later visits are compared with."""
    return {x.name: float(x.value) for x in first_estimates.estimates if not x.at_bound}


@dataclass(frozen=True)
class VisitDiagnosis:
    """What ``shm diagnose`` says changed on one visit against the first visit's fitted set."""

    named: tuple[str, ...]
    """Effects and parameters diagnose blames, in its order (empty: nothing)."""
    verdict: str
    """Diagnose's verdict word."""
    message: str
    """Diagnose's message, in words."""
    wall_s: float
    """Wall time of the diagnosis (s)."""


def diagnose_visit(records: Sequence[Any], params: str, base: dict[str, float],
                   candidates: Sequence[str] = CANDIDATES) -> VisitDiagnosis:
    """What changed on this visit against ``base`` (the first visit's fitted values, SI)."""
    from board_config import load_parameter_set
    from studies.health.estimate import join_visit_records
    from workbench.diagnose import diagnose

    t0 = time.perf_counter()
    board = all(r.meta.get("provenance", {}).get("generator") == "board" for r in records)
    recs = [join_visit_records(records)] if board else list(records)
    pset = load_parameter_set(params).with_values(None, **base)
    d = diagnose(recs, pset, candidates=list(candidates), max_nfev=30)
    return VisitDiagnosis(tuple(d.found), d.verdict, d.message, time.perf_counter() - t0)


def effect_of(parameter: str) -> str | None:
    """The effect a parameter belongs to (None: a core parameter)."""
    return next((e for e, ps in EFFECT_PARAMETERS.items() if parameter in ps), None)
