"""The residual in frequency: the model's features (modes, real poles), the drive's dominant line, and the
third-octave bands that carry the residual above the white-noise floor."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from workbench.localise._results import Band


def model_features(model, params=None) -> list[tuple[float, str]]:
    """(frequency Hz, label) of the model's linear modes at rest and its real poles (e.g. the RC pole)."""
    from workbench.simulation import linearise

    a, _ = linearise(model, ["z3"], params)
    ev = np.linalg.eigvals(a)
    feats: list[tuple[float, str]] = []
    osc = sorted({round(abs(float(x.imag)), 9): x for x in ev if x.imag > 1e-6}.values(), key=lambda x: abs(x))
    for i, x in enumerate(osc, start=1):
        wn = abs(x)
        feats.append((wn / (2 * np.pi), f"mode {i} ({wn / (2 * np.pi):.1f} Hz, ζ {(-x.real / wn) * 100:.1f} %)"))
    real = sorted({float(f"{-x.real / (2 * np.pi):.3g}") for x in ev if abs(x.imag) <= 1e-6 and x.real < -1e-3})
    for f in real:
        if 0.5 < f < 1e4:
            feats.append((f, f"real pole {f:.3g} Hz"))
    return feats


def _third_octaves(f_min: float, f_max: float, min_width: float = 0.0) -> list[tuple[float, float]]:
    """Third-octave bands between f_min and f_max; neighbours are merged until each is ``min_width`` wide (the
    frequency resolution of a short record is coarser than a third octave at low frequency)."""
    centres = 1000.0 * 2.0 ** (np.arange(-60, 40) / 3.0)
    edges = [(max(c * 2 ** (-1 / 6), f_min), min(c * 2 ** (1 / 6), f_max)) for c in centres]
    edges = [(lo, hi) for lo, hi in edges if hi > lo]
    out: list[tuple[float, float]] = []
    for lo, hi in edges:
        if out and out[-1][1] - out[-1][0] < min_width:
            out[-1] = (out[-1][0], hi)
        else:
            out.append((lo, hi))
    return out


def _name_band(lo: float, hi: float, features: Sequence[tuple[float, str]], drive_f: float | None) -> str:
    names = [lab for f, lab in features if lo * 0.9 <= f <= hi * 1.1]
    if drive_f:
        for h in range(1, 40):
            if lo <= h * drive_f <= hi:
                names.append("drive frequency" if h == 1 else f"{h}× drive frequency")
                break
    return "; ".join(names)


def dominant_frequency(t: np.ndarray, u: np.ndarray) -> float | None:
    """Frequency of a periodic drive (Hz) if one line carries most of its power, else None."""
    u = np.asarray(u, float) - np.mean(u)
    if u.size < 16 or not np.any(u):
        return None
    p = np.abs(np.fft.rfft(u * np.hanning(u.size))) ** 2
    f = np.fft.rfftfreq(u.size, float(np.median(np.diff(t))))
    k = int(np.argmax(p[1:])) + 1
    if k < 2 or p[max(0, k - 2):k + 3].sum() < 0.8 * p[1:].sum():  # < 2 cycles, or not one line (a step)
        return None
    return float(f[k])


def residual_spectrum(t: np.ndarray, e: np.ndarray, y: np.ndarray, sigma: float, features, drive_f
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, list[Band]]:
    """Hann periodogram of the residual and the bands carrying its energy above the white-noise floor.

    The mean of the residual (an offset) is its own "0 Hz" band. A third-octave band counts only when its power
    exceeds what white noise of the estimated level reaches with probability 10⁻³ over all bands (the band power
    of noise is Gamma-distributed with ``k_eff = bins / 1.94`` degrees of freedom for a Hann periodogram).
    """
    from scipy.signal import periodogram
    from scipy.stats import gamma

    fs = 1.0 / float(np.median(np.diff(t)))
    f, pe = periodogram(e, fs=fs, window="hann", detrend="constant", scaling="density")
    _, py = periodogram(y, fs=fs, window="hann", detrend="constant", scaling="density")
    noise_psd = 2.0 * sigma ** 2 / fs  # one-sided white-noise density
    df = f[1] - f[0] if f.size > 1 else 1.0
    mean_sq = float(np.mean(e)) ** 2
    rows: list[tuple[float, float, float]] = []
    if mean_sq > 16.0 * sigma ** 2 / e.size:  # the mean is significant (4 standard errors)
        rows.append((0.0, 0.0, mean_sq))
    bands_all = _third_octaves(max(0.5 * df, 1e-3), fs / 2, min_width=4 * df)
    q = 1.0 - 1e-3 / max(1, len(bands_all))
    for lo, hi in bands_all:
        k = (f >= lo) & (f < hi)
        nk = int(np.count_nonzero(k))
        if not nk:
            continue
        power = float(np.sum(pe[k]) * df)
        floor = noise_psd * nk * df
        k_eff = max(1.0, nk / 1.94)  # Hann: neighbouring bins are correlated
        if power > gamma.ppf(q, a=k_eff, scale=floor / k_eff):
            rows.append((lo, hi, power - floor))
    total = sum(r[2] for r in rows)
    bands: list[Band] = []
    if total > 0:
        rows.sort(key=lambda r: -r[2])
        covered = 0.0
        for lo, hi, ex in rows:
            if covered >= 0.9 * total or len(bands) >= 6 or ex < 0.02 * total:
                break
            covered += ex
            near = "offset (mean residual)" if hi == 0.0 else _name_band(lo, hi, features, drive_f)
            bands.append(Band(lo, hi, ex / total, float(np.sqrt(ex)), near))
    return f, pe, py, noise_psd, bands
