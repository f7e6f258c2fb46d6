"""Where is the stiffness loss? Each section stiffness freed alone on a visit's records, scored on held-out data.

The health fit frees k3 (the tip section) because the monitor watches it; a stiffness loss in section 1 or 2 would
then show up as "k3 moved". Here, on a visit (by default the latest), each of the section stiffnesses k1, k2, k3 —
and, on request, whatever ``shm diagnose``'s ranking names first — is freed **alone** together with the hysteresis
parameters α_h, β_h (they move too, and would otherwise be blamed on the stiffness), fitted on the training blocks
of the visit's records (:func:`workbench.fit.fit_records`, the API of ``shm fit``) and scored on the held-out blocks.

The section whose fit leaves the smallest held-out residual is named — only when the records can tell it from the
runner-up: its held-out residual sum of squares (σ² units) must beat the runner-up's by more than the noise allows
(:data:`MIN_DELTA_RSS` or :data:`MIN_DELTA_REL` of it, whichever is larger), and the two stiffnesses' sensitivities
(∂ response / ∂ ln k over the records) must not be (anti)parallel, |correlation| < :data:`MAX_SENSITIVITY_CORR`.
Otherwise the answer says so and names the test that would separate them: a sweep through the second mode.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from reporting.uncertainty_text import format_percent_change
from studies.health.estimate import VisitParameter, join_visit_records, stopped_at_bound
from workbench.records import Record

if TYPE_CHECKING:
    from workbench.fit import FitReport

SECTIONS: dict[str, int] = {"k1": 1, "k2": 2, "k3": 3}
NUISANCE: tuple[str, ...] = ("alpha_h", "beta_h")
#: held-out Δ RSS (in σ² units) below which two candidates are "within noise"
MIN_DELTA_RSS = 25.0
#: ... or this share of the best candidate's held-out RSS (residual autocorrelation inflates Δ RSS's scatter)
MIN_DELTA_REL = 0.02
#: |correlation| of two stiffnesses' sensitivities above which the records cannot tell them apart
MAX_SENSITIVITY_CORR = 0.995


@dataclass(frozen=True, slots=True)
class LocationCandidate:
    """One parameter (or effect) freed alone with α_h, β_h on the visit: its fit's held-out score (residual sum of
    squares in σ², over ``n_held`` samples; rms in σ; wall time in s) and its own estimate (None for an effect,
    whose parameters are not a stiffness); ``error``: why an extra candidate could not be fitted (then no score)."""

    name: str
    kind: str  # "parameter" or "effect"
    section: int | None = None
    held_rss_sigma2: float = math.nan
    n_held: int = 0
    held_rms_sigma: float = math.nan
    train_rms_sigma: float = math.nan
    fit_wall_s: float = 0.0
    estimate: VisitParameter | None = None
    error: str | None = None

    @property
    def relative(self) -> float | None:
        """The estimate's relative change from nominal (1), None without an estimate."""
        return self.estimate.relative if self.estimate is not None else None

    @property
    def at_bound(self) -> bool:
        return self.estimate is not None and self.estimate.at_bound

    def to_json(self) -> dict[str, Any]:  # a row of health.json's location.candidates (docs/health.md)
        if self.error is not None:
            return {"name": self.name, "kind": self.kind, "error": self.error}
        out: dict[str, Any] = {"name": self.name, "kind": self.kind, "section": self.section,
                               "held_rss_sigma2": self.held_rss_sigma2, "n_held": self.n_held,
                               "held_rms_sigma": self.held_rms_sigma, "train_rms_sigma": self.train_rms_sigma,
                               "fit_wall_s": self.fit_wall_s}
        e = self.estimate
        if e is not None:
            out.update({"value": e.value, "stderr": e.stderr, "nominal": e.nominal, "unit": e.unit,
                        "relative": e.relative,
                        "relative_stderr": (e.stderr / abs(e.nominal)) if e.stderr is not None else None,
                        "at_bound": e.at_bound})
        return out


@dataclass(frozen=True, slots=True)
class Placement:
    """The location's verdict: ``distinguishable`` None (no loss to place), False (a loss the records cannot
    place: ``separating_test`` names the test that would) or True (``section`` and its ``parameter``); the best
    stiffness's relative change and its standard error (1)."""

    section: int | None
    parameter: str | None
    distinguishable: bool | None
    relative: float
    relative_stderr: float
    reason: str
    separating_test: str | None = None


