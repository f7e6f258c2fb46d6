"""Follow what changes: the visit series of whichever set is re-estimated, its trends, and the switch from the
default set to the set diagnose names (:mod:`.cause`) — shared by ``shm health`` and the prognosis challenge.

A core parameter is trended as its relative change from the nominal set (the monitor's trip boundary is in those
terms); an added effect's parameter in its own unit (G_leak in S: its nominal is 0), with the effect's own
repeatability floor, and its trip limit from :func:`.trip.effect_trip_limit`.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from studies.health.cause import (
    EFFECT_PARAMETERS,
    base_values,
    diagnose_visit,
    effect_of,
    excess_trigger,
    reestimation_set,
)
from studies.health.estimate import DEFAULT_FREE, VisitEstimates
from studies.health.trend import SIGMA_FLOOR, Trend, fit_trend

SECTION_STIFFNESSES = ("k1", "k2", "k3")


@dataclass
class Followed:
    """Which set is re-estimated from which visit on, and why."""

    free: tuple[str, ...] = DEFAULT_FREE
    effects: tuple[str, ...] = ()
    #: index of the visit diagnose ran on (None: it did not run)
    diagnosed_visit: int | None = None
    trigger: str | None = None
    named: list[str] = field(default_factory=list)
    message: str | None = None
    #: per visit: the estimates of the followed set (None: the default set is followed)
    estimates: list[VisitEstimates] | None = None
    diagnose_wall_s: float = 0.0

    @property
    def switched(self) -> bool:
        return self.estimates is not None

    def as_dict(self, hours: Sequence[float]) -> dict[str, Any]:  # health.json's ``followed`` (JSON at the edge)
        d = self.diagnosed_visit
        return {"free": list(self.free), "effects": list(self.effects), "switched": self.switched,
                "diagnosed_visit_hours": None if d is None else float(hours[d]), "trigger": self.trigger,
                "named": self.named, "diagnose_message": self.message, "diagnose_wall_s": self.diagnose_wall_s,
                "why": why_sentence(self, hours)}


def why_sentence(f: Followed, hours: Sequence[float]) -> str:
    """What was re-estimated at each visit and why, in words."""
    default = ", ".join(DEFAULT_FREE)
    if f.diagnosed_visit is None:
        return (f"re-estimated {default} at every visit: the default fit explained each visit (held-out residual "
                "within the noise, no estimate at its fit bound)")
    at = f"{hours[f.diagnosed_visit]:g} h"
    named = ", ".join(f.named) if f.named else "nothing"
    if not f.switched:
        return (f"re-estimated {default} at every visit; at {at} {f.trigger}, so shm diagnose was asked (against "
                f"the first visit's fitted set): it named {named}, which the default set already covers")
    return (f"at {at} {f.trigger}; shm diagnose on that visit (against the first visit's fitted set) named {named}: "
            f"every visit re-estimated with {', '.join(f.free)}"
            + (f" (added effect {', '.join(f.effects)})" if f.effects else "") + f" instead of {default}")


def follow_set(named: Sequence[str]) -> tuple[tuple[str, ...], tuple[str, ...]] | None:
    """(effects, free) to follow when diagnose named something outside the default set; None: keep the default.
    A named section stiffness replaces k3 (which stands for any section in the default set); the hysteresis
    parameters stay freed with it; an effect's parameters are freed alone (with any named core parameter)."""
    effects, free = reestimation_set(named)
    outside = [p for p in free if p not in DEFAULT_FREE]
    if not outside:
        return None
    if any(p in SECTION_STIFFNESSES for p in outside) and not effects:
        keep = tuple(p for p in DEFAULT_FREE if p not in SECTION_STIFFNESSES)
        free = tuple(dict.fromkeys([*free, *keep]))
    return effects, free


def find_and_follow(ests: Sequence[VisitEstimates], records_of: Callable[[int], Sequence[Any]], params: str,
                    reestimate: Callable[[tuple[str, ...], tuple[str, ...], dict[str, float]],
                                         list[VisitEstimates]],
                    say: Callable[[str], None] = lambda s: None) -> Followed:
    """Diagnose once, on the latest visit of ``ests`` whose default fit shows excess, and re-estimate the named
    set on every visit (``reestimate(effects, free, base)``) when it is not the default set."""
    trig = excess_trigger(ests)
    if trig is None:
        return Followed()
    idx, why = trig
    base = base_values(ests[0])
    say(f"what changed? at visit {idx + 1}: {why}; shm diagnose on it against the first visit's fitted set ...")
    d = diagnose_visit(records_of(idx), params, base)
    say(f"  shm diagnose names {', '.join(d.named) or 'nothing'} ({d.wall_s:.1f} s)")
    out = Followed(diagnosed_visit=idx, trigger=why, named=list(d.named), message=d.message,
                   diagnose_wall_s=d.wall_s)
    chosen = follow_set(d.named)
    if chosen is None:
        return out
    out.effects, out.free = chosen
    say(f"  re-estimating {', '.join(out.free)} on every visit")
    out.estimates = reestimate(out.effects, out.free, base)
    return out


def series(ests: Sequence[VisitEstimates], names: Sequence[str]) -> tuple[dict[str, np.ndarray],
                                                                          dict[str, np.ndarray]]:
    """Per parameter: the visits' values and standard errors — relative change from the estimate's nominal value
    (the parameter set's) for a core parameter, the value itself (SI) for an added effect's."""
    y: dict[str, list[float]] = {n: [] for n in names}
    s: dict[str, list[float]] = {n: [] for n in names}
    for e in ests:
        for n in names:
            x = e.parameter(n)
            se = x.stderr if x.stderr is not None else float("nan")
            if effect_of(n) is not None:
                y[n].append(float(x.value))
                s[n].append(float(se))
            else:
                y[n].append(float(x.value) / x.nominal - 1.0)
                s[n].append(float(se) / abs(x.nominal))
    return {n: np.array(v) for n, v in y.items()}, {n: np.array(v) for n, v in s.items()}


def floor_of(name: str) -> float:
    eff = effect_of(name)
    return EFFECT_PARAMETERS[eff][name]["floor"] if eff is not None else SIGMA_FLOOR


def trends_upto(hours: Sequence[float] | np.ndarray, y: Mapping[str, np.ndarray], s: Mapping[str, np.ndarray], upto: int
                ) -> dict[str, Trend]:
    """Each parameter's trend from the first ``upto`` visits."""
    h = np.asarray(hours, float)[:upto]
    return {n: fit_trend(n, h, y[n][:upto], s[n][:upto], floor=floor_of(n)) for n in y}


def effect_limits(params: str, names: Sequence[str]) -> dict[str, float]:
    """The monitor's trip limit of each added effect's parameter among ``names`` (SI)."""
    from studies.health.trip import effect_trip_limit

    out = {}
    for n in names:
        eff = effect_of(n)
        if eff is not None:
            out[n] = effect_trip_limit(params, eff, n, EFFECT_PARAMETERS[eff][n]["upper"])
    return out
