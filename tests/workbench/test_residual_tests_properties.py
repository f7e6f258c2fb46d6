"""The residual tests' arithmetic against independent references (direct correlation sums, SciPy's normal
quantiles) and their verdicts on residuals built to fail exactly one test; input checks at their limits."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import norm

from board_config.errors import InputError
from workbench.compare import ResidualTests, residual_tests
from workbench.compare import _residual_tests as rt_module
from workbench.compare._residual_tests import (
    POINTS_AT,
    band_for,
    bias_test,
    cross_correlation,
    effective_lags,
)

RNG = np.random.default_rng(20)
N = 2000
U = RNG.standard_normal(N)
NOISE = RNG.standard_normal(N)


def reference_phi(a, b, tau):
    a = a - a.mean()
    b = b - b.mean()
    s = np.sum(a[: a.size - tau] * b[tau:]) if tau >= 0 else np.sum(a[-tau:] * b[: b.size + tau])
    return s / math.sqrt(np.sum(a * a) * np.sum(b * b))


@pytest.mark.parametrize("nlags", [5, 300])  # direct sums and the FFT path
def test_cross_correlation_equals_the_definition(nlags):
    a, b = RNG.standard_normal(400) + 3.0, RNG.standard_normal(400) - 1.0
    lags = np.arange(-nlags // 2, nlags - nlags // 2)
    got = cross_correlation(a, b, lags)
    want = [reference_phi(a, b, int(t)) for t in lags]
    assert got == pytest.approx(want, abs=1e-12)
    assert np.isnan(cross_correlation(np.ones(50), b[:50], np.arange(3))).all()
    assert np.isnan(cross_correlation(a[:50], np.full(50, 2.0), np.arange(3))).all()


def test_band_is_the_sidak_bonferroni_normal_quantile():
    for n, m, level in ((100, 1.0, 0.05), (2000, 25.0, 0.01), (500, 7.5, 0.2)):
        assert band_for(n, m, level) == pytest.approx(norm.ppf(1 - level / (2 * m)) / math.sqrt(n), rel=1e-12)


def test_effective_lags_between_one_and_m():
    lags = np.arange(1, 26)
    white = effective_lags(NOISE, lags)
    assert 20.0 < white <= 25.0
    sine = effective_lags(np.sin(np.arange(N) * 0.05), lags)
    assert 1.0 <= sine < 4.0
    assert effective_lags(NOISE, np.array([3])) == 1.0
    assert effective_lags(np.ones(100), lags) == 25.0  # flat: no estimate, all lags counted


def test_bias_test_by_hand():
    e = np.array([1.0, 2.0, 3.0, 4.0])
    t = 2.5 / (np.std(e, ddof=1) / 2.0)
    r = bias_test(e, level=0.01)
    assert r.statistic == pytest.approx(t) and r.band == pytest.approx(norm.ppf(0.995))
    assert r.passed is False and r.verdict == "FAIL" and r.p_value == pytest.approx(2 * norm.sf(t))
    assert r.r.tolist() == [2.5] and r.ratio == pytest.approx(t / norm.ppf(0.995))
    assert "t = 3.87" in r.note and r.points_at == POINTS_AT["bias"]
    assert bias_test(e, level=1e-5).passed is True  # a looser band: z_{1-0.5e-5} = 4.42 > 3.87
    for flat in (np.full(5, 2.0), np.array([7.0])):
        c = bias_test(flat)
        assert c.passed is None and c.verdict == "n/a" and math.isnan(c.ratio) and "constant" in c.note
    assert bias_test(np.array([1.0, -1.0, 1.0, -1.0])).passed is True


def _battery(e, u=U, **kw):
    return residual_tests(e, u, **kw)


def test_white_residual_passes_and_each_built_fault_fails_its_test():
    ok = _battery(0.1 * NOISE)
    assert ok.adequate is True and ok.failed == [] and [t.key for t in ok.tests] == list(POINTS_AT)
    delayed = 0.1 * NOISE + 0.05 * np.roll(U, 3)  # error follows the drive 3 samples late
    b = _battery(delayed)
    failed = [t.key for t in b.failed]
    assert "ue" in failed and "bias" not in failed and "ee" not in failed
    assert b["ue"].worst_lag == 3 and b.adequate is False
    squared = 0.1 * NOISE + 0.05 * (U ** 2 - 1.0)
    b = _battery(squared)
    assert "u2e" in [t.key for t in b.failed] and b["u2e"].worst_lag == 0
    offset = 0.1 * NOISE + 0.02
    b = _battery(offset)
    assert [t.key for t in b.failed] == ["bias"]
    coloured = np.convolve(NOISE, np.ones(5) / 5, mode="same")
    b = _battery(coloured)
    assert "ee" in [t.key for t in b.failed] and b["ee"].worst_lag == 1
    with pytest.raises(KeyError, match="nope"):
        b["nope"]


def test_effective_lags_from_the_input_but_all_lags_for_the_residuals_own_tests():
    # a slow sine drive: its lags are strongly correlated, the cross tests count few independent lags (a wider
    # band); the whiteness and e(eu) tests are built from the residual itself: white under H0, all m lags count, even
    # when the residual at hand is coloured
    u = np.sin(np.arange(N) * 0.02)
    coloured = np.convolve(NOISE, np.ones(5) / 5, mode="same")
    b = residual_tests(coloured, u, max_lag=10)
    both = np.arange(-10, 11)
    uc = u - u.mean()
    m_ue = effective_lags(uc, both)
    assert m_ue < 5.0
    assert b["ue"].band == pytest.approx(band_for(N, m_ue, 0.01))
    assert b["ue"].note == f"21 lags, {m_ue:.1f} effectively independent"
    u2 = uc ** 2 - np.mean(uc ** 2)
    assert b["u2e"].band == pytest.approx(band_for(N, effective_lags(u2, both), 0.01))
    assert effective_lags(coloured, np.arange(1, 11)) < 9.0  # an estimate would be well below m here
    for key in ("ee", "e_eu"):
        assert b[key].band == pytest.approx(band_for(N, 10.0, 0.01))
        assert b[key].note == "10 lags, 10.0 effectively independent"


def test_statistic_band_and_p_value_are_consistent():
    b = _battery(0.1 * NOISE + 0.05 * np.roll(U, 3), max_lag=10)
    ee = b["ee"]
    assert ee.band == pytest.approx(band_for(N, 10.0, 0.01)) and "10 lags, 10.0 effectively independent" in ee.note
    assert ee.lags.tolist() == list(range(1, 11))
    assert b["ue"].lags.tolist() == list(range(-10, 11)) and b["e_eu"].lags.tolist() == list(range(1, 11))
    for t in b.tests[1:]:
        assert t.statistic == pytest.approx(float(np.max(np.abs(t.r))))
        assert t.passed is (t.statistic <= t.band)
        assert t.ratio == pytest.approx(t.statistic / t.band)
        assert t.worst_lag == int(t.lags[np.argmax(np.abs(t.r))])
    ue = b["ue"]
    m_eff = float(ue.note.split(", ")[1].split(" ")[0])
    assert ue.p_value == pytest.approx(min(1.0, m_eff * 2 * norm.sf(ue.statistic * math.sqrt(N))), rel=1e-2)
    assert ee.p_value == pytest.approx(min(1.0, 10 * 2 * norm.sf(ee.statistic * math.sqrt(N))))
    d = b.to_dict()
    assert (d["channel"], d["input"], d["n"], d["level"], d["max_lag"], d["decimate"], d["adequate"]) == \
        ("y", "u", N, 0.01, 10, 1, False)
    assert d["tests"][2]["verdict"] == "FAIL" and d["tests"][2]["key"] == "ue"


def test_a_flat_input_makes_the_cross_tests_not_applicable():
    b = _battery(0.1 * NOISE, np.full(N, 3.0))
    assert [t.passed for t in b.tests[2:]] == [None] * 4
    assert all(t.note == "not applicable: the input does not vary" for t in b.tests[2:])
    assert b["ee"].passed is True and b.adequate is True
    both_flat = _battery(np.full(N, 0.5), np.full(N, 3.0))
    assert both_flat.adequate is None and both_flat.failed == []


def test_inputs_checked_at_their_limits():
    m = 25
    _battery(NOISE[: 4 * m + 10], U[: 4 * m + 10])  # exactly enough samples
    with pytest.raises(InputError, match=f"need at least {4 * m + 10} samples for {m} lags, got {4 * m + 9}"):
        _battery(NOISE[: 4 * m + 9], U[: 4 * m + 9])
    with pytest.raises(InputError, match="need at least 14 samples for 1 lags"):
        _battery(NOISE[:13], U[:13], max_lag=1)
    assert _battery(NOISE[:14], U[:14], max_lag=1).max_lag == 1  # one lag is enough
    with pytest.raises(InputError, match="0 lags"):
        _battery(NOISE, max_lag=0)
    for level in (0.0, 1.0):
        with pytest.raises(InputError, match="level must be in"):
            _battery(NOISE, level=level)
    with pytest.raises(ValueError, match=r"^residual and input must have the same length, got 2000 and 1999$"):
        _battery(NOISE, U[:-1])
    bad = NOISE.copy()
    bad[7] = np.nan
    with pytest.raises(ValueError, match=r"^residual and input must be finite$"):
        _battery(bad)
    with pytest.raises(ValueError, match=r"^residual and input must be finite$"):
        _battery(NOISE, np.where(np.arange(N) == 3, np.inf, U))
    b = _battery(NOISE, decimate=4, channel="z3", input_name="v")
    assert (b.n, b.decimate, b.channel, b.input_name) == (N // 4, 4, "z3", "v")
    assert _battery(NOISE, decimate=0).n == N


def test_test_result_ratio_and_dict():
    r = rt_module.TestResult("ue", "s", "t", np.arange(3), np.zeros(3), 0.0, 0.01, 0.5, 0, 0.5, True, "x")
    assert math.isnan(r.ratio) and r.verdict == "pass"
    d = r.to_dict()
    assert d["lags"] == [0, 1, 2] and d["verdict"] == "pass" and d["key"] == "ue"
    # the JSON record of one test (shm compare --json), every field by its name
    r2 = rt_module.TestResult("u2e", "sym", "title", np.arange(2), np.array([0.5, -0.25]), 0.2, 0.05, 0.5, 1, 0.01,
                              False, "points", "note")
    assert r2.to_dict() == {"key": "u2e", "symbol": "sym", "title": "title", "verdict": "FAIL", "statistic": 0.5,
                            "band": 0.2, "ratio": 2.5, "worst_lag": 1, "p_value": 0.01, "level": 0.05,
                            "points_at": "points", "note": "note", "lags": [0, 1], "r": [0.5, -0.25]}
    rt = ResidualTests("y", "u", 10, 0.01, 2, 1)
    assert rt.adequate is None


def test_a_flat_residual_makes_its_correlation_tests_not_applicable():
    b = _battery(np.full(N, 0.5))
    ee = b["ee"]
    assert ee.to_dict() | {"r": None, "statistic": None, "p_value": None, "ratio": None} == {
        "key": "ee", "symbol": "φee(τ)", "title": "whiteness (autocorrelation)", "verdict": "n/a", "statistic": None,
        "band": pytest.approx(band_for(N, 25.0, 0.01)), "ratio": None, "worst_lag": 0, "p_value": None,
        "level": 0.01, "points_at": POINTS_AT["ee"], "note": "not applicable: a signal in the test has no variation",
        "lags": list(range(1, 26)), "r": None}
    assert np.isnan(ee.r).all() and ee.r.shape == (25,) and math.isnan(ee.statistic) and math.isnan(ee.p_value)
    assert b.adequate is None and all(t.passed is None for t in b.tests)


def test_integer_records_give_the_same_verdicts():
    rng = np.random.default_rng(3)
    e = rng.integers(-128, 128, N).astype(np.int8)
    u = rng.integers(-128, 128, N).astype(np.int8)
    a, b = _battery(e, u), _battery(e.astype(float), u.astype(float))
    for x, y in zip(a.tests, b.tests, strict=True):
        assert x.to_dict() == y.to_dict()


def test_the_correlation_tests_are_blind_to_constant_offsets():
    # the residual or the input shifted by a constant: only the bias test may change; every correlation is the same
    e = 0.1 * NOISE + 0.05 * np.roll(U, 2) * U  # fails e(eu)-type tests: an error depending on the drive's product
    ref = _battery(e, U, level=0.05)
    for e2, u2 in ((e + 3.0, U), (e, U - 7.0), (e - 1.0, U + 2.0)):
        b = _battery(e2, u2, level=0.05)
        for x, y in zip(ref.tests[1:], b.tests[1:], strict=True):
            assert (x.key, x.passed, x.worst_lag) == (y.key, y.passed, y.worst_lag)
            assert x.r == pytest.approx(y.r, abs=1e-9) and x.band == pytest.approx(y.band)
    assert all(t.level == 0.05 for t in ref.tests)  # the bias test too
    ue = ref["ue"]
    assert (ue.symbol, ue.title) == ("φue(τ)", "input–residual cross-correlation")


def test_a_statistic_exactly_on_the_band_passes(monkeypatch):
    # a test fails when max |φ| *leaves* the band: exactly on its edge is a pass (the band is inclusive)
    delayed = 0.1 * NOISE + 0.05 * np.roll(U, 3)
    stat = _battery(delayed)["ue"].statistic
    monkeypatch.setattr(rt_module, "band_for", lambda n, m_eff, level: stat)
    on_edge = _battery(delayed)["ue"]
    assert on_edge.statistic == on_edge.band == stat and on_edge.passed is True
    monkeypatch.setattr(rt_module, "band_for", lambda n, m_eff, level: float(np.nextafter(stat, 0.0)))
    assert _battery(delayed)["ue"].passed is False


def test_effective_lags_count_uncorrelated_lags_fully():
    # a signal whose autocorrelation is exactly zero at lag 1: two adjacent lags are independent, m_eff = 2 exactly
    a = np.tile([1.0, 0.0, -1.0, 0.0], 100)
    assert effective_lags(a, np.array([1, 2])) == 2.0
    assert effective_lags(a, np.array([5])) == 1.0


def test_bias_test_result_in_full():
    """The bias test's whole result: key, symbol and title from TITLES, one lag 0 (integers), the mean as its value,
    the two-sided normal band, the level, |t|, p, the verdict, what it points at and the note — and the
    not-applicable result of a constant residual, with NaN statistic and p."""
    from scipy.special import ndtr, ndtri

    from workbench.compare._residual_tests import TITLES, bias_test

    e = np.array([1, 2, 3, 4, 6])  # integers: read as floats; mean 3.2, sd (ddof 1) √3.7
    r = bias_test(e, level=0.05)
    t = 3.2 / (math.sqrt(3.7) / math.sqrt(5))
    assert (r.key, r.symbol, r.title) == ("bias", *TITLES["bias"])
    assert r.lags.tolist() == [0] and r.lags.dtype.kind == "i" and r.worst_lag == 0
    assert r.r.tolist() == [pytest.approx(3.2)]
    assert r.band == pytest.approx(float(ndtri(0.975))) and r.level == 0.05
    assert r.statistic == pytest.approx(t) and r.p_value == pytest.approx(2 * float(ndtr(-t)))
    assert r.passed is False and r.points_at == POINTS_AT["bias"]
    assert r.note == f"mean residual 3.2 (SI), t = {t:.3g}"
    assert r.to_dict()["lags"] == [0]
    # negative mean: |t| is the statistic
    assert bias_test(-e, level=0.05).statistic == pytest.approx(t)
    # two samples are enough for a standard deviation
    two = bias_test(np.array([1.0, 2.0]))
    assert two.passed is not None and two.statistic == pytest.approx(1.5 / (math.sqrt(0.5) / math.sqrt(2)))
    for const in (np.full(10, 2.5), np.array([4.0])):
        c = bias_test(const, level=0.05)
        assert (c.key, c.symbol, c.title) == ("bias", *TITLES["bias"])
        assert c.lags.tolist() == [0] and c.lags.dtype.kind == "i" and c.worst_lag == 0
        assert c.r.tolist() == [float(const[0])] and c.band == pytest.approx(float(ndtri(0.975)))
        assert c.level == 0.05 and math.isnan(c.statistic) and math.isnan(c.p_value) and c.passed is None
        assert c.points_at == POINTS_AT["bias"] and c.note == "not applicable: the residual is constant"


def test_bias_statistic_exactly_on_the_band_passes(monkeypatch):
    """|t| equal to the band passes (the band is inclusive, like the correlation tests')."""
    import workbench.compare._residual_tests as rt

    e = np.array([1.0, 2.0, 3.0, 4.0, 6.0])
    t = rt.bias_test(e).statistic  # the band becomes exactly the statistic
    monkeypatch.setattr(rt, "ndtri", lambda q: t)
    r = rt.bias_test(e)
    assert r.band == r.statistic and r.passed is True


def test_single_precision_records_are_computed_in_double():
    """A float32 record (a DAQ's native type) gives the double-precision statistics of the same values."""
    from workbench.compare._residual_tests import bias_test

    a32 = RNG.standard_normal(600).astype(np.float32)
    b32 = RNG.standard_normal(600).astype(np.float32) + np.float32(0.3)
    lags = np.arange(-3, 4)
    got = cross_correlation(a32, b32, lags)
    want = cross_correlation(a32.astype(np.float64), b32.astype(np.float64), lags)
    assert got == pytest.approx(want, abs=1e-9)  # (the float32 mean differs in its last bits; float32 sums: 1e-7)
    e32 = (RNG.standard_normal(500) + 0.1).astype(np.float32)
    one, other = bias_test(e32), bias_test(e32.astype(np.float64))
    assert (one.statistic, one.p_value, float(one.r[0])) == (other.statistic, other.p_value, float(other.r[0]))


def test_unit_energy_signals_and_whole_number_float_lags():
    """Signals whose centred energies multiply to exactly 1 are not 'flat'; lags given as whole-number floats
    (np.linspace) are read as integers."""
    a = np.array([0.5, -0.5, 0.5, -0.5])
    assert cross_correlation(a, a, np.array([0, 1])).tolist() == [1.0, -0.75]
    x, y = RNG.standard_normal(100), RNG.standard_normal(100)
    assert cross_correlation(x, y, np.linspace(0, 4, 5)).tolist() == cross_correlation(x, y, np.arange(5)).tolist()


def test_an_overflowing_energy_gives_nan_not_a_silent_zero():
    big = RNG.standard_normal(200) * 1e160  # Σa² overflows to inf
    with np.errstate(over="ignore"):
        assert np.isnan(cross_correlation(big, RNG.standard_normal(200), np.arange(3))).all()
