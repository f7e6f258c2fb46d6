"""Combined explanations without a fit (docs/workbench.md, "Combined explanations"): when the greedy path from a
re-estimation that mimics an effect falls short of the noise floor, the beam's other starts and the swap step find
the true pair; a set without new physics still wins when it explains within ``PREFER_PARAMETER_WITHIN``; the
verdict says how much each member explains. The fits are stubbed: each path's outcome is given."""

from __future__ import annotations

import math
from types import SimpleNamespace

import pytest

import workbench.diagnose._fit_cache as fit_cache
import workbench.diagnose._forward_selection as fs
from plant.effect import registered_effects
from workbench.fit import PREFER_PARAMETER_WITHIN, CandidateResult, CandidateSpec, parameter_candidate

N = 2000
RSS0 = 400.0 ** 2 * N  # the nominal model misses the held-out data by 400 σ


def spec(*names: str) -> CandidateSpec:
    reg = registered_effects()
    return CandidateSpec(tuple(reg[n] for n in names if n in reg),
                         tuple(parameter_candidate(n) for n in names if n not in reg))


def fitted(held_sigma: float, *names: str, accepted: bool = True) -> CandidateResult:
    s = spec(*names)
    o = SimpleNamespace(held_rss=held_sigma ** 2 * N, held_rms_sigma=held_sigma, n_held=N, values={})
    c = CandidateResult(s.label, "", "", "", [object()] * len(names), o, spec=s)  # type: ignore[arg-type]
    c.stable, c.accepted, c.n_eff_held = True, accepted, float(N)
    c.held_reduction = 1 - o.held_rss / RSS0
    c.delta_bic_held = N * math.log(RSS0 / o.held_rss) - len(names) * math.log(N)
    return c


def screened(*names: str) -> CandidateResult:
    s = spec(*names)
    c = CandidateResult(s.label, "", "", "", [], None, spec=s, status="screened out", screen_train_rms_sigma=300.0)
    c.stable = True
    return c


def _stub_paths(monkeypatch, paths: dict[str, CandidateResult]) -> list[str]:
    """forward_select from a start returns paths[start label] (or the start itself); records the starts."""
    starts: list[str] = []

    def fake(start, others, base, targets, data, rss0_held, *, without=None, **kw):
        starts.append(start.effect)
        final = paths.get(start.effect, start)
        if without is not None and len(final.members) > 1:
            for m in final.members:
                rest = [x for x in final.members if x != m]
                without[m] = fitted(300.0 if m == final.members[0] else 100.0, *rest)
        return final, [start] + ([final] if final is not start else [])

    monkeypatch.setattr(fs, "forward_select", fake)
    return starts


def _select(winner, others):
    return fs.select_set(winner, others, None, [], {}, RSS0, min_reduction=0.02, threads=None, max_nfev=5, seed=0,
                         base_held=400.0)


def test_a_mimicking_reestimation_taken_first_loses_to_the_true_pair(monkeypatch):
    # sweep-like: the stiffness group mimics geometric stiffening (taken first, greedy stalls at 40 σ); the beam's
    # next start, the effect itself, leads to the pair at the noise floor
    stiffness = fitted(60.0, "stiffness")
    stiffening = fitted(80.0, "geometric_stiffening")
    leakage = fitted(200.0, "dielectric_leakage")
    pair = fitted(1.0, "geometric_stiffening", "dielectric_leakage")
    starts = _stub_paths(monkeypatch, {"stiffness": fitted(40.0, "dielectric_leakage", "stiffness"),
                                       "geometric_stiffening": pair})
    sel = _select(stiffness, [stiffening, leakage])
    assert sel.final is pair and set(sel.final.members) == {"geometric_stiffening", "dielectric_leakage"}
    assert starts == ["stiffness", "geometric_stiffening"]  # stops once a set reaches the noise floor
    assert sel.steps[0] is stiffening  # found: the effect first
    assert [label for label, _, _ in sel.tried] == starts and all(w >= 0 for _, _, w in sel.tried)
    shares = sel.shares(RSS0)
    assert set(shares) == set(pair.members) and all(0 < v <= 1 for v in shares.values())


