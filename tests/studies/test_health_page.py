"""The health page an engineer reads, and the prognosis scored against a known truth (issue 27, points 2 and 3).

Fast: the visits' estimates are made up from a known degradation law (no fits), the trip boundary is a constant
α_h band like table2's (−9.5 %, +15 %), so every step after the re-estimation — trends, forecast, the forecast as of
every visit, the truth, the evaluation, the figures and report.html — runs for real in a second or two.
"""

from __future__ import annotations

import dataclasses
import json
import re

import numpy as np
import pytest

from studies.health.assess import assess_estimates
from studies.health.estimate import Visit, VisitEstimates, VisitParameter, VisitTruth
from studies.health.report import evaluation_text, four_levels_text, write_health_outputs
from studies.health.trip import TripBoundary
from studies.health.truth import true_first_fault

NOMINAL = {"k3": 20.0, "alpha_h": 0.5, "beta_h": 1.0}
SE = {"k3": 0.004, "alpha_h": 5e-6, "beta_h": 2.5e-4}  # relative standard errors as on the aging run


def _boundary() -> TripBoundary:
    return TripBoundary(np.array([-0.6, 0.3]), np.array([-0.6, 0.6]), np.full((2, 2), -0.095),
                        np.full((2, 2), 0.15), key="test")


def _life(n: int = 12, interval: float = 100.0, alpha_rate: float = 1.6e-4, verdicts: bool = False, seed: int = 3):
    """Visits with the truth in them (a life's log), and their estimates: truth + noise of the quoted size."""
    rng = np.random.default_rng(seed)
    visits, ests = [], []
    for i in range(n):
        h = i * interval
        truth = {"k3": -2e-4 * h, "alpha_h": alpha_rate * h, "beta_h": -1e-4 * h}
        verdict = ("FAULT" if truth["alpha_h"] >= 0.15 else "PASS") if verdicts else None
        visits.append(Visit(h, [], i + 1, verdict, {}, VisitTruth("table2", relative=truth)))
        est = []
        for name, nom in NOMINAL.items():
            rel = truth[name] + rng.normal(0.0, SE[name] + 3e-4)
            est.append(VisitParameter(name, nom * (1 + rel), SE[name] * nom, nom, ""))
        ests.append(VisitEstimates(tuple(est), 1.1, 1.0, 0.0))
    return visits, ests


@pytest.fixture(autouse=True)
def _nominal_is_the_fixtures(monkeypatch):
    """The truth is relative to table2's nominal values; here the fixtures' own nominal set stands in for it."""
    import studies.health.truth as truth

    monkeypatch.setattr(truth, "_nominal", lambda params, name: NOMINAL[name])


def _assess(n_used: int, evaluate: bool, **kw):
    visits, ests = _life(**kw)
    used, extra = visits[:n_used], []
    b = _boundary()
    ff = true_first_fault(visits, "table2", b)
    if evaluate:
        extra = [v for v in visits[n_used:] if v.operating_hours < ff.operating_hours]
    return assess_estimates(used, visits, extra, ests[: n_used + len(extra)], params="table2",
                            free=("k3", "alpha_h", "beta_h"), boundary=b, truth_ff=ff, as_of=used[-1].operating_hours,
                            seed=1, say=lambda s: None, evaluate=evaluate), ff


def test_the_page_is_a_page_not_a_json_dump(tmp_path):
    a, _ = _assess(7, evaluate=False)
    failed = write_health_outputs(a, tmp_path, four_levels_text(a))
    assert failed == {}
    page = (tmp_path / "report.html").read_text()
    assert "<style>" in page and "<pre>" not in page and '"visits":' not in page  # styled, no JSON printed
    for level in ("DETECTED?", "WHERE?", "HOW MUCH?", "HOW LONG?"):
        assert f"<h3>{level}</h3>" in page
    assert page.count("<img ") == 3  # parameters, forecast, remaining life
    assert "href='health.json'" in page and (tmp_path / "health.json").exists()
    assert "± 0.00 %" not in page and re.search(r"alpha_h</td><td><span class='num'>\+\d+\.\d{4,} ± 0\.000", page)
    # the truth the records carry is on the page (visits table and the trend table)
    assert "alpha_h truth" in page and "<th>truth</th>" in page
    doc = json.loads((tmp_path / "health.json").read_text())
    assert doc["truth"]["visits"][-1]["relative"]["alpha_h"] == pytest.approx(1.6e-4 * 600)
    assert len(doc["remaining_life"]) == 7 - 3  # one forecast as of each visit from the 4th
    assert doc["evaluation"] is None


