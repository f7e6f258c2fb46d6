"""One reading of the evidence (issue 11 point 4): localise() ranks hypothesis classes and the findings lead with the
most likely one, in numbers. Synthetic signals (a second-order mode driven by a chirp) with designed distortions, so
each class is known; no plant simulation."""

from __future__ import annotations

import re

import numpy as np
import pytest
from scipy import signal

from workbench.localise import localise
from workbench.localise._localise import mode_shift

FS = 500.0
T = np.arange(0, 12.0, 1 / FS)
SIGMA = 1e-6


def _mode(f_hz: float, zeta: float = 0.05) -> np.ndarray:
    w = 2 * np.pi * f_hz
    sys = signal.lti([w * w * 2e-5], [1, 2 * zeta * w, w * w])
    u = np.sin(2 * np.pi * (0.5 * T + (40 - 0.5) / (2 * 12.0) * T ** 2))  # chirp 0.5 → 40 Hz
    _, y, _ = signal.lsim(sys, u, T)
    return u, y


U, YHAT = _mode(17.0)
RNG = np.random.default_rng(1)


def _top(measured: np.ndarray, yhat: np.ndarray = YHAT):
    noisy = measured + RNG.normal(0, SIGMA, measured.size)
    loc = localise(T, noisy, yhat, U * 300, channel="z3", unit="m", drive_name="v_a", drive_unit="V",
                   noise_std=SIGMA, features=[(17.0, "mode 1 (17.0 Hz, ζ 5.0 %)")])
    return loc


def test_sign_asymmetric_leads_with_the_ratio():
    loc = _top(YHAT + 0.3 * np.maximum(YHAT, 0.0))
    assert loc.hypotheses[0].kind == "sign-asymmetric"
    ratio = float(re.search(r"error is ([\d.]+)× larger for positive", loc.hypotheses[0].sentence).group(1))
    assert ratio > 5
    assert any(f.startswith("Most likely: sign-asymmetric") for f in loc.findings)


def test_time_varying_gain():
    t = (T - T[0]) / (T[-1] - T[0])
    loc = _top(YHAT * (1 + 0.3 * t))
    assert loc.hypotheses[0].kind == "time-varying"
    assert "grows in time" in loc.hypotheses[0].sentence


def test_switching_at_velocity_reversals():
    v = np.gradient(YHAT, T)
    loc = _top(YHAT + 3e-6 * np.sign(v))
    assert loc.hypotheses[0].kind == "switching at zero crossings"
    amp = re.search(r"switches by ±([\d.]+) µm", loc.hypotheses[0].sentence)
    assert amp and 2.0 < float(amp.group(1)) < 4.0


def test_shifted_mode_is_measured_in_percent():
    _, y_low = _mode(17.0 * 0.92)
    f_meas, f_mod = mode_shift(T, U, y_low, YHAT, 17.0)
    assert f_meas / f_mod - 1 == pytest.approx(-0.08, abs=0.015)
    loc = _top(y_low)
    h = loc.hypotheses[0]
    assert h.kind == "shifted dynamics" and "lower than modelled" in h.sentence
    pct = float(re.search(r"mode 1 is ([\d.]+) % lower", h.sentence).group(1))
    assert 6 <= pct <= 10


def test_quadratic_sensor_reads_as_sign_asymmetric_static_map():
    loc = _top(YHAT + 2e4 * (YHAT - YHAT[0]) ** 2)
    top = loc.hypotheses[0]
    assert top.kind == "sign-asymmetric" and "suspect the sensor" in top.sentence


def test_noise_only_has_no_hypothesis():
    loc = _top(YHAT.copy())
    assert loc.hypotheses == []
