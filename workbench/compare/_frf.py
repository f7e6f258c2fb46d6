"""The frequency part of ``shm compare``: resonance peaks measured vs model, and a sweep's H1 against the model.

* **FRF table** (:func:`table_peaks`). The measured peaks are placed between the table's frequencies by a local
  one-mode fit (:mod:`workbench.compare._frf_peaks`); the grid's spacing at each peak is reported as its resolution. The
  model is not limited to the table's grid: around each of its discrete maxima its stepped-sine response is
  evaluated at :data:`FINE_POINTS` more frequencies across the two neighbouring cells (same drive and amplitude,
  so the nonlinear plant answers as it does at the table's points), and the same fit places its peak.
* **Sweep** (:func:`sweep_frf`). H1 and coherence of each measured output against the drive
  (:mod:`workbench.compare._frf_estimate`); the model side is the *same estimator* applied to the model's free-run
  response to the same drive (the replay's simulated channel), so what is left of the estimator's bias cancels;
  the linearised model's FRF at rest is drawn for reference. Peaks are located on the frequencies where the
  measured coherence is high.

Frequencies in Hz, responses in the output's SI unit per drive unit.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from plant import PlantModel
from workbench.compare._frf_estimate import COHERENT, EstimatedFrf, h1_estimate
from workbench.compare._frf_peaks import FrfPeak, find_peaks, local_maxima, match_peaks
from workbench.records import FrfRecord
from workbench.simulation import stepped_sine

#: extra model frequencies evaluated across the two grid cells around each of the model's discrete maxima
FINE_POINTS = 12


@dataclass
class PeakComparison:
    """Peaks of one channel, measured and model, paired (nearest in log-frequency)."""

    measured: list[FrfPeak]
    model: list[FrfPeak]
    how_measured: str  # where the measured peaks come from and the resolution there
    how_model: str

    @property
    def pairs(self) -> list[tuple[FrfPeak, FrfPeak | None]]:
        return match_peaks(self.measured, self.model)

    def sentence(self, channel: str) -> str:
        """One line for the findings: each measured resonance against the model's, with the shift."""
        if not self.measured:
            return (f"{channel}: no resonance peak stands out in the measured response "
                    f"({len(self.model)} in the model's).")
        parts = []
        for p, q in self.pairs:
            if q is None:
                parts.append(f"resonance at {p.describe()} measured, none near it in the model")
            else:
                shift = 100.0 * (p.frequency_Hz / q.frequency_Hz - 1.0)
                parts.append(f"resonance at {p.describe()} measured vs {q.describe()} model ({shift:+.1f} %)")
        how = f"{self.how_measured}; {self.how_model}."
        return f"{channel}: " + "; ".join(parts) + ". " + how[:1].upper() + how[1:]

    def to_dict(self) -> dict[str, Any]:
        return {"measured": [p.to_dict() for p in self.measured], "model": [p.to_dict() for p in self.model],
                "how_measured": self.how_measured, "how_model": self.how_model,
                "pairs": [{"measured_Hz": p.frequency_Hz, "model_Hz": q.frequency_Hz if q else None,
                           "shift_pct": 100.0 * (p.frequency_Hz / q.frequency_Hz - 1.0) if q else None}
                          for p, q in self.pairs]}


def _resolution_text(peaks: Sequence[FrfPeak], what: str) -> str:
    if not peaks:
        return what
    cells = "; ".join(f"grid spacing {p.spacing_Hz:.3g} Hz ({100 * p.spacing_Hz / p.grid_Hz:.0f} %) at "
                      f"{p.grid_Hz:.3g} Hz, by a {p.method}" for p in sorted(peaks, key=lambda q: q.frequency_Hz))
    return f"{what}: {cells}"


