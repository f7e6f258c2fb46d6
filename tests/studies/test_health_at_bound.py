"""Results at the bound of a fit's range are said to be so (issue 27, point 3: localisation printed "k2 alone:
+200.00 %" at its bound without saying so)."""

from __future__ import annotations

from studies.health.estimate import VisitParameter
from studies.health.locate import LocationCandidate, at_bound_note, location_sentence


def _cand(name: str, relative: float, rss: float, at_bound: bool) -> LocationCandidate:
    return LocationCandidate(name, "parameter", int(name[1]), rss,
                             estimate=VisitParameter(name, 1.0 + relative, None, 1.0, "N/m", at_bound))


def _loc(**kw):
    cands = [_cand("k1", -0.30, 3300.0, False), _cand("k2", 2.0, 9000.0, True), _cand("k3", -0.18, 1700.0, False)]
    loc = {"distinguishable": True, "section": 3, "parameter": "k3", "relative": -0.18, "relative_stderr": 0.004,
           "reason": "k3 alone explains the held-out data better than k1 by 1600 σ²",
           "candidates": [c.to_json() for c in cands],
           "at_bound": ["k2"], "at_bound_note": at_bound_note(cands)}
    loc.update(kw)
    return loc


def test_the_location_sentence_names_a_stiffness_at_its_bound():
    s = location_sentence(_loc())
    assert "k2 alone at +200 % stopped at the bound of the fit's range" in s and "not an estimate" in s


def test_no_bound_no_note():
    assert at_bound_note([_cand("k3", -0.1, 100.0, False)]) is None
    assert "bound" not in location_sentence(_loc(at_bound=[], at_bound_note=None))


def test_an_estimate_at_its_bound_is_said_in_how_much():
    import numpy as np

    from studies.health.assess import levels
    from studies.health.forecast import Forecast
    from studies.health.trend import fit_trend

    est = [{"name": "k3", "value": 3 * 20.0, "stderr": None, "unit": "N/m", "nominal": 20.0, "relative": 2.0,
            "at_bound": True, "verdict": "changed"}]
    doc = {"visits": [{"visit": 1, "operating_hours": 0.0, "board_verdict": None, "estimates": est}],
           "forecast": {}, "location": {"run": False}}
    trends = {"k3": fit_trend("k3", [0.0, 100.0], [2.0, 2.0], [None, None])}
    fc = Forecast(None, None, None, None, 1000.0, 0.0, 100.0, 2000.0, False, np.zeros(1), np.zeros(1),
                  np.zeros(1), False)
    lv = levels(doc, trends, fc)
    assert "k3 +200 ± ? % — at its fit bound: a limit, not an estimate" in lv.how_much


def test_a_fit_that_ended_next_to_its_bound_counts_as_at_the_bound():
    """The aging run's localisation: k1 alone ended at +200.00 % of a +200 % bound with the optimiser's flag unset."""
    from studies.health.estimate import stopped_at_bound
    from workbench.fit import ParameterEstimate

    def est(value, flag=False):
        return ParameterEstimate("k1", "N/m", "core", value, 0.1, 10.0, 60.0, flag)

    assert stopped_at_bound(est(59.9999)) and stopped_at_bound(est(10.0001)) and stopped_at_bound(est(30.0, True))
    assert not stopped_at_bound(est(59.9)) and not stopped_at_bound(est(30.0))
