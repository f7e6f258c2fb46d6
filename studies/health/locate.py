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
from typing import Any

import numpy as np

from reporting.uncertainty_text import format_percent_change
from workbench.records import Record

SECTIONS: dict[str, int] = {"k1": 1, "k2": 2, "k3": 3}
NUISANCE: tuple[str, ...] = ("alpha_h", "beta_h")
#: held-out Δ RSS (in σ² units) below which two candidates are "within noise"
MIN_DELTA_RSS = 25.0
#: ... or this share of the best candidate's held-out RSS (residual autocorrelation inflates Δ RSS's scatter)
MIN_DELTA_REL = 0.02
#: |correlation| of two stiffnesses' sensitivities above which the records cannot tell them apart
MAX_SENSITIVITY_CORR = 0.995


def _fit(recs: Sequence[Record], params: str, name: str, *, effect: bool, max_nfev: int) -> Any:
    from workbench.fit import fit_records

    if effect:
        return fit_records(recs, params, add=[name], free=list(NUISANCE), max_nfev=max_nfev)
    return fit_records(recs, params, free=[name, *NUISANCE], max_nfev=max_nfev)


def _candidate(rep: Any, name: str, kind: str) -> dict[str, Any]:
    from studies.health.estimate import stopped_at_bound

    o = rep.outcome
    est = next((e for e in o.estimates if e.name == name), None)
    out: dict[str, Any] = {"name": name, "kind": kind, "section": SECTIONS.get(name),
                           "held_rss_sigma2": float(o.held_rss), "n_held": int(o.n_held),
                           "held_rms_sigma": float(o.held_rms_sigma), "train_rms_sigma": float(o.train_rms_sigma),
                           "fit_wall_s": float(rep.wall_s)}
    if est is not None:
        nominal = float(rep.model.param_value(name))
        se = est.stderr if math.isfinite(est.stderr) else None
        out.update({"value": float(est.value), "stderr": se, "nominal": nominal, "unit": est.unit,
                    "relative": float(est.value) / nominal - 1.0,
                    "relative_stderr": (se / abs(nominal)) if se is not None else None,
                    "at_bound": stopped_at_bound(est)})
    return out


def sensitivity_correlation(rep: Any, names: Sequence[str], rel_step: float = 0.01) -> np.ndarray:
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
                    ) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """Each section stiffness (and each ``extra``) freed alone with the hysteresis pair: the fits by name and the
    candidates' JSON rows (an extra that cannot be fitted gets an ``error`` row; a section that cannot, raises)."""
    from workbench.fit import CORE_PARAMETER_NAMES

    reps: dict[str, Any] = {}
    cands: list[dict[str, Any]] = []
    for name in [*SECTIONS, *[e for e in extra if e not in SECTIONS and e not in NUISANCE]]:
        effect = name not in SECTIONS and name not in CORE_PARAMETER_NAMES
        try:
            rep = _fit(recs, params, name, effect=effect, max_nfev=max_nfev)
        except Exception as exc:  # an extra candidate that cannot be fitted is reported, not fatal
            if name in SECTIONS:
                raise
            cands.append({"name": name, "kind": "effect" if effect else "parameter", "error": str(exc)})
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


def _placement(best_k: dict[str, Any], runner: dict[str, Any], possible: list[int], corr_pair: float,
               delta: float, noise: float, sweep: str) -> dict[str, Any]:
    """The location's verdict: no loss to place, a loss the records cannot place (with the test that would), or
    the section; ``delta`` and ``noise`` are held-out RSS in σ² units."""
    rel, rse = best_k.get("relative", 0.0), best_k.get("relative_stderr") or 0.0
    if not abs(rel) > max(3 * rse, 0.02):
        return {"section": None, "parameter": None, "distinguishable": None, "relative": rel, "relative_stderr": rse,
                "reason": f"no section stiffness has moved beyond 3 standard errors or 2 % ({best_k['name']}"
                          f" alone: {100 * rel:+.1f} %)"}
    if abs(corr_pair) >= MAX_SENSITIVITY_CORR or delta <= noise:
        why = (f"the sensitivities of {best_k['name']} and {runner['name']} are correlated at {corr_pair:+.4f}"
               if abs(corr_pair) >= MAX_SENSITIVITY_CORR else
               f"the held-out scores of {best_k['name']} and {runner['name']} differ by {delta:.1f} σ² "
               f"(noise {noise:.1f} σ²)")
        others = [s for s in SECTIONS.values() if s not in possible]
        lean = (f"; the held-out score leans to section {best_k['section']} ({best_k['name']} "
                f"{100 * rel:+.0f} %) by {delta:.0f} σ² (noise {noise:.0f} σ²), which near-parallel sensitivities "
                "do not make a placement" if abs(corr_pair) >= MAX_SENSITIVITY_CORR and delta > noise else "")
        return {"section": None, "parameter": None, "distinguishable": False, "relative": rel,
                "relative_stderr": rse, "separating_test": sweep,
                "reason": f"a stiffness loss, but these records cannot tell section {best_k['section']} "
                          f"from section {runner['section']}: {why}{lean}"
                          + (f"; section {' or '.join(map(str, others))} is ruled out (clearly worse on "
                             "held-out data)" if others else "")}
    return {"section": best_k["section"], "parameter": best_k["name"], "distinguishable": True,
            "relative": rel, "relative_stderr": rse,
            "reason": f"{best_k['name']} alone explains the held-out data better than {runner['name']} "
                      f"by {delta:.0f} σ² (noise {noise:.0f} σ²; sensitivity correlation "
                      f"{corr_pair:+.3f})"}


