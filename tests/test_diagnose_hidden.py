"""The hidden-effect challenge, a small fast subset (the full sweep is ``python -m bench --only hidden_effect``):
library effects hidden in MBIT.b records are named first and fitted down to the noise floor; effect-free records
are "nothing missing"; the confusion matrix and the summary count what they should."""

from __future__ import annotations

import pytest

from workbench.hidden_effect import (
    STRENGTHS,
    CaseResult,
    confusion_matrix,
    effect_size_sigma,
    format_confusion,
    run_case,
    summarise,
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
    out += [run_case(None, None, "mbit-b", NOISE, seed=s) for s in (21, 22)]
    return out


def test_hidden_effects_are_ranked_first_and_fitted_to_the_noise_floor(results):
    for r in results:
        if r.effect == "none":
            continue
        assert r.counts, f"{r.effect}: size {r.size_sigma:.3g} σ should be above the noise in this subset"
        assert r.ranked_first, f"{r.effect} diagnosed as {r.diagnosed} (ranking {r.ranking[:3]})"
        assert r.held_after_true_sigma <= 1.5, f"{r.effect}: held-out {r.held_after_true_sigma:.3g} σ after fit"
        assert r.held_before_sigma > 1.5


def test_effect_free_records_are_nothing_missing(results):
    nulls = [r for r in results if r.effect == "none"]
    assert nulls and all(r.verdict == "nothing_missing" and r.diagnosed == "nothing missing" for r in nulls)


def test_confusion_matrix_and_summary(results):
    truths, diags, m = confusion_matrix(results)
    assert m.sum() == len(results)
    for i, t in enumerate(truths):
        j = diags.index(t if t != "none" else "nothing missing")
        assert m[i, j] == sum(1 for r in results if r.effect == t)  # all on the diagonal in this subset
    text = format_confusion(results)
    assert text.splitlines()[0].startswith("truth \\ diagnosis") and "nothing" in text
    s = summarise(results)
    assert s["ranked_first_rate"] == 1.0 and s["null_nothing_missing_rate"] == 1.0 and not s["misses"]


def test_effect_size_is_zero_at_neutral_and_grows_with_strength():
    weak, strong = (effect_size_sigma("mbit-b", "dielectric_leakage", STRENGTHS["dielectric_leakage"][i], NOISE)
                    for i in (0, 2))
    assert 0 < weak < strong
    assert effect_size_sigma("mbit-b", "dielectric_leakage", {"G_leak": 0.0}, NOISE) == pytest.approx(0, abs=1e-3)
