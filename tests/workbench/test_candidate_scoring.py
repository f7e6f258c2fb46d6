"""A candidate's score and the acceptance rule without a fit (docs/workbench.md, "How a candidate is judged"):
held-out reduction ``1 − RSS/RSS_ref``; ΔBIC on held-out data ``N_eff·ln(RSS_ref/RSS) − k·ln N_eff`` with
``N_eff = N·(1 − ρ₁)/(1 + ρ₁)`` (ρ₁ clipped to [0, 0.99], N_eff at least k + 2); training AIC/BIC; accepted only
when stable, fitted, ΔBIC > 0 and the reduction reaches the margin — each condition flipped alone rejects (MC/DC).
``explained`` and ``noise_tolerance`` decide "at the noise floor"."""

from __future__ import annotations

import math
from types import SimpleNamespace

import pytest
from hypothesis import given
from hypothesis import strategies as st

from workbench.fit import CandidateResult, explained, noise_tolerance, score
from workbench.fit._candidate_fit import EXCESS_SHARE_EXPLAINED, EXPLAINED_CEILING, NOISE_TOLERANCE


def cand(held_rss: float, *, k: int = 1, n_held: int = 1000, rho: float = 0.0, train_rss: float = 50.0,
         n_train: int = 4000, stable: bool = True, status: str = "fitted") -> CandidateResult:
    o = SimpleNamespace(held_rss=held_rss, n_held=n_held, rho1_held=rho, train_rss=train_rss, n_train=n_train)
    c = CandidateResult("drag", "", "", "", [object()] * k, o, status=status)  # type: ignore[arg-type]
    c.stable = stable
    return c


def test_the_scores_by_hand():
    c = cand(100.0, k=2, n_held=1000, rho=0.0, train_rss=40.0, n_train=4000)
    score(c, rss_ref=400.0, min_reduction=0.02)
    assert c.n_eff_held == 1000.0
    assert c.held_reduction == pytest.approx(0.75)
    assert c.delta_bic_held == pytest.approx(1000 * math.log(4.0) - 2 * math.log(1000))
    ll = 4000 * math.log(40.0 / 4000)
    assert c.aic_train == pytest.approx(ll + 4) and c.bic_train == pytest.approx(ll + 2 * math.log(4000))
    assert c.accepted


def test_correlated_held_out_samples_count_less():
    c = cand(100.0, rho=0.5)
    score(c, 400.0, 0.02)
    assert c.n_eff_held == pytest.approx(1000 * 0.5 / 1.5)
    assert c.delta_bic_held == pytest.approx(c.n_eff_held * math.log(4.0) - math.log(c.n_eff_held))
    # ρ₁ below 0 counts as 0, above 0.99 as 0.99; N_eff never below k + 2
    neg, high = cand(100.0, rho=-0.4), cand(100.0, rho=0.999, k=3)
    score(neg, 400.0, 0.02)
    score(high, 400.0, 0.02)
    assert neg.n_eff_held == 1000.0
    assert high.n_eff_held == pytest.approx(max(1000 * 0.01 / 1.99, 5.0))
    tiny = cand(100.0, n_held=3, k=2)
    score(tiny, 400.0, 0.02)
    assert tiny.n_eff_held == 4.0


def test_parameters_counted_against_the_reference():
    """A set scored against a reference with k_ref free parameters pays only for its extra ones (never less
    than none)."""
    a, b, c = cand(100.0, k=3), cand(100.0, k=3), cand(100.0, k=1)
    score(a, 400.0, 0.02)
    score(b, 400.0, 0.02, k_ref=2)
    score(c, 400.0, 0.02, k_ref=2)
    gain = 1000 * math.log(4.0)
    assert a.delta_bic_held == pytest.approx(gain - 3 * math.log(1000))
    assert b.delta_bic_held == pytest.approx(gain - math.log(1000))
    assert c.delta_bic_held == pytest.approx(gain)
    assert c.aic_train == pytest.approx(4000 * math.log(50.0 / 4000) + 2)  # the training scores use all of free


def test_a_zero_reference_gives_no_reduction():
    c = cand(1.0)
    score(c, 0.0, 0.02)
    assert math.isnan(c.held_reduction) and c.delta_bic_held == -math.inf and not c.accepted


@pytest.mark.parametrize("flip", ["none", "unstable", "not fitted", "bic", "reduction"])
def test_each_condition_of_acceptance_matters_alone(flip):
    """Accepted = stable ∧ fitted ∧ ΔBIC_held > 0 ∧ reduction ≥ margin; flipping one condition alone rejects."""
    rss, ref, margin, k, n = 100.0, 400.0, 0.02, 1, 1000
    if flip == "bic":  # a real reduction (above the margin) that does not pay for 200 parameters
        k, rss = 200, 370.0
    if flip == "reduction":  # significant on ΔBIC but below a 50 % margin
        margin = 0.8
    c = cand(rss, k=k, n_held=n, stable=flip != "unstable",
             status="at bound, unreliable" if flip == "not fitted" else "fitted")
    score(c, ref, margin)
    assert c.accepted is (flip == "none")
    if flip == "bic":
        assert c.delta_bic_held < 0 and c.held_reduction >= margin
    if flip == "reduction":
        assert c.delta_bic_held > 0 and c.held_reduction < margin