def fine_model_response(model: PlantModel, record: FrfRecord, output: str, f: np.ndarray, h: np.ndarray,
                        params: np.ndarray | None = None, max_peaks: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """The model's response ``h`` at the table's frequencies ``f`` with :data:`FINE_POINTS` more frequencies
    across the two cells around each of its discrete maxima (stepped sine at the table's drive and amplitude)."""
    extra: list[np.ndarray] = []
    for i in local_maxima(np.abs(h))[:max_peaks]:
        lo, hi = f[max(i - 1, 0)], f[min(i + 1, f.size - 1)]
        extra.append(np.geomspace(lo, hi, FINE_POINTS + 2)[1:-1])
    if not extra:
        return f, h
    fe = np.setdiff1d(np.concatenate(extra), f)
    he = stepped_sine(model, fe, [output], drive=record.drive, amplitude=record.drive_amplitude,
                      bias_v=record.bias_V, params=params)[output]
    ff = np.concatenate([f, fe])
    hh = np.concatenate([h, he])
    order = np.argsort(ff)
    return ff[order], hh[order]


def table_peaks(model: PlantModel, record: FrfRecord, modelled: Mapping[str, np.ndarray],
                outputs: Mapping[str, str], params: np.ndarray | None = None) -> dict[str, PeakComparison]:
    """Per channel of an FRF table: measured peaks placed between the table's frequencies, model peaks from its
    finely evaluated response (see the module docstring). ``modelled[ch]`` is the model's response at the table's
    frequencies, ``outputs[ch]`` the model output it came from."""
    f = record.frequency_Hz
    out = {}
    for ch, resp in record.responses.items():
        meas = find_peaks(f, resp.response)
        ff, hh = fine_model_response(model, record, outputs[ch], f, modelled[ch], params)
        mod = find_peaks(ff, hh)
        out[ch] = PeakComparison(
            meas, mod, _resolution_text(meas, f"measured peaks placed between the table's {f.size} frequencies"),
            f"model evaluated at {FINE_POINTS} more frequencies around each of its peaks")
    return out


@dataclass
class SweepFrf:
    """One channel of a broadband record in the frequency domain: H1 measured and of the model's free run
    (same drive, same estimator), the linearised model's FRF at the same frequencies, and the peaks."""

    channel: str
    unit: str  # SI response unit (output per drive unit)
    drive: str
    measured: EstimatedFrf
    model: EstimatedFrf
    linear: np.ndarray | None
    peaks: PeakComparison
    band_Hz: tuple[float, float]  # frequencies where the measured coherence is high (first, last)
    fit_pct: float  # complex fit of the model's H1 to the measured one over the trusted frequencies
    notes: list[str] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        trusted = self.measured.trusted()
        return {
            "channel": self.channel, "unit": self.unit, "drive": self.drive, "estimator": "H1 (Welch, Hann, 50 %)",
            "resolution_Hz": self.measured.resolution_Hz, "segments": self.measured.n_segments,
            "segment_s": self.measured.segment_s, "coherent_band_Hz": list(self.band_Hz),
            "coherence_threshold": COHERENT, "trusted_frequencies": int(trusted.sum()),
            "complex_fit_pct": self.fit_pct, "peaks": self.peaks.to_dict(), "notes": self.notes,
        }


def _linear_frf(model: PlantModel, output: str, drive: str, f: np.ndarray,
                params: np.ndarray | None) -> np.ndarray | None:
    from plant.linear import INPUT_DIRECTIONS, linearise

    if drive not in INPUT_DIRECTIONS:
        return None
    h = np.full(f.size, np.nan + 0j)
    pos = f > 0  # at 0 Hz the hysteresis' pure integrators make the resolvent singular
    h[pos] = linearise(model, params).frf(f[pos], output, drive)
    return h


def sweep_frf(model: PlantModel, fs: float, drive_name: str, drive_unit: str, drive: np.ndarray,
              channels: Mapping[str, tuple[str, str, np.ndarray, np.ndarray]],
              params: np.ndarray | None = None) -> dict[str, SweepFrf]:
    """H1 of each channel measured and modelled against ``drive`` (``drive_unit``, SI) sampled at ``fs`` Hz.

    ``channels[ch] = (model output, SI unit, measured, simulated)``; see the module docstring."""
    out = {}
    for ch, (output, unit, meas, sim) in channels.items():
        em = h1_estimate(drive, meas, fs)
        es = h1_estimate(drive, sim, fs)
        ok = em.trusted() & np.isfinite(es.h1)
        notes = []
        if ok.sum() < 3:
            notes.append(f"coherence ≥ {COHERENT:g} at fewer than 3 frequencies: the record is not broadband "
                         "enough (or too noisy) for a frequency response")
            band = (math.nan, math.nan)
        else:
            band = (float(em.frequency_Hz[ok][0]), float(em.frequency_Hz[ok][-1]))
        f_ok = em.frequency_Hz[ok]
        meas_peaks = find_peaks(f_ok, em.h1[ok]) if ok.sum() >= 3 else []
        model_peaks = find_peaks(f_ok, es.h1[ok]) if ok.sum() >= 3 else []
        res = f"H1 resolution {em.resolution_Hz:.3g} Hz"
        pc = PeakComparison(meas_peaks, model_peaks,
                            f"measured peaks from H1 where the coherence is ≥ {COHERENT:g} ({res})",
                            "model peaks from the same estimator on its simulated response")
        h, hm = em.h1[ok], es.h1[ok]
        den = float(np.linalg.norm(h))
        fit = 100.0 * (1.0 - float(np.linalg.norm(h - hm)) / den) if den > 0 else math.nan
        lin = _linear_frf(model, output, drive_name, em.frequency_Hz, params)
        ratio = f"{unit}/({drive_unit})" if "/" in drive_unit else f"{unit}/{drive_unit}"
        out[ch] = SweepFrf(ch, ratio, drive_name, em, es, lin, pc, band, fit, notes)
    return out
