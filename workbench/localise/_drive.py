"""The residual in time and against the drive: regime labels, the rolling RMS and the windows it flags, the
residual binned against drive amplitude (rising/falling branches), rate and output, and the branch tables."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from workbench.localise._results import AmplitudeRate, BranchStats, Window
from workbench.records import Segment


def drive_rate(t: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(u smoothed over ~10 ms, du/dt)``; the smoothing (edge-replicating) keeps sensor noise on a measured
    drive from flipping the branch at every sample."""
    from scipy.ndimage import uniform_filter1d

    u = np.asarray(u, float)
    k = max(1, round(0.01 / max(float(np.median(np.diff(t))), 1e-12)))
    us = uniform_filter1d(u, size=k, mode="nearest") if k > 1 and u.size > k else u
    return us, np.gradient(us, t)


def drive_regimes(t: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Per-sample labels from the drive: rest (near zero and still), rising, falling, hold (still, not zero)."""
    u = np.asarray(u, float)
    span = float(np.ptp(u))
    if span == 0.0:
        return np.full(u.size, "rest", dtype=object)
    _, du = drive_rate(t, u)
    thr = 0.01 * float(np.max(np.abs(du))) if np.any(du) else 0.0
    lab = np.where(du > thr, "rising", np.where(du < -thr, "falling", "hold")).astype(object)
    lab[(lab == "hold") & (np.abs(u) <= 0.01 * span)] = "rest"
    return lab


def segment_labels(t: np.ndarray, segments: Sequence[Segment], fallback: np.ndarray) -> np.ndarray:
    """Label each sample by the record's segments (later segments win on overlap); uncovered samples keep
    ``fallback``."""
    lab = np.array(fallback, dtype=object)
    for s in segments:
        lab[(t >= s.start_s) & (t < s.end_s)] = s.label
    if segments:  # the last sample belongs to the segment that ends there
        last = [s for s in segments if s.end_s >= t[-1] - 1e-12 and s.start_s < t[-1]]
        if last:
            lab[-1] = last[-1].label
    return lab


def rolling_rms(e: np.ndarray, n: int) -> np.ndarray:
    """Centred rolling RMS over ``n`` samples (edges use the available samples)."""
    n = max(1, int(n))
    c = np.concatenate([[0.0], np.cumsum(np.asarray(e, float) ** 2)])
    i = np.arange(e.size)
    lo = np.clip(i - n // 2, 0, e.size)
    hi = np.clip(i + n - n // 2, 0, e.size)
    return np.sqrt((c[hi] - c[lo]) / np.maximum(hi - lo, 1))


def flagged_windows(t: np.ndarray, e: np.ndarray, rr: np.ndarray, thr: float, labels: np.ndarray, n_win: int,
                    total_sq: float) -> list[Window]:
    """The stretches where the rolling RMS ``rr`` exceeds ``thr`` (gaps under one window merged, blips under half
    a window dropped), each named by the regimes carrying its squared error."""
    flag = rr > thr
    if not flag.any():
        return []
    # merge gaps shorter than one window, drop blips shorter than half a window
    idx = np.flatnonzero(np.diff(np.concatenate([[0], flag.astype(np.int8), [0]])))
    runs = [[int(a), int(b)] for a, b in zip(idx[::2], idx[1::2])]
    merged: list[list[int]] = []
    for a, b in runs:
        if merged and a - merged[-1][1] < n_win:
            merged[-1][1] = b
        else:
            merged.append([a, b])
    out = []
    for a, b in merged:
        if b - a < max(2, n_win // 2):
            continue
        seg = e[a:b]
        # name the window by the regimes carrying its error (not by the ones it merely spans)
        labs, inv = np.unique(labels[a:b].astype(str), return_inverse=True)
        sq = np.bincount(inv, weights=seg ** 2, minlength=labs.size)
        order = np.argsort(-sq)
        regime = " / ".join(labs[j] for j in order[:2] if sq[j] >= 0.2 * sq.sum()) or str(labs[order[0]])
        out.append(Window(float(t[a]), float(t[b - 1]), regime, float(np.max(np.abs(seg))),
                          float(np.sqrt(np.mean(seg ** 2))), float(np.sum(seg ** 2) / total_sq) if total_sq else 0.0))
    return out


def _binned_mean(x: np.ndarray, e: np.ndarray, edges: np.ndarray, min_n: int) -> tuple[np.ndarray, np.ndarray]:
    idx = np.clip(np.digitize(x, edges) - 1, 0, edges.size - 2)
    cnt = np.bincount(idx, minlength=edges.size - 1)
    s = np.bincount(idx, weights=e, minlength=edges.size - 1)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(cnt >= min_n, s / np.maximum(cnt, 1), np.nan)
    return mean, cnt


def amplitude_rate(t: np.ndarray, u: np.ndarray, e: np.ndarray, y: np.ndarray, drive: str, unit: str,
                   sigma: float, n_bins: int = 24) -> AmplitudeRate | None:
    """Residual against drive amplitude (rising / falling branches), drive rate and measured output."""
    u = np.asarray(u, float)
    if np.ptp(u) == 0:
        return None
    _, du = drive_rate(t, u)
    thr = 0.01 * float(np.max(np.abs(du)))
    rise, fall = du > thr, du < -thr
    edges = np.linspace(u.min(), u.max(), n_bins + 1)
    min_n = max(5, int(0.002 * u.size))
    er, _ = _binned_mean(u[rise], e[rise], edges, min_n) if rise.any() else (np.full(n_bins, np.nan), None)
    ef, _ = _binned_mean(u[fall], e[fall], edges, min_n) if fall.any() else (np.full(n_bins, np.nan), None)
    common = np.isfinite(er) & np.isfinite(ef)
    width = edges[1] - edges[0]
    area = float(np.sum((er - ef)[common]) * width) if common.any() else 0.0
    rms_e = float(np.sqrt(np.mean(e ** 2)))
    gap = float(np.sqrt(np.mean((er - ef)[common] ** 2))) if common.any() else 0.0
    loop_index = abs(area) / (float(np.ptp(u)) * rms_e) if rms_e > 0 else 0.0
    # a loop is real when the branch gap is large against both the residual and the noise in a bin mean
    loop = bool(common.sum() >= 3 and gap > 0.25 * rms_e and gap > 4.0 * sigma / np.sqrt(min_n))
    redges = np.linspace(du.min(), du.max(), n_bins + 1) if np.ptp(du) > 0 else np.array([du.min(), du.min() + 1])
    eb, _ = _binned_mean(du, e, redges, min_n)
    yedges = np.linspace(y.min(), y.max(), n_bins + 1) if np.ptp(y) > 0 else np.array([y.min(), y.min() + 1])
    ey, _ = _binned_mean(y, e, yedges, min_n)

    def corr(a: np.ndarray, b: np.ndarray) -> float:
        a, b = a - a.mean(), b - b.mean()
        d = float(np.sqrt(np.einsum("i,i->", a, a) * np.einsum("i,i->", b, b)))
        return float(np.einsum("i,i->", a, b) / d) if d > 0 else 0.0

    return AmplitudeRate(
        drive=drive, unit=unit, u_centres=0.5 * (edges[1:] + edges[:-1]), e_rising=er, e_falling=ef, loop_area=area,
        loop_index=loop_index, branch_gap_rms=gap, loop_detected=loop,
        rate_centres=0.5 * (redges[1:] + redges[:-1]), e_by_rate=eb, rate_corr=corr(du, e),
        amp_corr=corr(np.abs(u - np.median(u)), np.abs(e)), y_centres=0.5 * (yedges[1:] + yedges[:-1]), e_by_y=ey,
    )


def branch_stats(t: np.ndarray, u: np.ndarray, e: np.ndarray, eps: np.ndarray | None) -> list[BranchStats]:
    """Residual statistics on the rising/falling and charging/discharging branches of the drive (a branch must
    cover 5 % of the record)."""
    if np.ptp(u) == 0:
        return []
    us, du = drive_rate(t, u)
    dabs = np.gradient(np.abs(us - np.median(u[: max(2, u.size // 50)])), t)
    thr = 0.01 * float(np.max(np.abs(du)))
    out = []
    for label, mask in (("rising", du > thr), ("falling", du < -thr), ("charging (|drive| rising)", dabs > thr),
                        ("discharging (|drive| falling)", dabs < -thr)):
        if np.count_nonzero(mask) < max(2, 0.05 * u.size):  # a branch must cover 5 % of the record (not a step)
            continue
        em = e[mask]
        ep = eps[mask] if eps is not None else np.array([np.nan])
        ep = ep[np.isfinite(ep)]
        out.append(BranchStats(label, int(mask.sum()), float(np.sqrt(np.mean(em ** 2))), float(em.mean()),
                               float(ep.mean()) if ep.size else float("nan"),
                               float(ep.max()) if ep.size else float("nan")))
    return out