def locate_stiffness(records: Sequence[Record], params: str, *, operating_hours: float | None = None,
                     extra: Sequence[str] = (), max_nfev: int = 30) -> dict[str, Any]:
    """Free k1, k2, k3 (and ``extra``: core parameters or effects, e.g. ``shm diagnose``'s first name) one at a time
    with α_h and β_h on one visit's records; the JSON-ready ``location`` (see docs/health.md)."""
    from studies.health.estimate import join_visit_records

    board = all(r.meta.get("provenance", {}).get("generator") == "board" for r in records)
    recs = [join_visit_records(records)] if board else list(records)
    reps, cands = _fit_candidates(recs, params, extra, max_nfev)
    scored = sorted((c for c in cands if "error" not in c), key=lambda c: c["held_rss_sigma2"])
    best = scored[0]
    stiff = [c for c in scored if c["name"] in SECTIONS]
    best_k, runner = stiff[0], stiff[1]
    corr = sensitivity_correlation(reps[best_k["name"]], list(SECTIONS))
    names = list(SECTIONS)
    corr_pair = float(corr[names.index(best_k["name"]), names.index(runner["name"])])
    delta = runner["held_rss_sigma2"] - best_k["held_rss_sigma2"]
    noise = max(MIN_DELTA_RSS, MIN_DELTA_REL * best_k["held_rss_sigma2"])
    sweep = _separating_sweep(params)
    # the sections the records rule out: clearly worse on held-out data and not (anti)parallel to the best
    possible = [best_k["section"]]
    for c in stiff[1:]:
        cc = float(corr[names.index(best_k["name"]), names.index(c["name"])])
        if not (c["held_rss_sigma2"] - best_k["held_rss_sigma2"] > noise and abs(cc) < MAX_SENSITIVITY_CORR):
            possible.append(c["section"])
    location: dict[str, Any] = {
        "possible_sections": sorted(possible),
        "operating_hours": operating_hours, "candidates": cands, "ranking": [c["name"] for c in scored],
        "sensitivity_correlation": {"names": names, "matrix": corr.tolist()},
        "delta_held_rss_sigma2": float(delta), "noise_held_rss_sigma2": float(noise),
        "correlation_best_runner_up": corr_pair, "runner_up": runner["name"], "separating_test": None,
    }
    location.update(_placement(best_k, runner, possible, corr_pair, delta, noise, sweep))
    if best["name"] not in SECTIONS:
        location["better_explained_by"] = best["name"]
    location["at_bound"] = [c["name"] for c in cands if c.get("at_bound")]
    location["at_bound_note"] = at_bound_note(cands)
    return location


def at_bound_note(cands: Sequence[dict[str, Any]]) -> str | None:
    """Words for the candidates whose fit stopped at a bound of the parameter's range (None: none did): such a
    value is where the fit was stopped, not an estimate, and its held-out score is that of a constrained fit."""
    hit = [c for c in cands if c.get("at_bound")]
    if not hit:
        return None
    parts = [f"{c['name']} alone at {100 * c['relative']:+.0f} %" if "relative" in c else c["name"] for c in hit]
    return (f"{', '.join(parts)} stopped at the bound of the fit's range: a limit, not an estimate (that "
            f"stiffness alone cannot explain the records)")


def location_sentence(loc: dict[str, Any]) -> str:
    """The "where?" sentence of a location."""
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
    from studies.health.estimate import join_visit_records
    from workbench.diagnose import diagnose

    board = all(r.meta.get("provenance", {}).get("generator") == "board" for r in records)
    recs = [join_visit_records(records)] if board else list(records)
    d = diagnose(recs, params)
    if d.found:
        return d.found[0]
    return d.ranked_names[0] if d.ranked_names else None