def test_the_swap_step_replaces_a_reestimation_by_an_effect_screened_out_alone(monkeypatch):
    # geometric stiffening alone looked useless (screened out), so no path starts from it; the swap step tries it
    # in place of the stiffness group next to the leakage
    stiffness = fitted(60.0, "stiffness")
    leakage = fitted(200.0, "dielectric_leakage")
    partial = fitted(40.0, "dielectric_leakage", "stiffness")
    pair = fitted(1.0, "geometric_stiffening", "dielectric_leakage")
    _stub_paths(monkeypatch, {"stiffness": partial, "dielectric_leakage": partial})
    swaps: list[str] = []

    def fake_fit(s, *a, **kw):
        swaps.append(s.label)
        return pair if "geometric_stiffening" in s.members else fitted(50.0, *s.members)

    monkeypatch.setattr(fit_cache, "fit_spec", fake_fit)
    sel = _select(stiffness, [leakage, screened("geometric_stiffening"), screened("piezo_creep")])
    assert sel.final is pair
    assert any("geometric_stiffening" in s for s in swaps)
    assert all("stiffness" not in s.split(" + ") for s in swaps)  # the re-estimation is what is swapped out


def test_greedy_at_the_noise_floor_tries_nothing_else(monkeypatch):
    winner = fitted(3.0, "piezo_creep")
    pair = fitted(1.02, "piezo_creep", "laser_sensor")
    starts = _stub_paths(monkeypatch, {"piezo_creep": pair})
    sel = _select(winner, [fitted(5.0, "beta_h"), fitted(9.0, "laser_sensor")])
    assert sel.final is pair and starts == ["piezo_creep"]


@pytest.mark.parametrize(("ratio", "plain_wins"), [(1.0, True), (PREFER_PARAMETER_WITHIN * 0.999, True),
                                                   (PREFER_PARAMETER_WITHIN * 1.01, False)])
def test_a_set_without_new_physics_wins_within_the_margin(ratio, plain_wins):
    with_effect = fitted(2.0, "thermal_drift", "k3")
    plain = fitted(2.0 * math.sqrt(ratio), "k3", "c1")
    assert (fs.better(with_effect, plain) is plain) is plain_wins
    assert (fs.better(plain, with_effect) is plain) is plain_wins


def test_a_new_set_must_beat_the_incumbent_clearly():
    a = fitted(3.0, "laser_sensor", "beta_h")
    assert fs.better(a, fitted(2.95, "laser_sensor", "piezo_creep")) is a  # within 10 % of the energy: keep
    b = fitted(1.0, "laser_sensor", "piezo_creep")
    assert fs.better(a, b) is b
    assert fs.better(a, fitted(1.0, "laser_sensor", "piezo_creep", accepted=False)) is a


def test_alternative_starts_put_effects_first_after_a_reestimation():
    winner = fitted(60.0, "stiffness")
    others = [fitted(70.0, "k3"), fitted(90.0, "geometric_stiffening"), fitted(65.0, "d_ep"),
              fitted(150.0, "dielectric_leakage"), fitted(10.0, "damping", accepted=False)]
    got = [c.effect for c in fs.alternative_starts(winner, others)]
    assert got == ["geometric_stiffening", "dielectric_leakage"]
    # two starts at most; after an effect the order is by ΔBIC alone (rejected candidates never start a path)
    got = [c.effect for c in fs.alternative_starts(fitted(50.0, "laser_sensor"), others)]
    assert got == ["d_ep", "k3"]


def test_the_verdict_says_how_much_each_term_explains():
    from workbench.diagnose._verdict import term_shares_words

    pair = fitted(1.0, "piezo_creep", "laser_sensor")
    d = SimpleNamespace(term_shares={"piezo_creep": 0.3, "laser_sensor": 0.7},
                        without_sigma={"piezo_creep": 220.0, "laser_sensor": 335.0})
    words = term_shares_words(d, pair)
    assert "without piezo_creep the rest leaves 220 σ (piezo_creep carries 30 % of what the set removes)" in words
    assert "laser_sensor carries 70 %" in words and "overlap" not in words
    d.term_shares = {"piezo_creep": 0.2, "laser_sensor": 0.3}
    assert "overlap" in term_shares_words(d, pair)
    assert term_shares_words(SimpleNamespace(), pair) == ""


def test_what_a_candidate_touches():
    """Effects by name, independent parameters by member, tied groups by their own name (not their members)."""
    assert fs._touches(spec("piezo_creep", "k3")) == {"piezo_creep", "k3"}
    assert fs._touches(spec("electrical")) == {"R_ep", "C_ep"}
    assert fs._touches(spec("stiffness")) == {"stiffness"}
    assert fs._touches(spec("laser_sensor", "stiffness", "m3")) == {"laser_sensor", "stiffness", "m3"}


