"""The whole assessment behind ``shm health``: visits → estimates → trends → forecast → the four levels.

Returns one JSON-ready document (see docs/health.md for every key) plus the objects the report plots; the four
levels' words are written from that document by :mod:`.four_levels`.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from board_config.errors import InputError
from studies.batch.runner import counted
from studies.health.cause import effect_of
from studies.health.estimate import DEFAULT_FREE, Visit, VisitEstimates, VisitParameter, estimate_visits
from studies.health.evaluate import (
    ALPHA,
    LAMBDAS,
    MIN_VISITS,
    SweepPrediction,
    evaluate_sweep,
    sweep_predictions,
)
from studies.health.follow import Followed, effect_limits, find_and_follow, series, trends_upto
from studies.health.forecast import Forecast, forecast_trip, visit_of
from studies.health.four_levels import levels, unit_of
from studies.health.locate import SECTIONS, LocationRun, diagnose_first_name, locate_stiffness
from studies.health.sources import load_visits
from studies.health.trend import Trend
from studies.health.trip import HEALTH_PARAMS, TripBoundary, trip_boundary
from studies.health.truth import TrueFirstFault, true_first_fault, truth_document


@dataclass
class Assessment:
    #: the health.json document (docs/health.md): JSON at the edge, written as is
    doc: dict[str, Any]
    visits: list[Visit]
    estimates: list[VisitEstimates]
    trends: dict[str, Trend]
    forecast: Forecast
    boundary: TripBoundary
    #: the forecast rebuilt as of each visit (:func:`.evaluate.sweep_predictions`; with trip samples)
    sweep: list[SweepPrediction] = field(default_factory=list)
    #: each visit's estimates of the set diagnose named (None: the default set was followed)
    followed_estimates: list[VisitEstimates] | None = None
    #: the monitor's trip limit of each followed effect parameter (SI)
    effect_limits: dict[str, float] = field(default_factory=dict)


def assess_health(sources: Sequence[str], *, params: str = "table2", as_of: float | None = None,
                  free: Sequence[str] | None = None, workers: int | None = None, seed: int = 1,
                  progress: Callable[[str], None] | None = None, dask_scheduler: str | None = None,
                  locate: str = "auto", locate_diagnose: bool = False, locate_visits: int = 1,
                  evaluate: bool = False, alpha: float = ALPHA, lambdas: Sequence[float] = LAMBDAS,
                  follow: str = "auto") -> Assessment:
    """``follow``: "auto" (when a visit's default fit leaves more than the noise or runs to a bound, ask shm
    diagnose on the latest such visit what changed and re-estimate and trend that set on every visit,
    :mod:`.follow`) or "never"; ``locate``: "auto" (place a stiffness loss in its section when the latest visit
    shows one — a stiffness changed or trending, or a health fit leaving 1.5 × the first visit's held-out
    residual), "always" or "never";
    ``locate_diagnose`` adds what ``shm diagnose`` names first on the latest visit to the candidates;
    ``locate_visits`` > 1 also places the loss on that many visits before the latest (``location_history``);
    ``evaluate`` scores the prognosis against the truth's first FAULT over every visit before it, whatever
    ``as_of`` (:mod:`.evaluate`; the sources must carry the truth: the board's verdicts or true parameters)."""
    say = progress or (lambda s: None)
    if follow not in ("auto", "never"):
        raise InputError(f"--follow must be auto or never, got {follow!r}")
    if locate not in ("auto", "always", "never"):
        raise InputError(f"--locate must be auto, always or never, got {locate!r}")
    free = tuple(free) if free else DEFAULT_FREE
    unknown = [f for f in free if f not in HEALTH_PARAMS]
    if unknown:
        raise InputError(f"--free {unknown[0]!r}: shm health re-estimates the monitor's health parameters "
                         f"({', '.join(HEALTH_PARAMS)})")
    if locate_visits < 1:
        raise InputError(f"--locate-visits must be >= 1, got {locate_visits}")
    all_visits = load_visits(sources)
    visits = [v for v in all_visits if as_of is None or v.operating_hours <= as_of + 1e-9]
    if len(visits) < 2:
        raise InputError(f"{counted(len(visits), 'visit')} up to --as-of {as_of:g} h: a trend needs at least two "
                         f"visits (the sources hold {counted(len(all_visits), 'visit')} at "
                         + ", ".join(f"{v.operating_hours:g}" for v in all_visits[:12]) + " h)"
                         if as_of is not None else "the sources hold fewer than two visits: a trend needs two")
    say(f"shm health: {len(visits)} visits ({visits[0].operating_hours:g} … {visits[-1].operating_hours:g} h"
        + (f", as of {as_of:g} h; {counted(len(all_visits) - len(visits), 'later visit')} not used"
           if as_of is not None else "")
        + f"), re-estimating {', '.join(free)} with params {params}")
    if evaluate and not any(v.verdict for v in all_visits) and any(v.truth is None for v in all_visits):
        _evaluation_truth(None, all_visits)  # the one-line error, before any long computation
    say("trip boundary of the board's monitor (campaign machinery; computed once per parameter set, then cached)")
    boundary = trip_boundary(params)
    truth_ff = true_first_fault(all_visits, params, boundary)
    extra: list[Visit] = []
    if evaluate:
        t_eol = _evaluation_truth(truth_ff, all_visits)
        extra = [v for v in all_visits if v.operating_hours > visits[-1].operating_hours and v.operating_hours < t_eol]
        if extra:
            say(f"--evaluate: also re-estimating the {len(extra)} visits after the as-of time up to the true first "
                f"FAULT at {t_eol:g} h")
    ests_all = estimate_visits([*visits, *extra], params, free, workers=workers, progress=say,
                               dask_scheduler=dask_scheduler)
    followed = Followed()
    if follow == "auto":
        followed = find_and_follow(ests_all[: len(visits)], lambda i: visits[i].records, params,
                                   lambda eff, fr, base: estimate_visits(
                                       [*visits, *extra], params, fr, workers=workers, progress=say,
                                       dask_scheduler=dask_scheduler, add=eff, base=base), say)
    return assess_estimates(visits, all_visits, extra, ests_all, params=params, free=free, boundary=boundary,
                            truth_ff=truth_ff, as_of=as_of, seed=seed, say=say, locate=locate,
                            locate_diagnose=locate_diagnose, locate_visits=locate_visits, evaluate=evaluate,
                            alpha=alpha, lambdas=lambdas, followed=followed)


def assess_estimates(visits: list[Visit], all_visits: list[Visit], extra: list[Visit],
                     ests_all: list[VisitEstimates], *, params: str, free: Sequence[str], boundary: TripBoundary,
                     truth_ff: TrueFirstFault | None, as_of: float | None, seed: int, say: Callable[[str], None],
                     locate: str = "never", locate_diagnose: bool = False, locate_visits: int = 1,
                     evaluate: bool = False, alpha: float = ALPHA, lambdas: Sequence[float] = LAMBDAS,
                     followed: Followed | None = None) -> Assessment:
    """The assessment from the visits' estimates (``ests_all``: ``visits`` then ``extra``, the visits after the
    as-of time that only --evaluate uses): trends, forecast, the forecast as of every visit, location, truth.
    ``followed``: the set diagnose named and its estimates (:mod:`.follow`): then that set is trended."""
    followed = followed or Followed()
    ests = ests_all[: len(visits)]
    hours = [v.operating_hours for v in visits]
    t_ests = followed.estimates if followed.estimates is not None else ests_all
    t_free = followed.free if followed.switched else tuple(free)
    limits = effect_limits(params, t_free)
    y_all, s_all = series(t_ests, t_free)
    trends = trends_upto(hours, y_all, s_all, len(hours))
    interval = float(np.median(np.diff(hours))) if len(hours) > 1 else 100.0
    current = {n: trends[n].best.predict(np.array([hours[-1]]))[0] for n in t_free if n in HEALTH_PARAMS}
    fc = forecast_trip(trends, boundary, hours[-1], interval, current=current, seed=seed, effect_limits=limits)
    swept = [*visits, *extra]
    say(f"remaining life against time: the forecast rebuilt as of each visit from the {MIN_VISITS}th on "
        f"({max(len(swept) - MIN_VISITS + 1, 0)} forecasts)")
    sweep = sweep_predictions([v.operating_hours for v in swept], {n: list(v) for n, v in y_all.items()},
                              {n: list(v) for n, v in s_all.items()}, boundary, interval, seed=seed,
                              effect_limits=limits)
    location = _locate(visits, ests, trends, params, locate, locate_diagnose, say)
    if location.found is not None and locate_visits > 1:
        history = []
        for v in visits[-locate_visits:-1]:
            say(f"where? the visit at {v.operating_hours:g} h (--locate-visits)")
            history.append(locate_stiffness(v.records, params, operating_hours=v.operating_hours))
        location = replace(location, history=history)
    doc = _document(visits, all_visits, ests, trends, fc, hours, interval, as_of, params, free, location)
    doc["followed"] = followed.as_dict(hours) | {"effect_trip_limits": limits}
    if followed.estimates is not None:
        for vd, fe in zip(doc["visits"], followed.estimates):
            vd["followed_estimates"] = [x.to_json() for x in fe.estimates]
            vd["followed_held_rms_sigma"] = fe.held_rms_sigma
    doc["levels"] = levels(doc, trends, fc).to_json()
    doc["remaining_life"] = [p.to_json() for p in sweep]
    doc["truth"] = truth_document(visits, params, free, truth_ff)
    t_eol = truth_ff.operating_hours if truth_ff is not None else None  # h; assess_health checks it is known
    doc["evaluation"] = (evaluate_sweep(sweep, t_eol, alpha=alpha, lambdas=lambdas).to_json()
                         | {"truth_source": truth_ff.source, "true_first_fault_visit": truth_ff.visit}
                         if evaluate and truth_ff is not None and t_eol is not None else None)
    return Assessment(doc, visits, ests, trends, fc, boundary, sweep, followed.estimates, limits)


def _evaluation_truth(truth_ff: TrueFirstFault | None, all_visits: Sequence[Visit]) -> float:
    """The true first FAULT's hours for --evaluate, or a one-line InputError saying what is missing."""
    if truth_ff is None:
        raise InputError("--evaluate needs a life whose truth is known: these sources carry neither the board's "
                         "verdicts (a run directory of shm run or its usage.db) nor true parameters (the "
                         "provenance.truth_values of a shm synth record)")
    if truth_ff.operating_hours is None:
        raise InputError(f"--evaluate: no FAULT in the {len(all_visits)} visits (up to "
                         f"{all_visits[-1].operating_hours:g} h; truth from {truth_ff.source}): a prognosis is "
                         "scored against the first FAULT")
    t_eol = float(truth_ff.operating_hours)
    if sum(v.operating_hours < t_eol for v in all_visits) < MIN_VISITS:
        raise InputError(f"--evaluate: the first FAULT is at {t_eol:g} h, after only "
                         f"{sum(v.operating_hours < t_eol for v in all_visits)} visits; a prediction needs "
                         f"{MIN_VISITS} visits before it")
    return t_eol


def _locate_trigger(ests: list[VisitEstimates], trends: dict[str, Trend]) -> str | None:
    """Why the latest visit calls for placing a stiffness loss (None: no reason)."""
    last = ests[-1]
    for x in last.estimates:
        if x.name in SECTIONS and _est_verdict(x) == "changed":
            return f"{x.name} changed at the latest visit"
    for n, t in trends.items():
        if n in SECTIONS and t.significant:
            return f"significant {n} trend"
    first = ests[0].held_rms_sigma
    if math.isfinite(first) and last.held_rms_sigma > 1.5 * first:
        return (f"the health fit leaves {last.held_rms_sigma:.2f} σ held-out residual at the latest visit "
                f"({first:.2f} σ at the first)")
    return None


def _locate(visits: list[Visit], ests: list[VisitEstimates], trends: dict[str, Trend], params: str, mode: str,
            with_diagnose: bool, say: Callable[[str], None]) -> LocationRun:
    """Place the stiffness loss on the latest visit when ``mode`` asks for it (auto: when a trigger says so)."""
    why = _locate_trigger(ests, trends) if mode == "auto" else ("asked (--locate always)" if mode == "always"
                                                                  else None)
    if why is None:
        return LocationRun("not asked (--locate never)" if mode == "never" else
                           "no stiffness change, trend or excess residual at the latest visit (--locate always "
                           "forces it)")
    v = visits[-1]
    extra: list[str] = []
    if with_diagnose:
        say(f"where? shm diagnose on the visit at {v.operating_hours:g} h ...")
        name = diagnose_first_name(v.records, params)
        say(f"  shm diagnose names first: {name}")
        if name:
            extra.append(name)
    say(f"where? ({why}) freeing k1, k2, k3{''.join(', ' + e for e in extra if e not in SECTIONS)} one at a time "
        "with alpha_h, beta_h "
        f"on the visit at {v.operating_hours:g} h")
    found = locate_stiffness(v.records, params, operating_hours=v.operating_hours, extra=extra)
    for c in found.candidates:
        if c.error is not None:
            say(f"  {c.name}: could not be fitted ({c.error})")
        else:
            rel = f"{100 * c.relative:+.2f} %" if c.relative is not None else "effect"
            bound = " AT ITS FIT BOUND (a limit, not an estimate)" if c.at_bound else ""
            say(f"  {c.name} alone: {rel}{bound}, held-out rss {c.held_rss_sigma2:.0f} σ² ({c.fit_wall_s:.1f} s)")
    return LocationRun(found=found, trigger=why, diagnose_named=extra[0] if extra else None)


def _document(visits: list[Visit], all_visits: list[Visit], ests: list[VisitEstimates], trends: dict[str, Trend],
              fc: Forecast, hours: list[float], interval: float, as_of: float | None, params: str,
              free: Sequence[str], location: LocationRun | None = None) -> dict[str, Any]:
    """health.json (docs/health.md) from the typed results: the JSON document at the edge."""
    vis = []
    for v, e in zip(visits, ests):
        vis.append({
            "visit": v.visit, "operating_hours": v.operating_hours, "board_verdict": v.verdict,
            "mbit_verdicts": v.mbit_verdicts, "records": [str(r.path) for r in v.records],
            "held_rms_sigma": e.held_rms_sigma,
            "estimates": [{"name": x.name, "value": x.value, "stderr": x.stderr, "unit": x.unit,
                           "nominal": x.nominal, "relative": x.relative, "at_bound": x.at_bound,
                           "verdict": _est_verdict(x)} for x in e.estimates],
        })
    trend_doc = {}
    for n, t in trends.items():
        trend_doc[n] = {"model": t.model, "best_fit_model": t.best.name, "significant": t.significant,
                        "p_value": t.p_value, "rate": t.rate_per_100h(hours[-1]) / 100.0,
                        "rate_unit": "relative deviation per hour" if effect_of(n) is None else
                        f"{unit_of(n)} per hour", "rate_per_100h_pct": 100 * t.rate_per_100h(
                            hours[-1]), "information_criterion": {k: (f.ic if math.isfinite(f.ic) else None)
                                                 for k, f in t.fits.items()},
                        "model_weights": t.weights,
                        "change_point_hours": t.best.tau if t.best.name == "change_point" and t.significant
                        else None, "change_point_note": t.change_point_note,
                        "current_relative": float(t.best.predict(np.array([hours[-1]]))[0]),
                        "latest_visit_check": t.check}
    f = fc.as_dict()
    start = hours[0]
    f["visit_interval_hours"] = interval
    if fc.trip_interval_90 is not None:
        lo, hi = fc.trip_interval_90
        f["trip_visits_90"] = [_visit_number(visits, lo, start, interval), _visit_number(visits, hi, start, interval)]
        f["trip_visit"] = _visit_number(visits, fc.trip_operating_hours, start, interval)
    later = [v for v in all_visits if v.operating_hours > hours[-1]]
    first_fault = next((v for v in all_visits if v.verdict == "FAULT"), None)
    doc = {
        "params": params, "free": list(free), "as_of_hours": as_of, "visits_used": len(visits),
        "visits_later_not_used": len(later), "visits": vis, "trend": trend_doc, "forecast": f,
        "location": None if location is None else location.to_json(),
        "board_first_fault": None if first_fault is None else {"visit": first_fault.visit,
                                                               "operating_hours": first_fault.operating_hours},
    }
    doc["levels"] = levels(doc, trends, fc).to_json()
    return doc


def _visit_number(visits: list[Visit], hours: float | None, start: float, interval: float) -> int | None:
    k = visit_of(hours, start, interval)
    if k is None:
        return None
    first_no = visits[0].visit if visits[0].visit is not None else 1
    return first_no + k


def _est_verdict(x: VisitParameter) -> str:
    rel = x.relative
    se = (x.stderr or 0.0) / abs(x.nominal)
    if abs(rel) > max(3 * se, 0.02):
        return "changed"
    return "as nominal"
