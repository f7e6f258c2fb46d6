"""The diagnosis' scoring and verdict rules without a fit (docs/workbench.md): the ranking puts accepted candidates
first, best held-out ΔBIC first, unstable or unfitted last; the winner is the best accepted candidate, except that
a re-estimation explaining the held-out data within ``PREFER_PARAMETER_WITHIN`` of the best effect wins (no new
physics needed); ``found`` lists the blamed names in the order forward selection found them."""

from __future__ import annotations

from dataclasses import dataclass

import pytest

from workbench.diagnose._pipeline import Diagnosis, choose_winner, rank_key
from workbench.fit import PREFER_PARAMETER_WITHIN


@dataclass
class Cand:
    """What the scoring reads of a fitted candidate (stands in for ``CandidateResult``)."""

    effect: str
    kind: str = "effect"
    accepted: bool = True
    stable: bool = True
    delta_bic_held: float = 0.0
    held_rss: float = 1.0
    outcome: object | None = True
    members: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        self.members = self.members or (self.effect,)


def rank(cands):
    return [c.effect for c in sorted(cands, key=rank_key)]


def test_ranking_accepted_first_then_best_held_out_bic():
    cands = [Cand("rejected_big", accepted=False, delta_bic_held=100.0), Cand("small", delta_bic_held=5.0),
             Cand("big", delta_bic_held=50.0), Cand("unstable", stable=False, delta_bic_held=80.0),
             Cand("unfitted", outcome=None, delta_bic_held=90.0)]
    assert rank(cands) == ["big", "small", "unstable", "unfitted", "rejected_big"]
    assert rank([Cand("r2", accepted=False, delta_bic_held=1.0), Cand("r1", accepted=False, delta_bic_held=9.0)]) == \
        ["r1", "r2"]


def test_no_accepted_candidate_no_winner():
    assert choose_winner([]) is None
    assert choose_winner([Cand("a", accepted=False), Cand("p", kind="parameter", accepted=False)]) is None


def test_the_best_accepted_candidate_wins():
    best = Cand("drag", held_rss=1.0)
    assert choose_winner([Cand("x", accepted=False), best, Cand("y")]) is best
    par = Cand("k3", kind="parameter", held_rss=0.5)
    assert choose_winner([par, best]) is par  # a re-estimation ranked first simply wins


@pytest.mark.parametrize(("ratio", "param_wins"), [(1.0, True), (PREFER_PARAMETER_WITHIN, True),
                                                   (PREFER_PARAMETER_WITHIN * 1.001, False), (3.0, False)])
def test_a_reestimation_close_to_the_best_effect_wins(ratio, param_wins):
    assert PREFER_PARAMETER_WITHIN == pytest.approx(1.10)
    best = Cand("drag", held_rss=2.0)
    par = Cand("k3", kind="parameter", held_rss=2.0 * ratio)
    later = Cand("d_ep", kind="parameter", held_rss=0.1)
    got = choose_winner([best, Cand("other", held_rss=2.5), par, later])
    assert got is (par if param_wins else best)
    # a rejected re-estimation never wins; a combination is not a re-estimation
    assert choose_winner([best, Cand("k3", kind="parameter", accepted=False, held_rss=1.0)]) is best
    assert choose_winner([best, Cand("a + b", kind="combination", held_rss=1.0)]) is best


def _diagnosis(winner, steps=(), ranking=()):
    return Diagnosis(verdict="missing", message="", winner=winner, ranking=list(ranking),
                     baseline_train_rms_sigma=1.0, baseline_held_rms_sigma=1.0, baseline_channels=[],
                     where_it_fails=[], tests_before=[], tests_after=[], targets=[], baseline_sim=None,
                     params_name="table2", timings={}, steps=list(steps))


def test_found_lists_the_blamed_names_in_forward_selection_order():
    win = Cand("drag + creep", kind="combination", members=("drag", "creep"))
    steps = [Cand("creep"), Cand("creep + k3", kind="combination", members=("creep", "k3"))]
    d = _diagnosis(win, steps, ranking=[win, *steps])
    assert d.found == ("creep", "drag")  # k3 was tried but is not in the winner
    assert d.ranked_names == ["drag + creep", "creep", "creep + k3"]
    assert _diagnosis(None, steps).found == ()
    assert _diagnosis(Cand("drag")).found == ("drag",)


@dataclass
class _Rec:
    name: str
    test: str


@dataclass
class _Tg:
    """What ``Diagnosis.to_dict`` reads of a prepared record (stands in for ``fit_targets.Target``)."""

    record: _Rec
    t: object
    train: object
    held: object
    channels: tuple[str, ...]
    sigma: object
    sigma_source: tuple[str, ...]

    @property
    def name(self) -> str:
        return self.record.name


class _DictCand(Cand):
    def to_dict(self) -> dict:
        return {"effect": self.effect, "kind": self.kind}