def test_alternative_starts_never_share_what_they_touch():
    """A start touching the winner or an earlier start is skipped and the next one is still taken; what the
    winner touches stays excluded after starts are taken (the starts accumulate, they do not replace it)."""
    winner = fitted(60.0, "electrical")  # touches R_ep and C_ep
    others = [fitted(61.0, "k3"), fitted(62.0, "R_ep"), fitted(63.0, "m3"), fitted(64.0, "C_ep")]
    assert [c.effect for c in fs.alternative_starts(winner, others, n=3)] == ["k3", "m3"]
    others = [fitted(61.0, "R_ep"), fitted(62.0, "electrical"), fitted(63.0, "k3")]
    assert [c.effect for c in fs.alternative_starts(fitted(60.0, "laser_sensor"), others, n=3)] == ["R_ep", "k3"]


def test_strength_order_accepted_and_fitted_first():
    acc_weak, acc_strong = fitted(50.0, "k3"), fitted(5.0, "c1")
    rejected = fitted(4.0, "m3", accepted=False)
    scr_good, scr_bad = screened("piezo_creep"), screened("laser_sensor")
    scr_good.screen_train_rms_sigma, scr_bad.screen_train_rms_sigma = 20.0, 200.0
    unstable = fitted(1.0, "d_ep")
    unstable.stable = False
    combo = fitted(0.5, "k3", "c1")
    nospec = fitted(0.5, "m1")
    nospec.spec = None
    got = [c.effect for c in fs._strength_order([scr_bad, rejected, acc_weak, unstable, combo, scr_good, nospec,
                                                 acc_strong])]
    assert got == ["c1", "k3", "m3", "piezo_creep", "laser_sensor"]


def test_at_noise_floor_boundary():
    from workbench.fit import noise_tolerance

    c = fitted(1.0, "k3")
    limit = 1.0 + noise_tolerance(c.n_eff_held)
    c.outcome.held_rms_sigma = limit
    assert fs.at_noise_floor(c)
    c.outcome.held_rms_sigma = math.nextafter(limit, 2.0)
    assert not fs.at_noise_floor(c)
    c.outcome.held_rms_sigma = 1.9  # far above the floor (tolerance ≈ 0.2 σ here)
    assert not fs.at_noise_floor(c)


def test_better_boundaries_and_rejected_sets():
    """Exactly at the margins: a plain set within PREFER_PARAMETER_WITHIN (inclusive) wins either way round; a
    challenger must be strictly better on ΔBIC and leave strictly less than 1/PREFER_PARAMETER_WITHIN of the energy;
    a rejected or unfitted set never wins, and a rejected incumbent loses to any accepted challenger."""
    eff = fitted(2.0, "thermal_drift")
    plain = fitted(2.0, "k3")
    plain.outcome.held_rss = PREFER_PARAMETER_WITHIN * eff.held_rss
    assert fs.better(eff, plain) is plain and fs.better(plain, eff) is plain
    plain.outcome.held_rss = math.nextafter(PREFER_PARAMETER_WITHIN * eff.held_rss, math.inf)
    eff.delta_bic_held = plain.delta_bic_held + 1.0
    # just outside the margin: the effect set competes on ΔBIC and energy, and wins here
    assert fs.better(plain, eff) is eff and fs.better(eff, plain) is eff
    # two plain sets (or two with effects): no preference, ΔBIC and the energy margin decide
    p1, p2 = fitted(3.0, "k3"), fitted(1.0, "c1")
    assert fs.better(p1, p2) is p2 and fs.better(p2, p1) is p2
    p3 = fitted(3.0, "m3")
    p3.outcome.held_rss = p1.held_rss / PREFER_PARAMETER_WITHIN * 1.0000001
    assert fs.better(p3, p1) is p3 and fs.better(p1, p3) is p1  # within the margin: the incumbent stays
    # equal ΔBIC is not better, even with less energy
    a, b = fitted(3.0, "laser_sensor"), fitted(1.0, "piezo_creep")
    b.delta_bic_held = a.delta_bic_held
    assert fs.better(a, b) is a
    # exactly the energy margin is not enough
    c = fitted(1.0, "piezo_creep")
    c.outcome.held_rss = a.held_rss / PREFER_PARAMETER_WITHIN
    c.delta_bic_held = a.delta_bic_held + 1.0
    assert c.held_rss * PREFER_PARAMETER_WITHIN == pytest.approx(a.held_rss)
    if c.held_rss * PREFER_PARAMETER_WITHIN == a.held_rss:
        assert fs.better(a, c) is a
    # rejected / unfitted
    rej = fitted(3.0, "laser_sensor", accepted=False)
    assert fs.better(rej, fitted(5.0, "k3")).effect == "k3"
    unfitted = screened("piezo_creep")
    assert fs.better(unfitted, fitted(5.0, "k3")).effect == "k3"
    assert fs.better(fitted(5.0, "k3"), unfitted).effect == "k3"
    nospec = fitted(5.0, "k3")
    nospec.spec = None  # a set whose spec is unknown is not "plain": a plain challenger within the margin wins
    m3 = fitted(5.0, "m3")
    assert fs.better(nospec, m3) is m3


