"""Frequency responses estimated from broadband time records (a sweep): the H1 estimator and coherence.

    H1(f) = G_xy(f) / G_xx(f),      γ²(f) = |G_xy|² / (G_xx G_yy)

with x the drive and y a measured output, the auto- and cross-spectral densities averaged over Hann-windowed,
half-overlapping segments (Welch; ``scipy.signal.csd`` / ``welch`` / ``coherence``). H1 is unbiased by noise on
the output; the coherence γ² says where the estimate can be trusted (near 1: the output is the drive's linear
response; low: noise, nonlinearity or no drive energy at that frequency). The segments cover the whole record:
the signals (mean removed) are padded with zeros to a whole number of segment steps, so a sweep's last
frequencies are not dropped. The frequency resolution is ``fs / nperseg``.

For a swept sine the averaged spectra are sums over the segments each frequency was swept through, so H1 is
the sweep's linear response wherever the drive had energy; the same estimator applied to the model's simulated
output (what ``shm compare`` does) cancels what remains of the estimator's own bias.

Pure logic: arrays in, :class:`EstimatedFrf` out (SI).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: default segment length (s): long enough to resolve a mode with a few percent damping (≈ 0.1 Hz at 1 kHz)
DEFAULT_SEGMENT_S = 8.0
#: the drive has usable energy where its spectral density exceeds this fraction of its largest value
DRIVE_FLOOR = 1e-4
#: coherence above which an H1 estimate counts as trusted
COHERENT = 0.9


@dataclass
class EstimatedFrf:
    """H1 and coherence of one output against the drive; ``driven`` marks frequencies where the drive had
    energy (its PSD above :data:`DRIVE_FLOOR` of its maximum)."""

    frequency_Hz: np.ndarray
    h1: np.ndarray  # complex, output unit per drive unit (SI)
    coherence: np.ndarray
    driven: np.ndarray  # bool
    resolution_Hz: float
    n_segments: int
    segment_s: float

    def trusted(self, min_coherence: float = COHERENT) -> np.ndarray:
        """Frequencies (mask) where the drive had energy and the coherence is at least ``min_coherence``."""
        return self.driven & (self.coherence >= min_coherence) & (self.frequency_Hz > 0)


def segment_length(n_samples: int, fs: float, segment_s: float = DEFAULT_SEGMENT_S) -> int:
    """Samples per segment: the power of two nearest ``segment_s`` seconds, at most a quarter of the record
    (so at least ~7 half-overlapping segments average) and at least 64."""
    if n_samples < 64:
        raise ValueError(f"a record of {n_samples} samples is too short for a spectral estimate (at least 64)")
    target = max(64.0, segment_s * fs)
    n = 2 ** round(math.log2(target))
    while n > 64 and n > n_samples // 4:
        n //= 2
    return max(64, min(n, n_samples))


def _padded(x: np.ndarray, nperseg: int) -> np.ndarray:
    step = nperseg // 2
    n = x.size
    k = max(0, math.ceil((n - nperseg) / step))
    total = nperseg + k * step
    return np.concatenate([x - float(np.mean(x)), np.zeros(total - n)])


def h1_estimate(x: np.ndarray, y: np.ndarray, fs: float, nperseg: int | None = None,
                segment_s: float = DEFAULT_SEGMENT_S) -> EstimatedFrf:
    """H1 and coherence of ``y`` (output) against ``x`` (drive), both sampled at ``fs`` Hz (see the module
    docstring). ``nperseg`` defaults to :func:`segment_length`."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    if x.shape != y.shape or x.ndim != 1:
        raise ValueError(f"drive and output must be 1-D of the same length, got {x.shape} and {y.shape}")
    if not (fs > 0 and math.isfinite(fs)):
        raise ValueError(f"sample rate must be positive, got {fs}")
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(y))):
        raise ValueError("drive and output must be finite")
    n = nperseg if nperseg is not None else segment_length(x.size, fs, segment_s)
    xp, yp = _padded(x, n), _padded(y, n)
    kw = {"fs": fs, "nperseg": n, "noverlap": n // 2, "window": "hann"}
    from scipy import signal  # here, not at the top: a second of import that shm diagnose and a worker never use

    f, gxy = signal.csd(xp, yp, **kw)
    _, gxx = signal.welch(xp, **kw)
    _, gyy = signal.welch(yp, **kw)
    peak = float(np.max(gxx)) if gxx.size else 0.0
    driven = gxx > DRIVE_FLOOR * peak if peak > 0 else np.zeros(f.size, bool)
    with np.errstate(divide="ignore", invalid="ignore"):
        h1 = np.where(driven, gxy / np.where(gxx > 0, gxx, 1.0), np.nan + 0j)
        coh = np.where((gxx > 0) & (gyy > 0), np.abs(gxy) ** 2 / (gxx * gyy), 0.0)
    n_seg = 1 + (xp.size - n) // (n // 2)
    return EstimatedFrf(f, h1, np.clip(coh, 0.0, 1.0), driven, fs / n, n_seg, n / fs)
