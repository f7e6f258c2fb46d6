"""The fit report as lmfit users read it: statistics, variables, correlations and warnings of a ``shm fit``.

The layout follows lmfit's ``fit_report``::

    [[Fit Statistics]]
        # data points      = 2000         (training samples × channels)
        # variables        = 2
        chi-square         = 2003.1       (Σ r², r = (measured − model) / σ)
        reduced chi-square = 1.0026       (χ² / (N − k): ≈ 1 when what is left is noise)
        Akaike info crit   = 9.1
        Bayesian info crit = 20.3
    [[Variables]]
        k3:  17.02 +/- 0.051 (0.30%) (init = 21.28) N/m  [10, 40]
    [[Correlations]] (unreported correlations are < 0.100)
        C(k3, m3) = -0.962
    [[Warnings]]
        ...

The residuals are measured − simulated divided by each channel's noise level σ (:mod:`workbench.fit`), so the
chi-square is a true χ² when σ is right, and AIC/BIC use lmfit's forms ``N ln(χ²/N) + 2k`` and
``N ln(χ²/N) + k ln N``. The standard errors are those the fit reports (the Jacobian's, inflated for the residual's
lag-1 autocorrelation; or a block bootstrap's when the estimate says so — its interval is shown).

Warnings name a parameter at a bound of its range, one the records do not identify (infinite standard error), one
they barely determine (relative standard error above :data:`POORLY_DETERMINED`) and pairs correlated above
:data:`STRONGLY_CORRELATED` — the data cannot tell them apart. Pure logic: a fit outcome in, text and a JSON-able
mapping out.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from workbench.fit._optimiser import FitOutcome, ParameterEstimate

#: pairs shown under [[Correlations]] (lmfit's ``min_correl``)
MIN_CORRELATION = 0.1
#: |correlation| above which a pair is flagged: the records cannot separate the two
STRONGLY_CORRELATED = 0.95
#: relative standard error above which a parameter is flagged as barely determined
POORLY_DETERMINED = 0.5


@dataclass(frozen=True)
class FitStatistics:
    """lmfit's [[Fit Statistics]] of the training part, plus the held-out part's reduced chi-square."""

    n_data: int
    n_variables: int
    chi_square: float
    reduced_chi_square: float
    aic: float
    bic: float
    held_out_n: int
    held_out_reduced_chi_square: float  # χ²/N on held-out samples (no parameters were fitted there)
    residual_lag1: float  # lag-1 autocorrelation of the training residual (0 for white noise)


@dataclass(frozen=True)
class FitWarning:
    kind: str  # "at_bound" | "not_identifiable" | "poorly_determined" | "correlated"
    parameters: tuple[str, ...]
    message: str


def fit_statistics(outcome: FitOutcome) -> FitStatistics:
    """χ², reduced χ², AIC and BIC of the training residual (σ units) and held-out χ²/N (lmfit's definitions)."""
    n, k = outcome.n_train, len(outcome.estimates)
    chi2 = float(outcome.train_rss)
    nfree = n - k
    red = chi2 / nfree if nfree > 0 else math.nan
    if n > 0 and chi2 > 0:
        base = n * math.log(chi2 / n)
        aic, bic = base + 2 * k, base + k * math.log(n)
    else:
        aic = bic = -math.inf if n > 0 else math.nan
    held = float(outcome.held_rss) / outcome.n_held if outcome.n_held > 0 else math.nan
    return FitStatistics(n, k, chi2, red, aic, bic, int(outcome.n_held), held, float(outcome.rho1_train))


def correlated_pairs(names: Sequence[str], corr: np.ndarray, min_abs: float = MIN_CORRELATION
                     ) -> list[tuple[str, str, float]]:
    """(a, b, correlation) of every pair with |correlation| ≥ ``min_abs``, strongest first (finite values only)."""
    out = []
    for i in range(len(names)):
        for j in range(i + 1, len(names)):
            c = float(corr[i, j])
            if math.isfinite(c) and abs(c) >= min_abs:
                out.append((names[i], names[j], c))
    return sorted(out, key=lambda x: -abs(x[2]))


def _bound_side(e: ParameterEstimate) -> str:
    return "lower" if abs(e.value - e.lower) <= abs(e.upper - e.value) else "upper"


def fit_warnings(estimates: Sequence[ParameterEstimate], corr: np.ndarray) -> list[FitWarning]:
    """What a reader must not miss about the estimates (see the module docstring)."""
    out = []
    for e in estimates:
        if e.at_bound:
            side = _bound_side(e)
            out.append(FitWarning("at_bound", (e.name,), f"{e.name} is at the {side} bound of its range "
                                  f"[{e.lower:g}, {e.upper:g}] {e.unit}: the optimum may lie outside it, and its "
                                  f"standard error does not describe that; widen it with --free "
                                  f"{e.name}:LOWER:UPPER if the physics allows"))
        if not math.isfinite(e.stderr):
            out.append(FitWarning("not_identifiable", (e.name,), f"{e.name} is not identifiable from these records: "
                                  "changing it does not change the fit (or another free parameter does the same), "
                                  "so no standard error exists; fix it or add a test that excites it"))
        elif e.value != 0 and e.stderr / abs(e.value) > POORLY_DETERMINED:
            out.append(FitWarning("poorly_determined", (e.name,), f"{e.name} is barely determined: relative "
                                  f"standard error {100 * e.stderr / abs(e.value):.0f} % "
                                  f"(> {100 * POORLY_DETERMINED:.0f} %)"))
    names = [e.name for e in estimates]
    for a, b, c in correlated_pairs(names, corr, STRONGLY_CORRELATED):
        out.append(FitWarning("correlated", (a, b), f"{a} and {b} are correlated {c:+.4f}: these records barely "
                              "separate them (a change of one is mimicked by the other); free one of them only, or "
                              "add a test that separates them"))
    return out


def other_notes(notes: Sequence[str], estimates: Sequence[ParameterEstimate]) -> list[str]:
    """The fit's notes without those [[Warnings]] already gives (a parameter that ended at a bound)."""
    said = tuple(f"{e.name} ended at a bound" for e in estimates if e.at_bound)
    return [n for n in notes if not n.startswith(said)] if said else list(notes)


def _interval(e: ParameterEstimate) -> tuple[str, float, float]:
    """(method, low, high) of the estimate's 95 % interval (value ± 1.96 s.e. unless the fit says otherwise)."""
    return e.interval_method, float(e.interval_low), float(e.interval_high)


def _sig(x: float, digits: int = 5) -> str:
    return f"{x:.{digits}g}" if math.isfinite(x) else ("inf" if x > 0 else "-inf" if x < 0 else "nan")


def variable_rows(estimates: Sequence[ParameterEstimate], initial: Mapping[str, float] | None
                  ) -> list[dict[str, Any]]:
    rows = []
    for e in estimates:
        method, low, high = _interval(e)
        rel = e.stderr / abs(e.value) if e.value != 0 and math.isfinite(e.stderr) else math.inf
        rows.append({"name": e.name, "value": e.value, "stderr": e.stderr, "relative_stderr": rel,
                     "init": None if initial is None else initial.get(e.name), "unit": e.unit, "owner": e.owner,
                     "lower": e.lower, "upper": e.upper, "at_bound": e.at_bound,
                     "interval_method": method, "interval_95": [low, high]})
    return rows


def report_dict(outcome: FitOutcome, initial: Mapping[str, float] | None = None) -> dict[str, Any]:
    """The report as JSON-able data (for fit.json)."""
    names = [e.name for e in outcome.estimates]
    stats = fit_statistics(outcome)
    return {
        "statistics": asdict(stats),
        "variables": variable_rows(outcome.estimates, initial),
        "correlation_matrix": {"parameters": names, "matrix": np.asarray(outcome.correlation).tolist(),
                               "source": "the Jacobian at the optimum"},
        "correlations": [{"a": a, "b": b, "correlation": c}
                         for a, b, c in correlated_pairs(names, outcome.correlation)],
        "warnings": [asdict(w) | {"parameters": list(w.parameters)}
                     for w in fit_warnings(outcome.estimates, outcome.correlation)],
    }


def format_report(outcome: FitOutcome, initial: Mapping[str, float] | None = None) -> str:
    """lmfit-style text of the fit (see the module docstring)."""
    s = fit_statistics(outcome)
    lines = ["[[Fit Statistics]]",
             f"    # data points      = {s.n_data:<12d} (training samples × channels)",
             f"    # variables        = {s.n_variables}",
             f"    chi-square         = {_sig(s.chi_square, 6):<12} (Σ r², r = (measured − model)/σ of the channel)",
             f"    reduced chi-square = {_sig(s.reduced_chi_square, 6):<12} (≈ 1 when what is left is noise)",
             f"    Akaike info crit   = {_sig(s.aic, 6)}",
             f"    Bayesian info crit = {_sig(s.bic, 6)}",
             f"    held-out χ²/N      = {_sig(s.held_out_reduced_chi_square, 6):<12} ({s.held_out_n} samples not "
             "fitted)",
             f"    residual lag-1 ρ   = {s.residual_lag1:.3f}"]
    lines.append("[[Variables]]")
    rows = variable_rows(outcome.estimates, initial)
    width = max((len(r["name"]) for r in rows), default=0) + 1
    methods = set()
    for r in rows:
        se = (f"+/- {_sig(r['stderr'], 3)} ({100 * r['relative_stderr']:.2f}%)"
              if math.isfinite(r["stderr"]) and math.isfinite(r["relative_stderr"]) else
              "+/- " + _sig(r["stderr"], 3) if math.isfinite(r["stderr"]) else "(not identifiable)")
        init = f" (init = {_sig(r['init'])})" if r["init"] is not None else ""
        bound = " (at a bound)" if r["at_bound"] else ""
        interval = ""
        if r["interval_method"] != "jacobian":
            methods.add(r["interval_method"])
            lo, hi = r["interval_95"]
            interval = f" 95 % [{_sig(lo)}, {_sig(hi)}]"
        lines.append(f"    {(r['name'] + ':').ljust(width)} {_sig(r['value'])} {se}{init} {r['unit']}"
                     f"  [{_sig(r['lower'], 4)}, {_sig(r['upper'], 4)}]{interval}{bound}")
    if methods:
        lines.append(f"    (standard errors and 95 % intervals from the {', '.join(sorted(methods))})")
    else:
        lines.append("    (standard errors from the Jacobian at the optimum, inflated for the residual's lag-1 "
                     "autocorrelation)")
    names = [e.name for e in outcome.estimates]
    pairs = correlated_pairs(names, outcome.correlation)
    if len(names) > 1:
        source = "; from the Jacobian" if methods else ""  # a bootstrap replaces the errors, not the correlations
        lines.append(f"[[Correlations]] (unreported correlations are < {MIN_CORRELATION:.3f}{source})")
        w = max(len(f"C({a}, {b})") for a, b, _ in pairs) if pairs else 0
        lines.extend(f"    {f'C({a}, {b})'.ljust(w)} = {c:+.4f}" for a, b, c in pairs)
        lines.append("[[Correlation matrix]]")
        cw = max(7, *(len(n) for n in names))
        lines.append("    " + " " * cw + " ".join(n.rjust(cw) for n in names))
        corr = np.asarray(outcome.correlation)
        for i, n in enumerate(names):
            lines.append("    " + n.ljust(cw) + " ".join(f"{corr[i, j]:+.3f}".rjust(cw) for j in range(len(names))))
    warns = fit_warnings(outcome.estimates, outcome.correlation)
    if warns:
        lines.append("[[Warnings]]")
        lines.extend(f"    {w.message}" for w in warns)
    return "\n".join(lines)