def test_to_dict_is_the_json_document_diagnose_prints():
    """``shm diagnose --json``'s document: every field under its documented key, the winner's name and kind, the
    blamed names, the baseline scores per channel (with RMS in σ), the records' split sizes and noise levels."""
    import json

    import numpy as np

    from workbench.compare import residual_tests
    from workbench.fit import ChannelScore

    win = _DictCand("drag + creep", kind="combination", members=("drag", "creep"))
    step = _DictCand("creep")
    ch = ChannelScore(record="r1", channel="y_laser", unit="m", part="held", n=400, rms=6e-6, sigma=2e-6,
                      fit_pct=90.0)
    t = np.arange(10) * 1e-3
    tg = _Tg(_Rec("r1", "MBIT.b"), t, np.arange(10) < 7, np.arange(10) >= 7, ("y_laser",), np.array([2e-6]),
             ("record",))
    rng = np.random.default_rng(0)
    drive = np.sin(np.arange(500) * 0.05)
    white = residual_tests(rng.normal(size=500), drive, channel="y_laser", input_name="v", max_lag=10)
    biased = residual_tests(rng.normal(size=500) + 3.0, drive, channel="y_laser", input_name="v", max_lag=10)
    d = Diagnosis(verdict="combination", message="drag and creep", winner=win, ranking=[win, step],
                  baseline_train_rms_sigma=3.5, baseline_held_rms_sigma=4.5, baseline_channels=[ch],
                  where_it_fails=["mode 1"], tests_before=[biased], tests_after=[white], targets=[tg],
                  baseline_sim=None, params_name="table2", timings={"total_s": 1.5}, notes=["a note"],
                  steps=[step, win], identifiability=["k3 ~ m3"], fit_command="shm fit …",
                  next_command="shm discover …",
                  term_shares={"drag": 0.7, "creep": 0.3}, without_sigma={"drag": 3.0, "creep": 1.4},
                  selection_paths=["greedy: creep → drag"])
    doc = d.to_dict()
    json.dumps(doc)  # plain JSON values only
    assert doc["verdict"] == "combination" and doc["message"] == "drag and creep"
    assert doc["winner"] == "drag + creep" and doc["winner_kind"] == "combination"
    assert doc["found"] == ["creep", "drag"]
    assert doc["fit_command"] == "shm fit …" and doc["next_command"] == "shm discover …"
    assert doc["identifiability"] == ["k3 ~ m3"]
    assert doc["ranking"] == [{"effect": "drag + creep", "kind": "combination"}, {"effect": "creep", "kind": "effect"}]
    assert doc["forward_selection"] == [{"effect": "creep", "kind": "effect"},
                                        {"effect": "drag + creep", "kind": "combination"}]
    assert doc["term_shares"] == {"drag": 0.7, "creep": 0.3}
    assert doc["held_rms_sigma_without"] == {"drag": 3.0, "creep": 1.4}
    assert doc["selection_paths"] == ["greedy: creep → drag"]
    base = doc["baseline"]
    assert base["params"] == "table2" and base["train_rms_sigma"] == 3.5 and base["held_rms_sigma"] == 4.5
    assert base["channels"] == [{"record": "r1", "channel": "y_laser", "unit": "m", "part": "held", "n": 400,
                                 "rms": 6e-6, "sigma": 2e-6, "fit_pct": 90.0, "rms_sigma": pytest.approx(3.0)}]
    assert doc["where_it_fails"] == ["mode 1"]
    before, after = doc["residual_tests_before"], doc["residual_tests_after"]
    assert before[0]["channel"] == "y_laser" and before[0]["input"] == "v"
    assert before[0]["adequate"] is False and "bias" in before[0]["failed"]
    assert before[0]["tests"]["bias"] == {"verdict": biased.tests[0].verdict, "ratio": biased.tests[0].ratio}
    assert set(before[0]["tests"]) == {x.key for x in biased.tests}
    assert after[0]["adequate"] is True and after[0]["failed"] == []
    assert doc["records"] == [{"name": "r1", "test": "MBIT.b", "samples_used": 10, "train_samples": 7,
                               "held_samples": 3, "channels": ["y_laser"], "noise_sigma": [2e-6],
                               "noise_source": ["record"]}]
    assert doc["timings_s"] == {"total_s": 1.5} and doc["notes"] == ["a note"]
    # no winner: no name, no kind, nothing blamed
    empty = _diagnosis(None).to_dict()
    assert empty["winner"] is None and empty["winner_kind"] is None and empty["found"] == []


@pytest.mark.parametrize(("winner_kind", "explained", "base_held", "kind"), [
    (None, False, 1.0, "nothing_missing"),
    (None, True, 1.25, "nothing_missing"),  # at AT_NOISE_FLOOR exactly: still nothing missing
    (None, False, 1.2500001, "unexplained"),
    (None, False, 400.0, "unexplained"),
    ("parameter", True, 50.0, "wrong_parameter"),
    ("effect", True, 50.0, "missing"),
    ("combination", True, 50.0, "combination"),
    ("parameter", False, 50.0, "partial"),
    ("effect", False, 50.0, "partial"),
    ("combination", False, 50.0, "partial"),
    ("effect", True, 1.0, "missing"),  # a winner decides whatever the baseline
])
def test_the_verdict_kind(winner_kind, explained, base_held, kind):
    """docs/workbench.md's verdict kinds: no winner → nothing missing (nominal at the floor) or unexplained; a winner
    that leaves more than noise → partial; else wrong parameter / missing effect / combination by its kind."""
    from workbench.diagnose._verdict import verdict_kind
    from workbench.fit import AT_NOISE_FLOOR

    assert AT_NOISE_FLOOR == 1.25
    assert verdict_kind(winner_kind, explained, base_held) == kind
