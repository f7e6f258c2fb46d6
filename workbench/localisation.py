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
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass, field

import numpy as np

from workbench.records import Segment
from workbench.replay import estimate_noise_std

DEFAULT_THRESHOLD_SIGMA = 3.0
TRANSITION_LABELS = ("rest", "rising", "falling", "hold")


@dataclass(frozen=True)
class Window:
    """A stretch where the rolling RMS residual exceeds the threshold; ``regime`` names the test regime(s) that
    carry at least 20 % of the window's squared error (largest first)."""

    start_s: float
    end_s: float
    regime: str
    peak_abs_error: float  # SI
    rms_error: float  # SI
    share_sq_error: float  # of the whole record's squared error


@dataclass(frozen=True)
class RegimeStats:
    label: str
    duration_s: float
    rms_error: float
    mean_error: float
    share_sq_error: float
    frac_flagged: float
    eps_mean: float
    eps_max: float


@dataclass(frozen=True)
class Band:
    """A frequency band and its share of the residual power above the noise floor."""

    f_lo_Hz: float
    f_hi_Hz: float
    share: float
    rms_error: float  # SI, RMS of the residual content in the band (noise floor removed)
    near: str


@dataclass(frozen=True)
class BranchStats:
    label: str
    n: int
    rms_error: float
    mean_error: float
    eps_mean: float
    eps_max: float


@dataclass
class AmplitudeRate:
    """Residual binned against the drive (rising/falling branches) and against its rate."""

    drive: str
    unit: str
    u_centres: np.ndarray
    e_rising: np.ndarray  # mean residual per bin on the rising branch (NaN where too few samples)
    e_falling: np.ndarray
    loop_area: float  # ∫ (e_rising − e_falling) du over the common range, SI·drive unit
    loop_index: float  # |loop area| / (drive range × RMS residual): 0 none, ≳ 0.1 a visible loop
    branch_gap_rms: float  # RMS of (e_rising − e_falling) over common bins, SI
    loop_detected: bool
    rate_centres: np.ndarray
    e_by_rate: np.ndarray
    rate_corr: float  # correlation of e with du/dt
    amp_corr: float  # correlation of |e| with |u| (Eq. 4-like growth with amplitude)
    y_centres: np.ndarray  # residual vs the measured output (stiffening shows as an odd curve)
    e_by_y: np.ndarray


@dataclass(frozen=True)
class Hypothesis:
    """One reading of the evidence: a class of missing physics, how much of the residual its signature explains
    (``score``: share of the residual variance a small regressor of that class adds beyond a plain gain error), and
    the sentence with the numbers."""

    kind: str
    score: float
    sentence: str


@dataclass
class Localisation:
    channel: str
    unit: str
    noise_std: float
    noise_source: str
    threshold: float
    window_s: float
    windows: list[Window]
    regimes: list[RegimeStats]
    frac_flagged: float
    spectrum_f: np.ndarray
    spectrum_resid: np.ndarray  # one-sided PSD, SI²/Hz
    spectrum_meas: np.ndarray
    noise_psd: float
    bands: list[Band]
    branches: list[BranchStats]
    amp_rate: AmplitudeRate | None
    labels: np.ndarray  # regime label per sample
    rolling_rms: np.ndarray
    findings: list[str] = field(default_factory=list)
    hypotheses: list[Hypothesis] = field(default_factory=list)

    def to_dict(self) -> dict:
        ar = None
        if self.amp_rate is not None:
            ar = {k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in vars(self.amp_rate).items()}
        return {
            "channel": self.channel, "unit": self.unit, "noise_std": self.noise_std, "noise_source": self.noise_source,
            "threshold": self.threshold, "window_s": self.window_s, "frac_flagged": self.frac_flagged,
            "windows": [asdict(w) for w in self.windows], "regimes": [asdict(r) for r in self.regimes],
            "bands": [asdict(b) for b in self.bands], "branches": [asdict(b) for b in self.branches],
            "amplitude_rate": ar, "noise_psd": self.noise_psd, "findings": self.findings,
            "hypotheses": [asdict(h) for h in self.hypotheses],
        }


# ----------------------------------------------------------------------------------------------------------------


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


def _windows(t: np.ndarray, e: np.ndarray, rr: np.ndarray, thr: float, labels: np.ndarray, n_win: int,
             total_sq: float) -> list[Window]:
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