@dataclass(frozen=True, slots=True)
class Location:
    """Where the stiffness loss is on one visit (:func:`locate_stiffness`): the candidates by held-out score, the
    sections' sensitivity correlation, the best and runner-up's Δ held-out RSS against the noise (σ²) and the
    placement."""

    possible_sections: list[int]
    operating_hours: float | None  # h
    candidates: list[LocationCandidate]
    ranking: list[str]
    correlation_names: list[str]
    correlation: list[list[float]]
    delta_held_rss_sigma2: float
    noise_held_rss_sigma2: float
    correlation_best_runner_up: float
    runner_up: str
    placement: Placement
    better_explained_by: str | None = None

    def to_json(self) -> dict[str, Any]:  # health.json's location (docs/health.md): JSON at the edge
        p = self.placement
        out: dict[str, Any] = {
            "possible_sections": self.possible_sections, "operating_hours": self.operating_hours,
            "candidates": [c.to_json() for c in self.candidates], "ranking": self.ranking,
            "sensitivity_correlation": {"names": self.correlation_names, "matrix": self.correlation},
            "delta_held_rss_sigma2": self.delta_held_rss_sigma2, "noise_held_rss_sigma2": self.noise_held_rss_sigma2,
            "correlation_best_runner_up": self.correlation_best_runner_up, "runner_up": self.runner_up,
            "separating_test": p.separating_test, "section": p.section, "parameter": p.parameter,
            "distinguishable": p.distinguishable, "relative": p.relative, "relative_stderr": p.relative_stderr,
            "reason": p.reason}
        if self.better_explained_by is not None:
            out["better_explained_by"] = self.better_explained_by
        out["at_bound"] = [c.name for c in self.candidates if c.at_bound]
        out["at_bound_note"] = at_bound_note(self.candidates)
        return out


#: what health.json's location.history keeps of each visit's placement
HISTORY_KEYS = ("operating_hours", "section", "parameter", "distinguishable", "possible_sections", "relative",
                "relative_stderr", "ranking", "reason")


@dataclass(frozen=True, slots=True)
class LocationRun:
    """Whether the stiffness loss was placed and why: ``found`` (None: not run, ``reason`` says why not), the
    ``trigger`` that asked for it, what shm diagnose named first (with --locate-diagnose) and the earlier visits'
    placements (--locate-visits; None: not asked)."""

    reason: str | None = None
    found: Location | None = None
    trigger: str | None = None
    diagnose_named: str | None = None
    history: list[Location] | None = None

    def to_json(self) -> dict[str, Any]:  # health.json's location (docs/health.md): JSON at the edge
        if self.found is None:
            return {"run": False, "reason": self.reason}
        out = self.found.to_json() | {"run": True, "trigger": self.trigger, "diagnose_named": self.diagnose_named}
        if self.history is not None:
            rows = [h.to_json() for h in self.history]
            out["history"] = [{k: r[k] for k in HISTORY_KEYS} for r in [*rows, out]] if rows else []
        return out


def _fit(recs: Sequence[Record], params: str, name: str, *, effect: bool, max_nfev: int) -> FitReport:
    from workbench.fit import fit_records

    if effect:
        return fit_records(recs, params, add=[name], free=list(NUISANCE), max_nfev=max_nfev)
    return fit_records(recs, params, free=[name, *NUISANCE], max_nfev=max_nfev)


def _candidate(rep: FitReport, name: str, kind: str) -> LocationCandidate:
    o = rep.outcome
    est = next((e for e in o.estimates if e.name == name), None)
    mine = None if est is None else VisitParameter(
        name, float(est.value), est.stderr if math.isfinite(est.stderr) else None,
        float(rep.model.param_value(name)), est.unit, stopped_at_bound(est))
    return LocationCandidate(name, kind, SECTIONS.get(name), float(o.held_rss), int(o.n_held),
                             float(o.held_rms_sigma), float(o.train_rms_sigma), float(rep.wall_s), mine)


def sensitivity_correlation(rep: FitReport, names: Sequence[str], rel_step: float = 0.01) -> np.ndarray:
    """Correlation matrix of the response's sensitivities to ``names`` (relative steps of ``rel_step`` around the
    fit ``rep``'s optimum), over all samples of the records, in σ units."""
    from workbench.fit import Objective

    targets = rep.targets
    models = [tg.model for tg in targets]
    base = dict(rep.outcome.values)

    def resid(values: dict[str, float]) -> np.ndarray:
        obj = Objective(targets, models, [], base_values=values)
        return obj.residuals(obj.simulate(np.zeros((1, 0))), "all")[0]

    cols = []
    for n in names:
        v0 = float(base.get(n, models[0].param_value(n)))
        up, dn = dict(base), dict(base)
        up[n], dn[n] = v0 * (1 + rel_step), v0 * (1 - rel_step)
        cols.append(resid(dn) - resid(up))  # residual = measured - simulated: this is +d(response)
    S = np.array(cols)
    norms = np.linalg.norm(S, axis=1)
    norms[norms == 0] = 1.0
    S = S / norms[:, None]
    return S @ S.T


