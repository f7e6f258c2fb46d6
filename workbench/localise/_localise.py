"""Where the model fails: in time (by test regime), in frequency, against input amplitude and rate, by branch.

For one replayed channel (residual ``e = measured − model``, SI):

* **time windows** where the rolling RMS of ``e`` exceeds ``k × σ_noise`` (default k = 3; σ_noise declared in the
  record or estimated robustly from the residual's second differences), each marked with the test regime it
  falls in (the record's ``segments``, else regimes derived from the drive: rest / rising / falling / hold);
* **by regime**: RMS error, share of the total squared error, time flagged, normalised error (Eq. 5);
* **residual spectrum** (Hann periodogram over the whole record) and the third-octave **bands that carry the
  error** above the white-noise floor, each named by what sits there (a model mode, the RC pole, a harmonic of
  the drive);
* **residual vs input amplitude and rate**, split into rising and falling input: a gap between the branches at the
  same input level is a loop — the fingerprint of hysteresis the model gets wrong; a trend with the rate points at
  rate-dependent effects (damping, creep, RC dynamics);
* **rising vs falling / charging vs discharging** branches (the paper's Fig. 7 discussion: 5 % charging, 0.5 %
  discharging).

:func:`localise` is the entry point; the pieces live beside it: :mod:`workbench.localise._results` (what it
returns), :mod:`workbench.localise._drive` (time and drive), :mod:`workbench.localise._spectrum`
(frequency) and :mod:`workbench.localise._reading` (hypotheses and findings in words).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from workbench.localise._drive import (
    amplitude_rate,
    branch_stats,
    drive_rate,
    drive_regimes,
    flagged_windows,
    rolling_rms,
    segment_labels,
)
from workbench.localise._reading import HYPOTHESIS_KINDS, describe_findings, hypotheses, mode_shift
from workbench.localise._results import (
    AmplitudeRate,
    Band,
    BranchStats,
    Hypothesis,
    Localisation,
    RegimeStats,
    Window,
)
from workbench.localise._spectrum import dominant_frequency, model_features, residual_spectrum
from workbench.records import Segment
from workbench.simulation import estimate_noise_std

DEFAULT_THRESHOLD_SIGMA = 3.0
TRANSITION_LABELS = ("rest", "rising", "falling", "hold")


def localise(t: np.ndarray, measured: np.ndarray, simulated: np.ndarray, drive: np.ndarray, *,
             channel: str = "y", unit: str = "", drive_name: str = "u", drive_unit: str = "",
             segments: Sequence[Segment] = (), noise_std: float | None = None, eps: np.ndarray | None = None,
             threshold_sigma: float = DEFAULT_THRESHOLD_SIGMA, window_s: float | None = None,
             features: Sequence[tuple[float, str]] = ()) -> Localisation:
    """Where does the model fail on this channel? (see the module docstring; arrays share the time base ``t``)

    ``eps`` is the normalised error ε(t) (Eq. 5) for the regime and branch tables; ``features`` names model
    frequencies (see :func:`model_features`) for the spectrum bands.
    """
    t = np.asarray(t, float)
    y = np.asarray(measured, float)
    e = y - np.asarray(simulated, float)
    u = np.asarray(drive, float)
    if not (t.size == y.size == e.size == u.size):
        raise ValueError("t, measured, simulated and drive must have the same length")
    dt = float(np.median(np.diff(t)))
    if noise_std is not None and noise_std > 0:
        sigma, source = float(noise_std), "declared in the record"
    else:
        sigma, source = estimate_noise_std(e), "estimated from the residual (MAD of second differences)"
    duration = float(t[-1] - t[0])
    win = window_s if window_s is not None else float(np.clip(duration / 100.0, 20 * dt, 0.2))
    n_win = max(3, round(win / dt))
    thr = max(threshold_sigma * sigma, 1e-9 * float(np.ptp(y)) if np.ptp(y) > 0 else 1e-300)
    rr = rolling_rms(e, n_win)
    labels = segment_labels(t, segments, drive_regimes(t, u))
    total_sq = float(np.sum(e ** 2))
    windows = flagged_windows(t, e, rr, thr, labels, n_win, total_sq)
    flagged = rr > thr
    regimes: list[RegimeStats] = []
    for lab in dict.fromkeys(labels.tolist()):
        k = labels == lab
        ek = e[k]
        epk = eps[k] if eps is not None else np.array([np.nan])
        epk = epk[np.isfinite(epk)]
        regimes.append(RegimeStats(
            str(lab), float(np.count_nonzero(k) * dt), float(np.sqrt(np.mean(ek ** 2))), float(ek.mean()),
            float(np.sum(ek ** 2) / total_sq) if total_sq > 0 else 0.0, float(np.mean(flagged[k])),
            float(epk.mean()) if epk.size else float("nan"), float(epk.max()) if epk.size else float("nan")))
    drive_f = dominant_frequency(t, u)
    f, pe, py, npsd, bands = residual_spectrum(t, e, y, sigma, features, drive_f)
    ar = amplitude_rate(t, u, e, y, drive_name, drive_unit, sigma)
    loc = Localisation(
        channel=channel, unit=unit, noise_std=sigma, noise_source=source, threshold=thr, window_s=n_win * dt,
        windows=sorted(windows, key=lambda w: -w.share_sq_error)[:20], regimes=regimes,
        frac_flagged=float(np.mean(flagged)), spectrum_f=f, spectrum_resid=pe, spectrum_meas=py, noise_psd=npsd,
        bands=bands, branches=branch_stats(t, u, e, eps), amp_rate=ar, labels=labels, rolling_rms=rr,
    )
    loc.hypotheses = hypotheses(t, e, np.asarray(simulated, float), u, y, sigma, unit, features, drive_name)
    loc.findings = describe_findings(loc, t, e, sigma)
    return loc


__all__ = [
    "DEFAULT_THRESHOLD_SIGMA",
    "HYPOTHESIS_KINDS",
    "TRANSITION_LABELS",
    "AmplitudeRate",
    "Band",
    "BranchStats",
    "Hypothesis",
    "Localisation",
    "RegimeStats",
    "Window",
    "amplitude_rate",
    "branch_stats",
    "describe_findings",
    "dominant_frequency",
    "drive_rate",
    "drive_regimes",
    "flagged_windows",
    "hypotheses",
    "localise",
    "mode_shift",
    "model_features",
    "residual_spectrum",
    "rolling_rms",
    "segment_labels",
]
