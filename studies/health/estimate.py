"""Per-visit re-estimation of the health parameters from the visit's records, with standard errors.

A visit's MBIT records are consecutive ticks of one visit (MBIT.a's settle and test, then MBIT.b's), so they are
joined into one record that starts at rest — MBIT.b alone starts with the hysteresis MBIT.a left behind (about
0.09 mm of remnant tip deflection with table2), which a model started from rest cannot reproduce. The joined record
goes to the workbench's fit (:func:`workbench.fit.fit_records`, the fit API of ``shm fit``): the free parameters
(default k3, α_h, β_h — those the monitor watches) on the training blocks, standard errors from the Jacobian
inflated for residual autocorrelation. Visits are fitted in parallel on a local process pool.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from board_config.errors import InputError
from reporting.uncertainty_text import format_percent_change
from workbench.records import Record, record_from_arrays

if TYPE_CHECKING:
    from workbench.fit import ParameterEstimate

DEFAULT_FREE: tuple[str, ...] = ("k3", "alpha_h", "beta_h")
#: share of a parameter's fit range within which an estimate counts as stopped at the bound (the optimiser's own
#: flag needs 1e-6 in its internal coordinate: a fit that ends at +199.99 % of a +200 % bound escaped it)
NEAR_BOUND_SHARE = 1e-4


def stopped_at_bound(e: ParameterEstimate) -> bool:
    """True when a fit's :class:`~workbench.fit.ParameterEstimate` ended at (or next to) its range bound."""
    if e.at_bound:
        return True
    lo, hi = float(e.lower), float(e.upper)
    if not (math.isfinite(lo) and math.isfinite(hi)) or hi <= lo:
        return False
    tol = NEAR_BOUND_SHARE * (hi - lo)
    return bool(e.value - lo <= tol or hi - e.value <= tol)


@dataclass(frozen=True, slots=True)
class VisitParameter:
    """One health parameter re-estimated on one visit: ``value``, ``stderr`` and ``nominal`` in ``unit`` (SI);
    ``stderr`` None when the fit could not give one; ``nominal`` is the parameter set's value (0 for an added
    effect's parameter, which is then read in its own unit)."""

    name: str
    value: float
    stderr: float | None
    nominal: float
    unit: str
    at_bound: bool = False

    @property
    def relative(self) -> float:
        """Relative change from nominal (1; a core parameter only)."""
        return self.value / self.nominal - 1.0

    def to_json(self) -> dict[str, Any]:  # a JSON object at the edge (health.json's followed_estimates)
        return {"name": self.name, "value": self.value, "stderr": self.stderr, "nominal": self.nominal,
                "unit": self.unit, "at_bound": self.at_bound}


@dataclass(frozen=True, slots=True)
class VisitEstimates:
    """One visit's re-estimation (picklable: it crosses the process pool): the parameters and the fit's quality
    (residual rms in units of the noise σ, training and held-out blocks; wall time in s)."""

    estimates: tuple[VisitParameter, ...]
    held_rms_sigma: float
    train_rms_sigma: float
    fit_wall_s: float

    def parameter(self, name: str) -> VisitParameter:
        """The estimate of ``name`` (KeyError when it was not freed on this visit)."""
        for x in self.estimates:
            if x.name == name:
                return x
        raise KeyError(name)

    def names(self) -> list[str]:
        return [x.name for x in self.estimates]


@dataclass(frozen=True, slots=True)
class VisitTruth:
    """The truth a source carries for a visit (a simulated life or synthetic records), see :mod:`.truth`: each
    parameter's relative deviation from ``params``' nominal value (a life's log), or its SI value (a synthetic
    record's header); a parameter not named is at its nominal value."""

    params: str
    relative: dict[str, float] | None = None
    values: dict[str, float] | None = None


@dataclass
class Visit:
    """One maintenance visit as the records tell it."""

    operating_hours: float
    records: list[Record]
    visit: int | None = None
    verdict: str | None = None  # the board's verdict, when the log is at hand
    mbit_verdicts: dict[str, str] = field(default_factory=dict)
    #: the truth when the source carries it (a simulated life or synthetic records)
    truth: VisitTruth | None = None


def join_visit_records(records: Sequence[Record]) -> Record:
    """The visit's records (sorted by board time when known) as one record from rest; a single record is returned
    as is."""
    if len(records) == 1:
        return records[0]

    def board_t(r: Record) -> float:
        return float(r.meta.get("provenance", {}).get("board_time_s", 0.0))

    recs = sorted(records, key=board_t)
    rate = recs[0].sample_rate_Hz
    ts: list[np.ndarray] = []
    cols: dict[str, list[np.ndarray]] = {c: [] for c in ("v_ch1_V", "v_ch2_V", "z3_m")}
    t_next = 0.0
    for r in recs:
        t = r.t - r.t[0] + t_next
        ts.append(t)
        for c, q in (("v_ch1_V", "v_ch1"), ("v_ch2_V", "v_ch2"), ("z3_m", "z3")):
            cols[c].append(r[q])
        t_next = float(t[-1]) + 1.0 / rate
    meta = {k: v for k, v in recs[0].meta.items() if k in ("sample_rate_Hz", "terminal", "params",
                                                          "operating_hours", "channels")}
    meta.update({"test": "visit", "inputs": ["v_ch1_V", "v_ch2_V"],
                 "description": "a maintenance visit's MBIT records joined (" + ", ".join(r.name for r in recs) + ")"})
    return record_from_arrays(np.concatenate(ts), {c: np.concatenate(v) for c, v in cols.items()}, meta,
                              path="+".join(r.name for r in recs))