def second_mode_hz(params: str) -> float | None:
    """The nominal laminate's second natural frequency (Hz), for the test that would separate the sections."""
    try:
        from plant import PlantModel
        from plant.linear import linearise, modal_summary

        modes = modal_summary(linearise(PlantModel(params, terminal="amplifier"))).modes
        return float(modes[1]["frequency_Hz"]) if len(modes) > 1 else None
    except Exception:  # a name for the suggestion only; never fail the assessment on it
        return None


def _fit_candidates(recs: Sequence[Record], params: str, extra: Sequence[str], max_nfev: int
                    ) -> tuple[dict[str, FitReport], list[LocationCandidate]]:
    """Each section stiffness (and each ``extra``) freed alone with the hysteresis pair: the fits by name and the
    candidates (an extra that cannot be fitted gets an ``error``; a section that cannot, raises)."""
    from workbench.fit import CORE_PARAMETER_NAMES

    reps: dict[str, FitReport] = {}
    cands: list[LocationCandidate] = []
    for name in [*SECTIONS, *[e for e in extra if e not in SECTIONS and e not in NUISANCE]]:
        effect = name not in SECTIONS and name not in CORE_PARAMETER_NAMES
        try:
            rep = _fit(recs, params, name, effect=effect, max_nfev=max_nfev)
        except Exception as exc:  # an extra candidate that cannot be fitted is reported, not fatal
            if name in SECTIONS:
                raise
            cands.append(LocationCandidate(name, "effect" if effect else "parameter", error=str(exc)))
            continue
        reps[name] = rep
        cands.append(_candidate(rep, name, "effect" if effect else "parameter"))
    return reps, cands


def _separating_sweep(params: str) -> str:
    """The test that would separate two sections: a sweep through the second mode (its frequency when known)."""
    f2 = second_mode_hz(params)
    return ("a swept-sine record through the second mode"
            + (f" (about {f2:.0f} Hz with {params}; e.g. shm synth --test sweep --f0-hz 1 --f1-hz {1.5 * f2:.0f} "
               "shows what it would look like)" if f2 else "")
            + ": MBIT.a is quasi-static and MBIT.b's step rings mostly in the first mode, whose frequency every "
            "section stiffness shifts")


def _placement(best_k: LocationCandidate, runner: LocationCandidate, possible: list[int], corr_pair: float,
               delta: float, noise: float, sweep: str) -> Placement:
    """The location's verdict: no loss to place, a loss the records cannot place (with the test that would), or
    the section; ``delta`` and ``noise`` are held-out RSS in σ² units."""
    e = best_k.estimate
    rel = e.relative if e is not None else 0.0
    rse = (e.stderr / abs(e.nominal) if e.stderr is not None else None) if e is not None else None
    rse = rse or 0.0
    if not abs(rel) > max(3 * rse, 0.02):
        return Placement(None, None, None, rel, rse, f"no section stiffness has moved beyond 3 standard errors or 2 % "
                                                     f"({best_k.name} alone: {100 * rel:+.1f} %)")
    if abs(corr_pair) >= MAX_SENSITIVITY_CORR or delta <= noise:
        why = (f"the sensitivities of {best_k.name} and {runner.name} are correlated at {corr_pair:+.4f}"
               if abs(corr_pair) >= MAX_SENSITIVITY_CORR else
               f"the held-out scores of {best_k.name} and {runner.name} differ by {delta:.1f} σ² "
               f"(noise {noise:.1f} σ²)")
        others = [s for s in SECTIONS.values() if s not in possible]
        lean = (f"; the held-out score leans to section {best_k.section} ({best_k.name} "
                f"{100 * rel:+.0f} %) by {delta:.0f} σ² (noise {noise:.0f} σ²), which near-parallel sensitivities "
                "do not make a placement" if abs(corr_pair) >= MAX_SENSITIVITY_CORR and delta > noise else "")
        return Placement(None, None, False, rel, rse,
                         f"a stiffness loss, but these records cannot tell section {best_k.section} "
                         f"from section {runner.section}: {why}{lean}"
                         + (f"; section {' or '.join(map(str, others))} is ruled out (clearly worse on "
                            "held-out data)" if others else ""), separating_test=sweep)
    return Placement(best_k.section, best_k.name, True, rel, rse,
                     f"{best_k.name} alone explains the held-out data better than {runner.name} "
                     f"by {delta:.0f} σ² (noise {noise:.0f} σ²; sensitivity correlation {corr_pair:+.3f})")


