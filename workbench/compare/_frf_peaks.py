"""Resonance peaks of a sampled frequency response, located between the grid's frequencies.

A stepped-sine table is often coarse: 30 log-spaced frequencies from 0.5 to 50 Hz are 17 % apart, wider than the
half-power band of a mode with a few percent of damping (2ζ ≈ 9 % at ζ = 4.6 %), so the largest sample is not the
resonance — a 15.8 Hz and a 17.1 Hz mode both read "16.5 Hz". Each local maximum of |H| is therefore refined by a
local **one-mode rational fit** to the complex response of the points around it,

    H(s) ≈ (b0 + b1 s [+ b2 s²]) / (s² + a1 s + a0),    s = j 2π f,

with real a0, a1 (the mode: ωn = √a0, ζ = a1 / (2√a0)) and complex numerator coefficients (the mode's residue plus
a smooth background from the other modes and poles). The fit is linear in the unknowns once multiplied out (Levy),
re-weighted by the previous denominator (Sanathanan–Koerner, a few passes) so the errors are those of H itself.
Because amplitude *and* phase enter, three to five points around the maximum suffice to place the mode well
inside a grid cell. When the fit is not a stable, damped mode inside the window that reproduces the points (relative
error ≤ :data:`MAX_FIT_ERROR`), a parabola in log-magnitude over log-frequency through the three points around the
maximum is used instead, and the peak says so.

Pure logic: arrays in, :class:`FrfPeak` out (frequencies in Hz, magnitudes in the response's SI unit).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from board_config.json_values import JsonFields

#: points either side of the discrete maximum that a coarse grid's local fit always uses
NEIGHBOURS = 2
#: Sanathanan–Koerner re-weighting passes of the local rational fit
SK_PASSES = 4
#: a local maximum counts as a peak when it stands this factor above the lowest point between it and any higher
#: maximum (or the end of the grid) on both sides
MIN_PROMINENCE = 1.2
#: the local fit counts only when it reproduces the window's complex response this well (relative RMS) ...
MAX_FIT_ERROR = 0.1
#: ... with at least this damping ratio (a "mode" with none is a fit to a peak without a phase swing)
MIN_DAMPING = 1e-3


@dataclass(frozen=True)
class FrfPeak(JsonFields):
    """One resonance peak of a frequency response.

    ``frequency_Hz`` is the natural frequency of the locally fitted mode (|pole| / 2π) — what a mode table
    lists; ``peak_Hz`` is where the fitted |H| is largest (a little below ``frequency_Hz`` for a damped mode);
    ``grid_Hz`` the grid frequency of the largest sample; ``spacing_Hz`` the grid's spacing there (its
    resolution). ``method`` says how the peak was placed."""

    frequency_Hz: float
    damping_ratio: float
    peak_Hz: float
    magnitude: float
    grid_Hz: float
    spacing_Hz: float
    n_points: int
    method: str

    def describe(self) -> str:
        zeta = f", ζ {100 * self.damping_ratio:.1f} %" if math.isfinite(self.damping_ratio) else ""
        return f"{self.frequency_Hz:.4g} Hz{zeta}"


def grid_spacing(f: np.ndarray, i: int) -> float:
    """Spacing of the frequency grid ``f`` at index ``i`` (Hz): the mean of the steps either side."""
    f = np.asarray(f, float)
    steps = [f[j + 1] - f[j] for j in (i - 1, i) if 0 <= j and j + 1 < f.size]
    return float(np.mean(steps)) if steps else math.nan


def local_maxima(mag: np.ndarray, min_prominence: float = MIN_PROMINENCE) -> list[int]:
    """Indices of interior local maxima of ``mag`` that stand ``min_prominence`` times above the lowest point
    between them and a higher maximum (or the grid's end) on each side, largest first."""
    mag = np.asarray(mag, float)
    n = mag.size
    out = []
    for i in range(1, n - 1):
        if not (mag[i] > mag[i - 1] and mag[i] >= mag[i + 1]):
            continue
        bases = []
        for step in (-1, 1):
            j, low = i + step, mag[i]
            while 0 <= j < n and mag[j] <= mag[i]:
                low = min(low, mag[j])
                j += step
            bases.append(low)
        if mag[i] >= min_prominence * max(bases):
            out.append(i)
    return sorted(out, key=lambda k: -mag[k])


def _window(mag: np.ndarray, i: int) -> np.ndarray:
    """The points the local fit uses: the contiguous lobe around ``i`` above half its maximum, and at least
    :data:`NEIGHBOURS` points either side (clipped to the grid); never past a higher neighbouring maximum."""
    n = mag.size
    lo, hi = i, i
    while lo > 0 and mag[lo - 1] >= 0.5 * mag[i] and mag[lo - 1] <= mag[i]:
        lo -= 1
    while hi < n - 1 and mag[hi + 1] >= 0.5 * mag[i] and mag[hi + 1] <= mag[i]:
        hi += 1
    lo, hi = min(lo, max(i - NEIGHBOURS, 0)), max(hi, min(i + NEIGHBOURS, n - 1))
    return np.arange(lo, hi + 1)


def fit_one_mode(f: np.ndarray, h: np.ndarray) -> tuple[float, float, np.ndarray] | None:
    """(ωn rad/s, ζ, numerator coefficients b0, b1[, b2] in the scaled variable) of a one-mode rational fit to the
    complex response ``h`` at ``f`` (Hz), or None when the fit is not a stable, lightly damped mode.

    The variable is scaled by the window's centre frequency so the equations are well conditioned."""
    f, h = np.asarray(f, float), np.asarray(h, complex)
    w0 = 2 * np.pi * float(np.sqrt(f[0] * f[-1]))
    s = 1j * 2 * np.pi * f / w0
    n_num = 3 if f.size >= 6 else 2
    weight = np.ones(f.size)
    a0 = a1 = math.nan
    b = np.zeros(n_num, complex)
    for _ in range(SK_PASSES):
        # unknowns: a0, a1 (real), Re/Im of b0..b(n_num-1); equation  a0 H + a1 H s − Σ b_k s^k = −H s²
        cols = [h, h * s] + [c for k in range(n_num) for c in (-(s ** k), -1j * s ** k)]
        A = np.column_stack(cols) * weight[:, None]
        rhs = -h * s ** 2 * weight
        A_r = np.vstack([A.real, A.imag])
        rhs_r = np.concatenate([rhs.real, rhs.imag])
        sol, *_ = np.linalg.lstsq(A_r, rhs_r, rcond=None)
        a0, a1 = float(sol[0]), float(sol[1])
        b = sol[2::2] + 1j * sol[3::2]
        den = np.abs(s ** 2 + a1 * s + a0)
        if not np.all(den > 0) or not np.all(np.isfinite(den)):
            return None
        weight = 1.0 / den
        weight /= float(np.max(weight))
    if not (a0 > 0 and a1 > 0):
        return None
    wn = math.sqrt(a0)
    zeta = a1 / (2 * wn)
    if not MIN_DAMPING <= zeta < 0.5:
        return None
    fitted = sum(bk * s ** k for k, bk in enumerate(b)) / (s ** 2 + a1 * s + a0)
    if float(np.linalg.norm(fitted - h)) > MAX_FIT_ERROR * float(np.linalg.norm(h)):
        return None  # the points are not one mode and a smooth background (a peak without the phase of one)
    return wn * w0, zeta, b


def _parabola_peak(f: np.ndarray, mag: np.ndarray, i: int) -> tuple[float, float]:
    """(frequency Hz, magnitude) of the vertex of a parabola in log|H| over log f through points i−1, i, i+1."""
    x, y = np.log(f[i - 1:i + 2]), np.log(np.maximum(mag[i - 1:i + 2], 1e-300))
    c2, c1, c0 = np.polyfit(x - x[1], y, 2)
    if not c2 < 0:
        return float(f[i]), float(mag[i])
    xv = float(np.clip(-c1 / (2 * c2), x[0] - x[1], x[2] - x[1]))
    return float(f[i] * np.exp(xv)), float(np.exp(c0 + c1 * xv + c2 * xv ** 2))


def refine_peak(f: np.ndarray, h: np.ndarray, i: int) -> FrfPeak:
    """The peak around the discrete maximum ``i`` of |h| (see the module docstring)."""
    f, h = np.asarray(f, float), np.asarray(h, complex)
    mag = np.abs(h)
    idx = _window(mag, i)
    spacing = grid_spacing(f, i)
    fitted = fit_one_mode(f[idx], h[idx]) if idx.size >= 3 else None
    if fitted is not None:
        wn, zeta, b = fitted
        fn = wn / (2 * np.pi)
        if f[idx[0]] <= fn <= f[idx[-1]]:
            w0 = 2 * np.pi * float(np.sqrt(f[idx[0]] * f[idx[-1]]))
            ff = np.linspace(f[idx[0]], f[idx[-1]], 2001)
            s = 1j * 2 * np.pi * ff / w0
            a0, a1 = (wn / w0) ** 2, 2 * zeta * wn / w0
            model = sum(bk * s ** k for k, bk in enumerate(b)) / (s ** 2 + a1 * s + a0)
            k = int(np.argmax(np.abs(model)))
            return FrfPeak(float(fn), float(zeta), float(ff[k]), float(np.abs(model[k])), float(f[i]), spacing,
                           int(idx.size), f"one-mode rational fit to {idx.size} points")
    if 0 < i < f.size - 1:
        fp, mp = _parabola_peak(f, mag, i)
        return FrfPeak(fp, math.nan, fp, mp, float(f[i]), spacing, 3, "parabola in log|H| over log f (3 points)")
    return FrfPeak(float(f[i]), math.nan, float(f[i]), float(mag[i]), float(f[i]), spacing, 1, "grid maximum")


def find_peaks(f: np.ndarray, h: np.ndarray, max_peaks: int = 3,
               min_prominence: float = MIN_PROMINENCE) -> list[FrfPeak]:
    """The ``max_peaks`` most prominent resonance peaks of the complex response ``h`` at frequencies ``f`` (Hz),
    each placed between the grid's frequencies (see the module docstring); in increasing frequency."""
    f, h = np.asarray(f, float), np.asarray(h, complex)
    if f.size != h.size:
        raise ValueError(f"frequencies and response differ in length ({f.size} vs {h.size})")
    ok = np.isfinite(h) & np.isfinite(f)
    f, h = f[ok], h[ok]
    if f.size < 3:
        return []
    peaks = [refine_peak(f, h, i) for i in local_maxima(np.abs(h), min_prominence)[:max_peaks]]
    return sorted(peaks, key=lambda p: p.frequency_Hz)


def match_peaks(measured: list[FrfPeak], model: list[FrfPeak], max_ratio: float = 1.5
                ) -> list[tuple[FrfPeak, FrfPeak | None]]:
    """Each measured peak with the model peak nearest in log-frequency (None when none is within a factor
    ``max_ratio``)."""
    out: list[tuple[FrfPeak, FrfPeak | None]] = []
    for p in measured:
        best = min(model, key=lambda q: abs(math.log(q.frequency_Hz / p.frequency_Hz)), default=None)
        if best is not None and max(best.frequency_Hz / p.frequency_Hz, p.frequency_Hz / best.frequency_Hz) > max_ratio:
            best = None
        out.append((p, best))
    return out
