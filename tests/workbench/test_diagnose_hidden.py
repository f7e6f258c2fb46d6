"""The hidden-effect challenge, a small fast subset (the full sweep is ``python -m bench --only hidden_effect``):
library effects hidden in MBIT.b records are named first and fitted down to the noise floor, wrong core parameters
are named first as re-estimations; effect-free records are "nothing missing"; the confusion matrix and the summary
count what they should; the case-kind registry takes new kinds; a pair whose greedy first pick is a mimicking
re-estimation is still found (the beam of forward selection)."""

from __future__ import annotations

import pytest

from workbench.challenges.hidden_effect import (
    CASE_KINDS,
    STRENGTHS,
    CaseResult,
    HiddenCase,
    cases_of,
    confusion_matrix,
    effect_size_sigma,
    format_confusion,
    register_case_kind,
    run_case,
    run_hidden_case,
    summarise,
    truth_label,
)

NOISE = 2e-6
CASES = [
    ("piezo_creep", STRENGTHS["piezo_creep"][1]),
    ("geometric_stiffening", STRENGTHS["geometric_stiffening"][1]),
    ("amplifier_current_limit", STRENGTHS["amplifier_current_limit"][1]),
    ("root_compliance", STRENGTHS["root_compliance"][0]),
    ("laser_sensor", STRENGTHS["laser_sensor"][0]),
]


@pytest.fixture(scope="module")
def results() -> list[CaseResult]:
    out = [run_case(effect, values, "mbit-b", NOISE, seed=3, strength="test") for effect, values in CASES]
    wrong = {c.label: c for c in cases_of("parameter")}
    out += [run_hidden_case(wrong[label], "mbit-b", NOISE, seed=3) for label in ("m3+50%", "k2-20%", "d_ep-15%")]
    out += [run_case(None, None, "mbit-b", NOISE, seed=s) for s in (21, 22)]
    return out


def test_hidden_effects_are_ranked_first_and_fitted_to_the_noise_floor(results):
    for r in results:
        if r.effect == "none" or r.case_kind != "library":
            continue
        assert r.counts, f"{r.effect}: size {r.size_sigma:.3g} σ should be above the noise in this subset"
        assert r.ranked_first, f"{r.effect} diagnosed as {r.diagnosed} (ranking {r.ranking[:3]})"
        assert r.held_after_true_sigma <= 1.5, f"{r.effect}: held-out {r.held_after_true_sigma:.3g} σ after fit"
        assert r.held_before_sigma > 1.5


def test_wrong_parameters_are_named_first_as_re_estimations(results):
    wrong = [r for r in results if r.case_kind == "parameter"]
    assert len(wrong) == 3
    for r in wrong:
        assert r.counts and r.size_sigma > 3
        assert r.verdict == "wrong_parameter" and r.found == r.expected, (r.effect, r.diagnosed)
        assert r.held_after_winner_sigma <= 1.5


def test_case_kinds_are_a_registry():
    assert {"library", "parameter", "pair"} <= set(CASE_KINDS)
    assert len(cases_of("library")) == 24 and len(cases_of("parameter")) >= 8 and len(cases_of("pair")) >= 3
    new = HiddenCase("test_kind", "x", ("dielectric_leakage",), {"G_leak": 1e-5}, ("dielectric_leakage",))
    register_case_kind("test_kind", lambda: [new])
    try:
        assert cases_of("test_kind") == [new]
    finally:
        CASE_KINDS.pop("test_kind")


def test_effect_free_records_are_nothing_missing(results):
    nulls = [r for r in results if r.effect == "none"]
    assert nulls and all(r.verdict == "nothing_missing" and r.diagnosed == "nothing missing" for r in nulls)


def test_confusion_matrix_and_summary(results):
    truths, diags, m = confusion_matrix(results)
    assert m.sum() == len(results)
    for i, t in enumerate(truths):
        j = diags.index(t if t != "none" else "nothing missing")
        assert m[i, j] == sum(1 for r in results if truth_label(r) == t)  # all on the diagonal here
    text = format_confusion(results)
    assert text.splitlines()[0].startswith("truth \\ diagnosis") and "nothing" in text
    s = summarise(results)
    assert s["ranked_first_rate"] == 1.0 and s["null_nothing_missing_rate"] == 1.0 and not s["misses"]
    assert s["parameter_named_first_rate"] == 1.0 and s["library_top1_rate"] == 1.0


def test_effect_size_is_zero_at_neutral_and_grows_with_strength():
    weak, strong = (effect_size_sigma("mbit-b", "dielectric_leakage", STRENGTHS["dielectric_leakage"][i], NOISE)
                    for i in (0, 2))
    assert 0 < weak < strong
    assert effect_size_sigma("mbit-b", "dielectric_leakage", {"G_leak": 0.0}, NOISE) == pytest.approx(0, abs=1e-3)


@pytest.mark.slow
@pytest.mark.heavy
def test_a_pair_whose_first_pick_is_a_mimicking_re_estimation_is_still_found():
    # geometric stiffening + dielectric leakage (medium) on MBIT.b, the challenge's seed: the greedy path took β_h
    # first, then the stiffness group, and stopped at 1.65 σ ("combination: beta_h + stiffness", both missed); the
    # beam's start from an effect finds the pair at the noise floor. The beam tries every library pair with the
    # first effect (13 compositions compile when cold: 235 s at load 7), so it runs in make test-slow; make test
    # keeps the beam's rule on stubbed fits (test_forward_selection.py::
    # test_a_mimicking_reestimation_taken_first_loses_to_the_true_pair) and a pair found end to end on a few
    # candidates (test_diagnose_parameters.py::test_two_missing_effects_are_found_by_forward_selection)
    case = next(c for c in cases_of("pair") if c.label == "geometric_stiffening+dielectric_leakage"
                and c.strength == "medium")
    r = run_hidden_case(case, "mbit-b", NOISE, seed=3)
    assert r.counts and r.all_found, (r.diagnosed, r.ranking[:4])
    assert set(r.found) == {"geometric_stiffening", "dielectric_leakage"}
    assert r.verdict == "combination" and r.held_after_winner_sigma <= 1.3