def test_evaluate_scores_the_prognosis_against_the_truth(tmp_path):
    """α_h +1.6 % per 100 h from 0: the monitor (+15 %) trips at 1000 h; as of 600 h with --evaluate the sweep goes on
    to 900 h; α-λ at the λ points, the prognostic horizon and the relative accuracy follow ProgPy's definitions."""
    a, ff = _assess(7, evaluate=True)
    assert ff.operating_hours == 1000.0 and "trip boundary" in ff.source
    ev = a.doc["evaluation"]
    assert [p["as_of_hours"] for p in ev["predictions"]] == [300.0, 400.0, 500.0, 600.0, 700.0, 800.0, 900.0]
    assert [p["lambda"] for p in ev["alpha_lambda"]] == [0.25, 0.5, 0.75]
    t_p = ev["first_prediction_hours"]
    for p in ev["alpha_lambda"]:
        assert p["t_lambda_hours"] == pytest.approx(t_p + p["lambda"] * (1000.0 - t_p))
        assert p["prediction_hours"] >= p["t_lambda_hours"] - 1e-9  # ProgPy: at t_λ or the next prediction
    assert ev["alpha_lambda_all_met"] is True
    assert ev["prognostic_horizon_hours"] is not None and ev["prognostic_horizon_hours"] >= 300
    assert 0.8 <= ev["relative_accuracy_mean"] <= 1.0
    for r in ev["predictions"]:
        assert r["rul_true_hours"] == pytest.approx(1000.0 - r["as_of_hours"])
    text = evaluation_text(ev)
    assert "alpha-lambda (alpha 0.2, lambda 0.5" in text and "prognostic horizon" in text
    failed = write_health_outputs(a, tmp_path, four_levels_text(a) + "\n" + text)
    assert failed == {}
    page = (tmp_path / "report.html").read_text()
    assert "Prognostics scores" in page and "α-λ cone" in page and "met" in page


def test_a_bad_prognosis_is_scored_as_such(tmp_path):
    """The same life whose α_h speeds up after 600 h (trips at 800 h, not 1000 h): the predictions made on the slow
    part miss the α cone at λ = 0.5."""
    visits, ests = _life(n=12)
    for i, v in enumerate(visits):
        if v.operating_hours > 600:
            bump = 3.5e-4 * (v.operating_hours - 600)
            assert v.truth is not None and v.truth.relative is not None
            v.truth.relative["alpha_h"] += bump
            ests[i] = dataclasses.replace(ests[i], estimates=tuple(
                dataclasses.replace(x, value=x.value + bump * x.nominal) if x.name == "alpha_h" else x
                for x in ests[i].estimates))
    b = _boundary()
    ff = true_first_fault(visits, "table2", b)
    assert ff.operating_hours == 800.0
    used = visits[:5]
    extra = [v for v in visits[5:] if v.operating_hours < 800.0]
    a = assess_estimates(used, visits, extra, ests[: len(used) + len(extra)], params="table2",
                         free=("k3", "alpha_h", "beta_h"), boundary=b, truth_ff=ff, as_of=400.0, seed=1,
                         say=lambda s: None, evaluate=True)
    ev = a.doc["evaluation"]
    assert ev["alpha_lambda_all_met"] is False
    assert any(p["ok"] is False for p in ev["alpha_lambda"])


def test_the_board_verdicts_are_the_truth_when_the_log_has_them():
    visits, _ = _life(verdicts=True)
    ff = true_first_fault(visits, "table2", None)
    assert ff is not None
    assert ff.to_json() == {"visit": 11, "operating_hours": 1000.0, "source": "the board's own verdicts (usage.db)"}


def test_a_stable_laminate_gets_a_page_with_a_lower_bound(tmp_path):
    visits, ests = _life(n=6, alpha_rate=0.0)
    for i, v in enumerate(visits):  # nothing changes: the truth is nominal, the estimates scatter around it
        v.truth = VisitTruth("table2", relative={n: 0.0 for n in NOMINAL})
        ests[i] = dataclasses.replace(ests[i], estimates=tuple(
            dataclasses.replace(x, value=NOMINAL[x.name] * (1 + np.random.default_rng(int(v.operating_hours))
                                                             .normal(0, 3e-4)))
            for x in ests[i].estimates))
    b = _boundary()
    a = assess_estimates(visits, visits, [], ests, params="table2", free=("k3", "alpha_h", "beta_h"), boundary=b,
                         truth_ff=true_first_fault(visits, "table2", b), as_of=None, seed=1, say=lambda s: None)
    assert write_health_outputs(a, tmp_path, four_levels_text(a)) == {}
    page = (tmp_path / "report.html").read_text()
    assert "no date: no FAULT before" in page and "<h3>DETECTED?</h3><div class='answer'>no</div>" in page
    assert "no trend: not before" in page  # the remaining-life table


def test_the_page_counts_its_visits_in_words(tmp_path):
    """Eleven of twelve visits used: '11 visits … 1 later visit not used' (was '1 later visits')."""
    a, _ = _assess(11, evaluate=False)
    assert write_health_outputs(a, tmp_path, four_levels_text(a)) == {}
    page = (tmp_path / "report.html").read_text()
    assert "11 visits (" in page and "; 1 later visit not used" in page and "later visits" not in page