def model_features(model, params=None) -> list[tuple[float, str]]:
    """(frequency Hz, label) of the model's linear modes at rest and its real poles (e.g. the RC pole)."""
    from workbench.replay import linearise

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


def _spectrum(t: np.ndarray, e: np.ndarray, y: np.ndarray, sigma: float, features, drive_f
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


def _branches(t: np.ndarray, u: np.ndarray, e: np.ndarray, eps: np.ndarray | None) -> list[BranchStats]:
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
    windows = _windows(t, e, rr, thr, labels, n_win, total_sq)
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
    f, pe, py, npsd, bands = _spectrum(t, e, y, sigma, features, drive_f)
    ar = amplitude_rate(t, u, e, y, drive_name, drive_unit, sigma)
    loc = Localisation(
        channel=channel, unit=unit, noise_std=sigma, noise_source=source, threshold=thr, window_s=n_win * dt,
        windows=sorted(windows, key=lambda w: -w.share_sq_error)[:20], regimes=regimes,
        frac_flagged=float(np.mean(flagged)), spectrum_f=f, spectrum_resid=pe, spectrum_meas=py, noise_psd=npsd,
        bands=bands, branches=_branches(t, u, e, eps), amp_rate=ar, labels=labels, rolling_rms=rr,
    )
    loc.hypotheses = hypotheses(t, e, np.asarray(simulated, float), u, y, sigma, unit, features, drive_name)
    loc.findings = _findings(loc, t, e, sigma)
    return loc


# ----------------------------------------------------------------------------------------------------------------
# one reading of the evidence: hypothesis classes ranked by what their signature explains

HYPOTHESIS_KINDS = ("sign-asymmetric", "amplitude-dependent", "rate-dependent", "switching at zero crossings",
                    "time-varying", "shifted dynamics", "sensor-only (static map)")


def _r2(e: np.ndarray, cols: Sequence[np.ndarray]) -> float:
    """Share of the variance of ``e`` explained by least squares on ``cols`` (plus a constant)."""
    X = np.column_stack([np.ones(e.size), *cols])
    norms = np.linalg.norm(X, axis=0)
    norms[norms == 0] = 1.0
    coef, *_ = np.linalg.lstsq(X / norms, e, rcond=None)
    r = e - (X / norms) @ coef
    ss = float(np.sum((e - e.mean()) ** 2))
    return 1.0 - float(np.sum(r * r)) / ss if ss > 0 else 0.0


def _rms(a: np.ndarray) -> float:
    return float(np.sqrt(np.mean(a * a))) if a.size else float("nan")


def mode_shift(t: np.ndarray, u: np.ndarray, y: np.ndarray, yhat: np.ndarray, f_mode: float
               ) -> tuple[float, float] | None:
    """(measured, modelled) peak frequency (Hz) of the drive → response transfer function near ``f_mode``, from
    Welch cross-spectra; None when the drive carries too little power there to tell."""
    from scipy.signal import csd, welch

    dt = float(np.median(np.diff(t)))
    fs = 1.0 / dt
    if f_mode <= 0 or f_mode > 0.4 * fs:
        return None
    nper = int(max(256, u.size // 2))
    if u.size < 256 or np.ptp(u) == 0:
        return None
    f, puu = welch(u - u.mean(), fs=fs, nperseg=nper)
    band = (f > 0.6 * f_mode) & (f < 1.5 * f_mode)
    if band.sum() < 5 or puu[band].sum() < 1e-6 * puu[1:].sum():
        return None
    out = []
    for resp in (y, yhat):
        _, pyu = csd(u - u.mean(), resp - resp.mean(), fs=fs, nperseg=nper)
        h = np.abs(pyu[band]) / np.maximum(puu[band], 1e-300)
        k = int(np.argmax(h))
        if k == 0 or k == h.size - 1:
            return None
        a, b, c = np.log(h[k - 1:k + 2] + 1e-300)
        shift = 0.5 * (a - c) / (a - 2 * b + c) if (a - 2 * b + c) != 0 else 0.0
        fb = f[band]
        out.append(float(fb[k] + shift * (fb[1] - fb[0])))
    return out[0], out[1]


def hypotheses(t: np.ndarray, e: np.ndarray, yhat: np.ndarray, u: np.ndarray, y: np.ndarray, sigma: float,
               unit: str = "", features: Sequence[tuple[float, str]] = (), drive_name: str = "drive"
               ) -> list[Hypothesis]:
    """Rank the hypothesis classes (:data:`HYPOTHESIS_KINDS`) by the share of the residual variance their
    signature adds beyond a plain gain error (e ≈ a + b·ŷ), best first; none when the residual is noise."""
    t, e, yhat, u = (np.asarray(a, float) for a in (t, e, yhat, u))
    if e.size < 20 or _rms(e) <= 1.5 * sigma:
        return []
    rel_t = (t - t[0]) / max(float(t[-1] - t[0]), 1e-12)
    yc = yhat - yhat[0]
    v = np.gradient(yhat, t)
    acc = np.gradient(v, t)
    vs = max(_rms(v), 1e-300)
    base = _r2(e, [yc])
    out: list[Hypothesis] = []
    # sign-asymmetric: an even function of the deflection
    pos, neg = yc > 0.05 * np.ptp(yc), yc < -0.05 * np.ptp(yc)
    sc = _r2(e, [yc, np.abs(yc)]) - base
    if pos.sum() > 0.1 * e.size and neg.sum() > 0.1 * e.size:
        ep, en = _rms(e[pos]), _rms(e[neg])
        big, small = ("positive", "negative") if ep >= en else ("negative", "positive")
        out.append(Hypothesis("sign-asymmetric", sc, f"the error is {max(ep, en) / max(min(ep, en), 1e-300):.2g}× "
                              f"larger for {big} than for {small} deflection (RMS {_fmt(max(ep, en), unit)} vs "
                              f"{_fmt(min(ep, en), unit)}): sign-dependent physics (one-sided contact, polarisation-"
                              "dependent coupling, asymmetric sensor)"))
    # amplitude-dependent: odd growth with the deflection
    q = np.abs(yc)
    hi, lo = q >= np.quantile(q, 2 / 3), q <= np.quantile(q, 1 / 3)
    ratio_hi = _rms(e[hi]) / max(_rms(yc[hi]), 1e-300)
    ratio_lo = _rms(e[lo]) / max(_rms(yc[lo]), 1e-300)
    out.append(Hypothesis("amplitude-dependent", _r2(e, [yc, yc ** 3]) - base,
                          f"the relative error is {ratio_hi / max(ratio_lo, 1e-300):.2g}× larger in the largest third "
                          f"of the deflection than in the smallest ({100 * ratio_hi:.3g} % vs {100 * ratio_lo:.3g} %): "
                          "amplitude-dependent stiffness or damping (Duffing, drag, saturation)"))
    # rate-dependent
    fast, slow = np.abs(v) >= np.quantile(np.abs(v), 2 / 3), np.abs(v) <= np.quantile(np.abs(v), 1 / 3)
    out.append(Hypothesis("rate-dependent", _r2(e, [yc, v, np.abs(v) * v / vs]) - base,
                          f"the error follows the velocity: RMS {_fmt(_rms(e[fast]), unit)} in the fastest third of "
                          f"the motion vs {_fmt(_rms(e[slow]), unit)} in the slowest (damping, drag, a lag)"))
    # switching at zero crossings of the velocity (a ±g square wave)
    sw = np.tanh(v / (0.01 * vs))
    sc_sw = _r2(e, [yc, v, sw]) - _r2(e, [yc, v])
    coef = float(np.dot(e - e.mean(), sw - sw.mean()) / max(np.dot(sw - sw.mean(), sw - sw.mean()), 1e-300))
    out.append(Hypothesis("switching at zero crossings", sc_sw,
                          f"the residual switches by ±{_fmt(abs(coef), unit)} each time the motion reverses (a square "
                          f"wave on the sign of the velocity explains {100 * max(sc_sw, 0):.0f} % of it beyond a "
                          "viscous term): dry friction, a clearance or backlash"))
    # time-varying
    thirds = np.array_split(np.arange(e.size), 3)
    # relative to the modelled response in each third (a sweep's response changes size with frequency)
    r_first = _rms(e[thirds[0]]) / max(_rms(yc[thirds[0]]), 1e-300)
    r_last = _rms(e[thirds[-1]]) / max(_rms(yc[thirds[-1]]), 1e-300)
    steady = dominant_frequency(t, u) is not None or np.ptp(u) == 0
    out.append(Hypothesis("time-varying", _r2(e, [yc, rel_t * yc, rel_t]) - base,
                          f"the residual grows in time: {100 * r_first:.3g} % of the response in the first third of "
                          f"the record, {100 * r_last:.3g} % in the last ({r_last / max(r_first, 1e-300):.2g}×): "
                          "a gain or zero drifting during the test (temperature, creep, a warming sensor)"
                          + ("" if steady else " — but the drive changes its character in time (a sweep: time is also "
                             "frequency); confirm on a record with a steady drive")))
    # shifted dynamics
    sc_dyn = _r2(e, [yc, v, acc]) - base
    words = "the dynamics are shifted: the error is in phase with the modelled velocity/acceleration"
    modes = [f for f, lab in features if lab.startswith("mode")]
    if modes:
        ms = mode_shift(t, u, y, yhat, modes[0])
        if ms is not None and abs(ms[0] / ms[1] - 1) > 0.01:
            rel = ms[0] / ms[1] - 1
            words = (f"measured mode 1 is {abs(100 * rel):.2g} % {'lower' if rel < 0 else 'higher'} than modelled "
                     f"({ms[0]:.3g} vs {ms[1]:.3g} Hz): a stiffness or mass is wrong, or something "
                     f"{'softens' if rel < 0 else 'stiffens'} the structure")
            sc_dyn = max(sc_dyn, 0.0) + 0.05
    out.append(Hypothesis("shifted dynamics", sc_dyn, words))
    # sensor-only: a memoryless map of the deflection explains it
    # sensor-only: a memoryless map of the deflection explains it better than any class above
    stat = _r2(e, [yc, yc ** 2, yc ** 3])
    others = max(base + h.score for h in out)
    out.append(Hypothesis("sensor-only (static map)", stat - others,
                          f"a static map of the deflection (offset + gain + quadratic + cubic) explains "
                          f"{100 * stat:.0f} % of the residual: a sensor error (gain, nonlinearity, offset) or a "
                          "static stiffness, not missing dynamics"))
    out.sort(key=lambda h: -h.score)
    if stat > 0.95 and out[0].kind != "sensor-only (static map)":
        top = out[0]
        out[0] = Hypothesis(top.kind, top.score, top.sentence + f"; a static map of the deflection explains "
                            f"{100 * stat:.0f} % of it — if the test is dynamic, suspect the sensor")
    return [Hypothesis(h.kind, round(float(h.score), 4), h.sentence) for h in out]


def _fmt(x: float, unit: str) -> str:
    if unit == "m":
        return f"{x * 1e6:.3g} µm" if abs(x) < 1e-3 else f"{x * 1e3:.3g} mm"
    return f"{x:.3g} {unit}".strip()


def _findings(loc: Localisation, t: np.ndarray, e: np.ndarray, sigma: float) -> list[str]:
    out = []
    rms = float(np.sqrt(np.mean(e ** 2)))
    u = loc.unit
    if loc.frac_flagged == 0:
        out.append(f"{loc.channel}: residual RMS {_fmt(rms, u)} against noise σ {_fmt(sigma, u)}; no window exceeds "
                   f"{loc.threshold / max(sigma, 1e-300):.0f}σ — no localised failure.")
        return out
    out.append(f"{loc.channel}: residual RMS {_fmt(rms, u)} against noise σ {_fmt(sigma, u)}; "
               f"{loc.frac_flagged * 100:.0f} % of the record exceeds {_fmt(loc.threshold, u)} "
               f"({len(loc.windows)} window{'s' if len(loc.windows) != 1 else ''}).")
    if loc.hypotheses and loc.hypotheses[0].score > 0.02:
        h = loc.hypotheses[0]
        nxt = [x for x in loc.hypotheses[1:3] if x.score > 0.02]
        out.append(f"Most likely: {h.kind} — {h.sentence}"
                   + (f". Next: {', '.join(f'{x.kind} ({100 * x.score:.0f} %)' for x in nxt)}" if nxt else "")
                   + f" (share of the residual its signature explains beyond a gain error: {100 * h.score:.0f} %).")
    reg = sorted(loc.regimes, key=lambda r: -r.share_sq_error)
    top = [r for r in reg if r.share_sq_error >= 0.1][:3]
    if top:
        out.append("Error by regime: " + "; ".join(
            f"'{r.label}' carries {r.share_sq_error * 100:.0f} % of the squared error in "
            f"{r.duration_s:.3g} s (RMS {_fmt(r.rms_error, u)})" for r in top) + ".")
    mean_e = float(np.mean(e))
    if mean_e ** 2 > 0.5 * rms ** 2:
        means = [r.mean_error for r in loc.regimes if r.duration_s > 0]
        if all(abs(m - mean_e) <= 0.3 * abs(mean_e) for m in means):
            out.append(f"The residual is mostly a constant offset: mean {_fmt(mean_e, u)} "
                       f"({mean_e ** 2 / rms ** 2 * 100:.0f} % of the squared error), the same in every regime — "
                       "a sensor zero/offset rather than a missing dynamic effect.")
        else:
            out.append(f"The residual is mostly static (its mean {_fmt(mean_e, u)} carries "
                       f"{mean_e ** 2 / rms ** 2 * 100:.0f} % of the squared error) but differs between regimes ("
                       + ", ".join(f"'{r.label}' {_fmt(r.mean_error, u)}" for r in loc.regimes[:4])
                       + "): an error that follows the drive level (static gain, creep, hysteresis), not a sensor "
                         "offset.")
    if top:
        # a slow trend inside the regime that carries most of the error: drift (creep, leakage, temperature)
        k = loc.labels == top[0].label
        if np.count_nonzero(k) > 10:
            tk, ek = t[k], e[k]
            a = np.polyfit(tk - tk[0], ek, 1)
            fit = np.polyval(a, tk - tk[0])
            ss = float(np.sum((ek - ek.mean()) ** 2))
            r2 = 1.0 - float(np.sum((ek - fit) ** 2)) / ss if ss > 0 else 0.0
            change = float(a[0] * (tk[-1] - tk[0]))
            if r2 > 0.5 and abs(change) > 3.0 * sigma:
                out.append(f"In '{top[0].label}' the error drifts by {_fmt(change, u)} over {tk[-1] - tk[0]:.3g} s "
                           f"(a straight line explains {r2 * 100:.0f} % of its variation): slow dynamics the model "
                           "lacks — piezo creep, dielectric leakage, thermal drift.")
    if len(top) > 1 and max(r.rms_error for r in reg) < 1.3 * min(r.rms_error for r in reg if r.duration_s > 0):
        out.append("The error is spread evenly over the regimes (not localised in time).")
    if loc.bands:
        out.append("Error-carrying bands: " + "; ".join(
            ("0 Hz (offset)" if b.f_hi_Hz == 0 else f"{b.f_lo_Hz:.3g}–{b.f_hi_Hz:.3g} Hz") + f" {b.share * 100:.0f} %"
            + (f" ({b.near})" if b.near and b.f_hi_Hz > 0 else "") for b in loc.bands[:4]) + ".")
    ar = loc.amp_rate
    if ar is not None:
        if ar.loop_detected:
            out.append(f"Residual vs {ar.drive}: the rising and falling branches differ by {_fmt(ar.branch_gap_rms, u)}"
                       f" RMS at the same drive level (loop index {ar.loop_index:.2f}) — a hysteresis loop the model "
                       "does not reproduce.")
        if ar.amp_corr >= 0.5:
            out.append(f"|error| grows with |{ar.drive}| (correlation {ar.amp_corr:.2f}): amplitude-dependent error "
                       "(Eq. 4 behaviour; stiffening, damping or hysteresis width).")
        if abs(ar.rate_corr) >= 0.5:
            out.append(f"Error follows the drive rate (correlation {ar.rate_corr:.2f}): rate-dependent behaviour "
                       "(damping, RC dynamics, creep) or a lag.")
    br = {b.label: b for b in loc.branches}
    c, d = br.get("charging (|drive| rising)"), br.get("discharging (|drive| falling)")
    if c and d and max(c.rms_error, d.rms_error) > 1.5 * min(c.rms_error, d.rms_error):
        worse = "charging" if c.rms_error > d.rms_error else "discharging"
        out.append(f"Worse while {worse}: RMS {_fmt(c.rms_error, u)} charging vs {_fmt(d.rms_error, u)} "
                   "discharging.")
    return out