def test_acceptance_boundaries():
    # ΔBIC exactly 0 is not accepted; the reduction exactly at the margin is
    n, k = 1000, 1
    rss_zero = 400.0 / math.exp(k * math.log(n) / n)  # ln(ref/rss)·N = k·ln N
    c = cand(rss_zero, k=k, n_held=n)
    score(c, 400.0, 0.0)
    assert c.delta_bic_held == pytest.approx(0.0, abs=1e-9)
    at_margin = cand(300.0)
    score(at_margin, 400.0, 0.25)
    assert at_margin.held_reduction == pytest.approx(0.25) and at_margin.accepted
    above = cand(300.0 + 1e-9)
    score(above, 400.0, 0.25)
    assert not above.accepted


@given(st.floats(1e-3, 1e3), st.floats(1.001, 100.0), st.integers(10, 10_000))
def test_a_smaller_residual_never_scores_worse(rss, factor, n):
    a, b = cand(rss, n_held=n), cand(rss * factor, n_held=n)
    score(a, 2e3, 0.02)
    score(b, 2e3, 0.02)
    assert a.delta_bic_held > b.delta_bic_held and a.held_reduction > b.held_reduction


def test_noise_tolerance():
    assert noise_tolerance(2000) == pytest.approx(NOISE_TOLERANCE + 3 / math.sqrt(4000))
    assert noise_tolerance(0.2) == noise_tolerance(1.0) == pytest.approx(NOISE_TOLERANCE + 3 / math.sqrt(2))
    assert noise_tolerance(100) > noise_tolerance(1000)


def test_explained_at_the_floor_or_a_tiny_share_of_a_large_excess():
    n = 2000
    tol = noise_tolerance(n)
    assert explained(1.0 + tol, 1.2, n) and not explained(1.0 + tol + 1e-6, 1.0 + tol + 1e-6, n)
    assert not explained(float("nan"), 50.0, n) and not explained(float("inf"), 50.0, n)
    # above the floor: at most EXCESS_SHARE_EXPLAINED of the baseline's excess energy, and below the ceiling
    base = 100.0
    share_limit = math.sqrt(1.0 + EXCESS_SHARE_EXPLAINED * (base ** 2 - 1.0))  # ≈ 10 σ: above the ceiling
    assert share_limit > EXPLAINED_CEILING
    assert explained(EXPLAINED_CEILING, base, n) and not explained(EXPLAINED_CEILING + 1e-9, base, n)
    base2 = 20.0  # share limit ≈ 2.23 σ, below the ceiling
    lim2 = math.sqrt(1.0 + EXCESS_SHARE_EXPLAINED * (base2 ** 2 - 1.0))
    assert explained(lim2 * (1 - 1e-9), base2, n) and not explained(lim2 * (1 + 1e-6), base2, n)
    # a baseline already at the floor has no excess to share
    assert not explained(1.0 + tol + 0.01, 1.0, n) and not explained(1.0 + tol + 0.01, 0.5, n)


def test_small_residuals_and_short_training_parts():
    """RSS in σ² units can be below 1; one training sample (or none) still gives finite training scores."""
    c = cand(0.1, train_rss=0.04, n_train=1)
    score(c, 0.4, 0.02)
    assert c.held_reduction == pytest.approx(0.75) and c.accepted
    assert c.delta_bic_held == pytest.approx(1000 * math.log(4.0) - math.log(1000))
    assert c.aic_train == pytest.approx(math.log(0.04) + 2) and c.bic_train == pytest.approx(math.log(0.04))
    empty = cand(0.1, train_rss=0.04, n_train=0)
    score(empty, 0.4, 0.02)
    assert empty.aic_train == pytest.approx(math.log(0.04) + 2)


def test_delta_bic_exactly_zero_is_not_accepted_and_a_small_positive_one_is():
    same = cand(400.0, k=1)
    score(same, 400.0, 0.0, k_ref=1)  # no extra parameter, no gain: ΔBIC = 0 exactly
    assert same.delta_bic_held == 0.0 and same.held_reduction == 0.0 and not same.accepted
    slight = cand(400.0 / math.exp(0.5 / 1000), k=1)
    score(slight, 400.0, 0.0, k_ref=1)
    assert 0.0 < slight.delta_bic_held < 1.0 and slight.accepted


def test_explained_exactly_at_the_excess_share_is_explained():
    n = 2000
    held = 1.21
    assert held > 1.0 + noise_tolerance(n)
    base = math.sqrt((held ** 2 - 1.0) / EXCESS_SHARE_EXPLAINED + 1.0)
    assert held ** 2 - 1.0 == EXCESS_SHARE_EXPLAINED * (base ** 2 - 1.0)  # exactly on the share (checked)
    assert explained(held, base, n)
    assert not explained(math.nextafter(held, 2.0), base, n)
