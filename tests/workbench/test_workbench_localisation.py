"""Where it fails: windows by regime, error-carrying bands, loops against the drive, branches (synthetic residuals)."""

from __future__ import annotations

import numpy as np

from workbench.localise import localise
from workbench.localise._localise import drive_regimes, rolling_rms
from workbench.records import Segment

FS = 1000.0
T = np.arange(int(20 * FS) + 1) / FS
U = 600 * np.sin(2 * np.pi * 0.1 * T)  # MBIT.a-like drive
Y = 5e-3 * np.sin(2 * np.pi * 0.1 * T)  # measured tip displacement
SIGMA = 2e-6
SEGS = (Segment(0.0, 5.0, "first half-cycle"), Segment(5.0, 20.0, "rest of the test"))


def _noise(seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).normal(0, SIGMA, T.size)


def test_white_residual_flags_nothing() -> None:
    loc = localise(T, Y + _noise(), Y, U, channel="z3", unit="m", noise_std=SIGMA)
    assert loc.windows == [] and loc.frac_flagged == 0.0
    assert not loc.bands  # nothing significantly above the noise floor
    assert "no localised failure" in loc.findings[0]


def test_noise_level_is_estimated_when_not_declared() -> None:
    loc = localise(T, Y + _noise(1) + 1e-4 * np.sin(2 * np.pi * 0.1 * T), Y, U, channel="z3", unit="m")
    assert abs(loc.noise_std - SIGMA) < 0.1 * SIGMA and "estimated" in loc.noise_source


def test_burst_is_found_in_time_and_marked_by_regime() -> None:
    err = np.where((T >= 3.0) & (T < 4.0), 50e-6 * np.sin(2 * np.pi * 17.0 * T), 0.0)
    loc = localise(T, Y + err + _noise(), Y, U, channel="z3", unit="m", noise_std=SIGMA, segments=SEGS)
    assert len(loc.windows) == 1
    w = loc.windows[0]
    assert 2.8 < w.start_s < 3.15 and 3.85 < w.end_s < 4.2 and w.regime == "first half-cycle"
    assert w.share_sq_error > 0.9  # the rest is the noise of the other 19 s
    reg = {r.label: r for r in loc.regimes}
    assert reg["first half-cycle"].share_sq_error > 0.9 and reg["rest of the test"].frac_flagged == 0.0
    # the band holding 17 Hz carries it
    top = loc.bands[0]
    assert top.f_lo_Hz <= 17.0 <= top.f_hi_Hz and top.share > 0.8


def test_band_is_named_by_a_model_feature() -> None:
    err = 30e-6 * np.sin(2 * np.pi * 35.6 * T)
    loc = localise(T, Y + err + _noise(), Y, U, channel="z3", unit="m", noise_std=SIGMA,
                   features=[(17.07, "mode 1 (17.1 Hz)"), (35.65, "mode 2 (35.6 Hz)")])
    assert "mode 2" in loc.bands[0].near and loc.bands[0].share > 0.8


def test_offset_is_its_own_band_and_finding() -> None:
    loc = localise(T, Y + 40e-6 + _noise(), Y, U, channel="z3", unit="m", noise_std=SIGMA)
    assert loc.bands[0].f_hi_Hz == 0.0 and loc.bands[0].share > 0.99
    assert any("constant offset" in f for f in loc.findings)


def test_hysteresis_loop_in_the_residual_is_detected() -> None:
    du = np.gradient(U, T)
    loop = 40e-6 * np.sign(du) * np.cos(np.pi * U / 1200)  # differs between rising and falling branches
    loc = localise(T, Y + loop + _noise(), Y, U, channel="z3", unit="m", drive_name="va", drive_unit="V",
                   noise_std=SIGMA)
    ar = loc.amp_rate
    assert ar is not None and ar.loop_detected and ar.loop_index > 0.5
    assert any("hysteresis loop" in f for f in loc.findings)
    # an error that depends only on the drive level (no memory) draws no loop
    loc2 = localise(T, Y + 40e-6 * (U / 600) ** 3 + _noise(), Y, U, channel="z3", unit="m", noise_std=SIGMA)
    assert not loc2.amp_rate.loop_detected
    assert loc2.amp_rate.amp_corr > 0.5  # but its size grows with |drive| (Eq. 4 behaviour)


def test_charging_vs_discharging_branches() -> None:
    dabs = np.gradient(np.abs(U), T)
    err = np.where(dabs > 0, 50e-6, 5e-6) * np.sign(U)  # worse while |drive| rises (charging)
    loc = localise(T, Y + err + _noise(), Y, U, channel="z3", unit="m", noise_std=SIGMA)
    br = {b.label: b for b in loc.branches}
    assert br["charging (|drive| rising)"].rms_error > 3 * br["discharging (|drive| falling)"].rms_error
    assert any("Worse while charging" in f for f in loc.findings)


def test_drive_regimes_and_rolling_rms() -> None:
    t = np.arange(0, 3, 1e-3)
    u = np.clip((t - 1.0) / 0.5, 0, 1) * 300.0
    lab = drive_regimes(t, u)
    assert lab[100] == "rest" and lab[1250] == "rising" and lab[2500] == "hold"
    e = np.ones(1000)
    np.testing.assert_allclose(rolling_rms(e, 50), 1.0)