def estimate_visit(records: Sequence[Record], params: str, free: Sequence[str] = DEFAULT_FREE,
                   add: Sequence[str] = (), base: dict[str, float] | None = None) -> VisitEstimates:
    """Fit the free parameters on one visit: the estimates and the fit's quality.
    ``add``: effects added to the model (their parameters may be in ``free``; their nominal is the effect's
    default, usually 0); ``base``: core values (SI) replacing the set's (the first visit's fitted set)."""
    from board_config import load_parameter_set
    from plant import PlantModel
    from workbench.fit import fit_records

    board = all(r.meta.get("provenance", {}).get("generator") == "board" for r in records)
    # the board's records of a visit are consecutive ticks: joined, they start at rest; other records (shm synth,
    # a rig's logs) each start at rest and are fitted as they are
    recs = [join_visit_records(records)] if board else list(records)
    pset = load_parameter_set(params).with_values(None, **base) if base else load_parameter_set(params)
    rep = fit_records(recs, pset, add=list(add), free=list(free), max_nfev=30)
    # relative changes are against the parameter set's nominal values, not the base (the monitor's terms)
    model = PlantModel(params, terminal="amplifier", effects=list(add))
    out = tuple(VisitParameter(e.name, float(e.value), float(e.stderr) if math.isfinite(e.stderr) else None,
                               float(model.param_value(e.name)), e.unit, stopped_at_bound(e))
                for e in rep.outcome.estimates)
    return VisitEstimates(out, float(rep.outcome.held_rms_sigma), float(rep.outcome.train_rms_sigma),
                          float(rep.wall_s))


def _estimate_job(paths: list[str], params: str, free: tuple[str, ...], add: tuple[str, ...] = (),
                  base: dict[str, float] | None = None) -> VisitEstimates:
    from workbench.records import load_record

    records = []
    for p in paths:
        rec = load_record(p)
        if not isinstance(rec, Record):
            raise InputError(f"{p}: a frequency-response table cannot be used for per-visit re-estimation")
        records.append(rec)
    return estimate_visit(records, params, free, add, base)


def estimate_visits(visits: Sequence[Visit], params: str, free: Sequence[str] = DEFAULT_FREE,
                    workers: int | None = None, progress: Callable[[str], None] | None = None,
                    dask_scheduler: str | None = None, add: Sequence[str] = (),
                    base: dict[str, float] | None = None) -> list[VisitEstimates]:
    """Every visit's estimates, in visit order (process pool of ``workers``; 1 = in this process; or the Dask
    cluster at ``dask_scheduler``, as ``shm campaign --dask-scheduler``: the records are read by the workers, so
    they need the same file system)."""
    n = workers if workers is not None else min(len(visits), os.cpu_count() or 1)
    free = tuple(free)
    paths = [[str(r.path) for r in v.records] for v in visits]
    results: list[VisitEstimates] = []
    if dask_scheduler:
        from studies.campaign import connect_dask

        client = connect_dask(dask_scheduler)
        try:
            with client.get_executor() as pool:
                futs = [pool.submit(_estimate_job, p, params, free, tuple(add), base) for p in paths]
                for v, f in zip(visits, futs):
                    results.append(f.result())
                    if progress:
                        progress(_line(v, results[-1]))
        finally:
            client.close()
        return results
    if n <= 1 or len(visits) <= 1:
        for v in visits:
            results.append(estimate_visit(v.records, params, free, add, base))
            if progress:
                progress(_line(v, results[-1]))
        return results
    with ProcessPoolExecutor(max_workers=n) as pool:
        futs = [pool.submit(_estimate_job, p, params, free, tuple(add), base) for p in paths]
        for v, f in zip(visits, futs):
            results.append(f.result())
            if progress:
                progress(_line(v, results[-1]))
    return results


def _line(v: Visit, res: VisitEstimates) -> str:
    parts = []
    for e in res.estimates:
        if e.nominal == 0.0:  # an added effect's parameter: in its own unit
            se_s = f" ± {e.stderr:.2g}" if e.stderr is not None else ""
            parts.append(f"{e.name} {e.value:.3g}{se_s} {e.unit}")
            continue
        se = e.stderr / abs(e.nominal) if e.stderr is not None else None
        bound = " (at its fit bound)" if e.at_bound else ""
        parts.append(f"{e.name} {format_percent_change(e.relative, se)}{bound}")
    return (f"  visit at {v.operating_hours:8.1f} h: " + ", ".join(parts)
            + f"; held-out rms {res.held_rms_sigma:.2f} σ ({res.fit_wall_s:.1f} s)")