def test_a_set_met_again_is_not_refitted_and_is_scored_against_the_nominal_model(monkeypatch):
    """The beam's paths and the backward step meet the same sets again (the set before a path's last addition is a
    drop-one fit; two members added in either order): one fit per set, each use a copy scored against the nominal
    model (a try scored against the path's current set does not leak into a later use)."""
    calls: list[str] = []

    def fake_fit(s, base, targets, data, rss0_held, *, start, min_reduction, **kw):
        calls.append(s.label)
        c = fitted(5.0, *s.members)
        c.outcome = SimpleNamespace(held_rss=25.0 * N, held_rms_sigma=5.0, n_held=N, n_train=N, train_rss=25.0 * N,
                                    rho1_held=0.0, values={})
        c.free = [object()] * len(s.members)
        c.status = "fitted"
        return c

    monkeypatch.setattr(fit_cache, "fit_spec", fake_fit)
    fits = fs.FitCache()
    kw = dict(start={}, min_reduction=0.02)
    a = fits.fit(spec("dielectric_leakage", "k1"), None, [], {}, RSS0, **kw)
    fs.score(a, 30.0 ** 2 * N, 0.02, k_ref=1)  # scored against a current set, as forward selection does
    b = fits.fit(spec("k1", "dielectric_leakage"), None, [], {}, RSS0, **kw)
    assert calls == [spec("dielectric_leakage", "k1").label] and fits.hits == 1
    assert b is not a and b.outcome is a.outcome
    assert b.delta_bic_held == pytest.approx(N * math.log(RSS0 / (25.0 * N)) - 2 * math.log(N))
    fits.fit(spec("k1"), None, [], {}, RSS0, **kw)
    assert len(calls) == 2


def test_a_forward_step_fits_every_try_quickly_and_only_the_best_in_full(monkeypatch):
    calls: list[tuple[str, int]] = []
    held = {"geometric_stiffening": 3.0, "piezo_creep": 9.0, "air_damping": 6.0}

    def fake_fit(s, base, targets, data, rss0_held, *, start, min_reduction, max_nfev=30, **kw):
        calls.append((s.label, max_nfev))
        other = next(m for m in s.members if m != "dielectric_leakage")
        h = held[other] * (0.9 if max_nfev > fs.TRY_NFEV else 1.0)
        c = fitted(h, *s.members)
        c.outcome = SimpleNamespace(held_rss=h * h * N, held_rms_sigma=h, n_held=N, n_train=N, train_rss=h * h * N,
                                    rho1_held=0.0, values={"x": 1.0})
        c.free = [object()] * len(s.members)
        c.status = "fitted"
        return c

    monkeypatch.setattr(fit_cache, "fit_spec", fake_fit)
    current = fitted(20.0, "dielectric_leakage")
    current.outcome.values = {}
    current.free = [object()]
    tries = [(spec(n), {}) for n in held]
    best = fs._best_try(current, tries, None, [], {}, RSS0, fs.FitCache(), min_reduction=0.02, max_nfev=30,
                        threads=None, seed=0)
    assert best is not None and "geometric_stiffening" in best.members and best.held_rms_sigma == pytest.approx(2.7)
    assert sorted(n for _, n in calls) == [fs.TRY_NFEV] * 3 + [30]
    assert calls[-1] == (current.spec.plus(spec("geometric_stiffening")).label, 30)


