"""The fit report as lmfit users expect it (issue 27.7): χ², reduced χ², AIC/BIC, variables with relative standard
errors, correlations and warnings (at a bound, not identifiable, strongly correlated) on the terminal and in
fit.json; ``--save`` is optional."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from workbench.fit import (
    FitOutcome,
    ParameterEstimate,
    fit_statistics,
    fit_warnings,
    format_report,
    other_notes,
    report_dict,
)


def _outcome(estimates: list[ParameterEstimate], corr: np.ndarray, rss: float = 420.0, n: int = 400
             ) -> FitOutcome:
    return FitOutcome(u=np.zeros(len(estimates)), estimates=estimates, correlation=corr, train_rms_sigma=1.0,
                      held_rms_sigma=1.1, train_rss=rss, held_rss=484.0, n_train=n, n_held=400, rho1_train=0.05,
                      rho1_held=0.0, history=[], sim=None, ok=True, message="", n_sims=1,  # type: ignore[arg-type]
                      wall_s=0.0)


def _est(name: str, value: float, stderr: float, at_bound: bool = False) -> ParameterEstimate:
    return ParameterEstimate(name, "N/m", "core", value, stderr, 1.0, 100.0, at_bound)


def test_statistics_follow_lmfits_definitions() -> None:
    o = _outcome([_est("k3", 20.0, 0.1), _est("m3", 5.0, 0.01)], np.eye(2))
    s = fit_statistics(o)
    assert (s.n_data, s.n_variables, s.chi_square) == (400, 2, 420.0)
    assert s.reduced_chi_square == pytest.approx(420.0 / 398)
    assert s.aic == pytest.approx(400 * math.log(420.0 / 400) + 4)
    assert s.bic == pytest.approx(400 * math.log(420.0 / 400) + 2 * math.log(400))
    assert s.held_out_reduced_chi_square == pytest.approx(484.0 / 400)


def test_warnings_name_bounds_unidentifiable_poorly_determined_and_correlated_parameters() -> None:
    corr = np.array([[1.0, 0.97, 0.2, 0.0], [0.97, 1.0, 0.05, 0.0], [0.2, 0.05, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]])
    ests = [_est("a", 1.0, 0.01, at_bound=True), _est("b", 50.0, 1.0), _est("c", 10.0, 8.0),
            _est("d", 3.0, math.inf)]
    kinds = {(w.kind, w.parameters) for w in fit_warnings(ests, corr)}
    assert kinds == {("at_bound", ("a",)), ("poorly_determined", ("c",)), ("not_identifiable", ("d",)),
                     ("correlated", ("a", "b"))}
    text = format_report(_outcome(ests, corr), initial={"a": 2.0})
    for part in ("[[Fit Statistics]]", "reduced chi-square", "Akaike info crit", "[[Variables]]",
                 "a: 1 +/- 0.01 (1.00%) (init = 2)", "(at a bound)", "(not identifiable)", "[[Correlations]]",
                 "C(a, b) = +0.9700", "C(a, c) = +0.2000", "[[Correlation matrix]]", "[[Warnings]]",
                 "lower bound"):
        assert part in text, part
    assert "C(b, c)" not in text  # below lmfit's 0.1
    assert text.index("C(a, b)") < text.index("C(a, c)")  # strongest first
    assert other_notes(["a ended at a bound of its range [1, 100] N/m: widen it", "the model does not explain"],
                       ests) == ["the model does not explain"]  # said once, under [[Warnings]]
    d = report_dict(_outcome(ests, corr))
    json.dumps(d, allow_nan=True)
    assert d["correlation_matrix"]["parameters"] == ["a", "b", "c", "d"]
    assert [w["kind"] for w in d["warnings"]].count("correlated") == 1


def test_an_interval_from_the_bootstrap_is_shown_with_its_method() -> None:
    e = _est("c3", 0.0385, 0.00067)
    e.interval_method, e.interval_low, e.interval_high = "block bootstrap", 0.0371, 0.0399
    text = format_report(_outcome([e, _est("m2", 4.0, 0.1)], np.array([[1.0, 0.54], [0.54, 1.0]])))
    assert "c3: 0.0385 +/- 0.00067 (1.74%) N/m  [1, 100] 95 % [0.0371, 0.0399]" in text
    assert "from the block bootstrap" in text and "from the Jacobian)" in text  # the correlations' source
    plain = format_report(_outcome([_est("k3", 20.0, 0.1)], np.eye(1)))
    assert "95 %" not in plain and "standard errors from the Jacobian" in plain


@pytest.mark.slow
def test_shm_fit_without_save_reports_the_fit_in_the_terminal_and_fit_json(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from shm_cli.main import main

    rec = tmp_path / "mb.csv"
    assert main(["synth", "--test", "mbit-b", "--deviation", "k3=-0.1", "--out", str(rec)]) == 0
    capsys.readouterr()
    out = tmp_path / "fit"
    assert main(["fit", str(rec), "--free", "k3", "--free", "m3", "--max-nfev", "8", "--out", str(out),
                 "--json"]) == 0
    cap = capsys.readouterr()
    doc = json.loads(cap.out)  # stdout: one JSON document
    for part in ("[[Fit Statistics]]", "chi-square", "[[Correlations]]", "C(k3, m3)", "[[Warnings]]"):
        assert part in cap.err
    rep = json.loads((out / "fit.json").read_text())
    assert rep["saved"] is None and doc["saved"] is None and not list(tmp_path.rglob("*.toml"))
    stats = rep["fit_report"]["statistics"]
    assert stats["n_variables"] == 2 and 0.7 < stats["reduced_chi_square"] < 1.5  # at the noise floor
    assert rep["fit_report"]["correlation_matrix"]["parameters"] == ["k3", "m3"]
    k3 = rep["fit_report"]["variables"][0]
    assert k3["init"] == pytest.approx(21.28) and "(init = 21.28)" in cap.err  # started at the set's value
    (w,) = [w for w in rep["fit_report"]["warnings"] if w["kind"] == "correlated"]
    assert w["parameters"] == ["k3", "m3"]  # a step cannot tell stiffness from mass
    assert "Fit statistics" in (out / "fit.html").read_text()
