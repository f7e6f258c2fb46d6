"""What :func:`workbench.localise.localise` finds: flagged windows, regime and branch tables, error-carrying
bands, the residual against the drive, the hypotheses, gathered in :class:`Localisation`."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np


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