def test_without_the_beam_only_the_greedy_path_is_taken_and_nothing_is_swapped(monkeypatch):
    # the same stalled greedy path as above; beam=False (an event inside the record, the discovery step follows):
    # no other start, no swap fit, the greedy set is the selection
    stiffness = fitted(60.0, "stiffness")
    greedy = fitted(40.0, "dielectric_leakage", "stiffness")
    starts = _stub_paths(monkeypatch, {"stiffness": greedy, "geometric_stiffening": fitted(1.0, "geometric_stiffening",
                                                                                           "dielectric_leakage")})
    swaps: list[str] = []
    monkeypatch.setattr(fit_cache, "fit_spec", lambda s, *a, **kw: swaps.append(s.label) or fitted(50.0, *s.members))
    sel = fs.select_set(stiffness, [fitted(80.0, "geometric_stiffening"), fitted(200.0, "dielectric_leakage")], None,
                        [], {}, RSS0, min_reduction=0.02, threads=None, max_nfev=5, seed=0, base_held=400.0,
                        beam=False)
    assert sel.final is greedy and starts == ["stiffness"] and swaps == []


def test_an_event_inside_the_record_is_where_the_nominal_residual_leaves_the_noise():
    import numpy as np

    from workbench.discover import event_onset

    rng = np.random.default_rng(0)
    t = np.arange(15000) / 1000.0
    noise = rng.standard_normal((1, t.size))
    step = noise + 40.0 * np.sin(2 * np.pi * 7.0 * t) * (t >= 9.0)
    assert event_onset(t, step) == pytest.approx(9.0, abs=0.01)
    assert event_onset(t, noise) is None  # nothing wrong
    assert event_onset(t, noise + 40.0 * np.sin(2 * np.pi * 7.0 * t)) is None  # wrong from the start
    assert event_onset(t, noise + 40.0 * (t >= 1.0)) is None  # quiet over less than QUIET_SHARE of the record
    assert event_onset(t, noise * 1.5 + 40.0 * (t >= 9.0)) is None  # not at the noise level before
    assert event_onset(t, noise + 10.0 * ((t >= 10.0) & (t < 10.05))) is None  # a burst, not a lasting change


@pytest.mark.parametrize("moot", [True, False])
def test_the_beam_asks_after_its_first_other_path_whether_its_search_is_moot(monkeypatch, moot):
    # greedy stalls at 40 σ, the first other start (an effect) at 30 σ; ``beam_unless`` hears the best set then, once:
    # True (the discovery, run then, found a cure of damage forms) ends the selection there — no second start, no
    # swap — False lets the beam go on to the start that finds the true pair
    stiffness = fitted(60.0, "stiffness")
    greedy = fitted(40.0, "dielectric_leakage", "stiffness")
    first = fitted(30.0, "geometric_stiffening", "mass")
    pair = fitted(1.0, "piezo_creep", "dielectric_leakage")
    starts = _stub_paths(monkeypatch, {"stiffness": greedy, "geometric_stiffening": first, "piezo_creep": pair})
    swaps: list[str] = []
    monkeypatch.setattr(fit_cache, "fit_spec", lambda s, *a, **kw: swaps.append(s.label) or fitted(50.0, *s.members))
    asked: list[CandidateResult] = []
    sel = fs.select_set(stiffness, [fitted(80.0, "geometric_stiffening"), fitted(90.0, "piezo_creep")], None,
                        [], {}, RSS0, min_reduction=0.02, threads=None, max_nfev=5, seed=0, base_held=400.0,
                        beam_unless=lambda final: asked.append(final) or moot)
    assert asked == [first]
    if moot:
        assert sel.final is first and starts == ["stiffness", "geometric_stiffening"] and swaps == []
    else:
        assert sel.final is pair and starts[:3] == ["stiffness", "geometric_stiffening", "piezo_creep"]


def test_a_first_other_path_at_the_noise_floor_asks_nothing(monkeypatch):
    # the mimic: the first other start finds the true pair — the discovery is never run
    stiffness = fitted(60.0, "stiffness")
    pair = fitted(1.0, "geometric_stiffening", "dielectric_leakage")
    _stub_paths(monkeypatch, {"stiffness": fitted(40.0, "dielectric_leakage", "stiffness"),
                              "geometric_stiffening": pair})
    asked: list[CandidateResult] = []
    sel = fs.select_set(stiffness, [fitted(80.0, "geometric_stiffening"), fitted(200.0, "dielectric_leakage")], None,
                        [], {}, RSS0, min_reduction=0.02, threads=None, max_nfev=5, seed=0, base_held=400.0,
                        beam_unless=lambda final: asked.append(final) or True)
    assert sel.final is pair and asked == []