def locate_stiffness(records: Sequence[Record], params: str, *, operating_hours: float | None = None,
                     extra: Sequence[str] = (), max_nfev: int = 30) -> Location:
    """Free k1, k2, k3 (and ``extra``: core parameters or effects, e.g. ``shm diagnose``'s first name) one at a time
    with α_h and β_h on one visit's records; :meth:`Location.to_json` is health.json's ``location``
    (docs/health.md)."""
    board = all(r.meta.get("provenance", {}).get("generator") == "board" for r in records)
    recs = [join_visit_records(records)] if board else list(records)
    reps, cands = _fit_candidates(recs, params, extra, max_nfev)
    scored = sorted((c for c in cands if c.error is None), key=lambda c: c.held_rss_sigma2)
    best = scored[0]
    stiff = [c for c in scored if c.name in SECTIONS]
    best_k, runner = stiff[0], stiff[1]
    corr = sensitivity_correlation(reps[best_k.name], list(SECTIONS))
    names = list(SECTIONS)
    corr_pair = float(corr[names.index(best_k.name), names.index(runner.name)])
    delta = runner.held_rss_sigma2 - best_k.held_rss_sigma2
    noise = max(MIN_DELTA_RSS, MIN_DELTA_REL * best_k.held_rss_sigma2)
    sweep = _separating_sweep(params)
    # the sections the records rule out: clearly worse on held-out data and not (anti)parallel to the best
    possible = [SECTIONS[best_k.name]]
    for c in stiff[1:]:
        cc = float(corr[names.index(best_k.name), names.index(c.name)])
        if not (c.held_rss_sigma2 - best_k.held_rss_sigma2 > noise and abs(cc) < MAX_SENSITIVITY_CORR):
            possible.append(SECTIONS[c.name])
    return Location(sorted(possible), operating_hours, cands, [c.name for c in scored], names, corr.tolist(),
                    float(delta), float(noise), corr_pair, runner.name,
                    _placement(best_k, runner, possible, corr_pair, delta, noise, sweep),
                    better_explained_by=best.name if best.name not in SECTIONS else None)


def at_bound_note(cands: Sequence[LocationCandidate]) -> str | None:
    """Words for the candidates whose fit stopped at a bound of the parameter's range (None: none did): such a
    value is where the fit was stopped, not an estimate, and its held-out score is that of a constrained fit."""
    hit = [c for c in cands if c.at_bound]
    if not hit:
        return None
    parts = [f"{c.name} alone at {100 * rel:+.0f} %" if (rel := c.relative) is not None else c.name for c in hit]
    return (f"{', '.join(parts)} stopped at the bound of the fit's range: a limit, not an estimate (that "
            f"stiffness alone cannot explain the records)")


def location_sentence(loc: dict[str, Any]) -> str:
    """The "where?" sentence of a location as health.json holds it (:meth:`Location.to_json`, read back by the
    levels and the page: the JSON document)."""
    if loc.get("distinguishable") is None:
        s = f"no stiffness loss to place ({loc['reason']})"
    elif loc["distinguishable"]:
        s = (f"stiffness loss in section {loc['section']} ({loc['parameter']} "
             f"{format_percent_change(loc['relative'], loc.get('relative_stderr'))}): {loc['reason']}")
    else:
        s = f"{loc['reason']}; to separate them: {loc['separating_test']}"
    if loc.get("diagnose_named"):
        s += f"; shm diagnose on this visit names {loc['diagnose_named']} first"
    if loc.get("better_explained_by"):
        s += f"; note: {loc['better_explained_by']} (named by shm diagnose) explains the held-out data better still"
    if loc.get("at_bound_note"):
        s += f"; {loc['at_bound_note']}"
    return s


def diagnose_first_name(records: Sequence[Record], params: str) -> str | None:
    """What ``shm diagnose`` names first on a visit's records (its forward selection's first, else the top of its
    ranking); None when it names nothing."""
    from workbench.diagnose import diagnose

    board = all(r.meta.get("provenance", {}).get("generator") == "board" for r in records)
    recs = [join_visit_records(records)] if board else list(records)
    d = diagnose(recs, params)
    if d.found:
        return d.found[0]
    return d.ranked_names[0] if d.ranked_names else None
