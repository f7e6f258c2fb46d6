"""Hold a model against one record: replay, metrics, residual tests, localisation, and plain-words findings.

This module only assembles the pieces (:mod:`workbench.simulation._replay`, :mod:`workbench.compare._metrics`,
:mod:`workbench.compare._residual_tests`, :mod:`workbench.localise._localise`);
:mod:`workbench.compare._report` renders the result.

    from workbench.compare import compare
    cmp = compare(model, record)            # a Comparison (time record) or FrfComparison (FRF table)
    cmp.verdicts()                          # {channel: "adequate" | "fails"}
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from board_config import load_monitor_settings
from board_config.error_law import normalised_error
from plant import PlantModel
from workbench.compare._frf import PeakComparison, SweepFrf, sweep_frf, table_peaks
from workbench.compare._metrics import (
    ChannelMetrics,
    FrfMetrics,
    channel_metrics,
    fit_percent,
    frf_metrics,
    nrmse,
)
from workbench.compare._residual_tests import DEFAULT_LAGS, DEFAULT_LEVEL, ResidualTests, residual_tests
from workbench.localise import Localisation, localise, model_features
from workbench.records import FrfRecord, Record
from workbench.simulation import (
    DEFAULT_HORIZON_S,
    DEFAULT_INTERVAL_S,
    FrfReplay,
    Replay,
    SimulationFailed,
    model_output_for,
    replay,
    replay_frf,
)


@dataclass(frozen=True)
class CompareOptions:
    """Settings of a comparison (SI). ``eq4_given`` maps channel -> (e0, kerr); z3 defaults to the paper's monitor
    values (Table 3 / Sec. 4.1: 0.75 mm, 0.075)."""

    skip_s: float = 0.0
    level: float = DEFAULT_LEVEL
    max_lag: int = DEFAULT_LAGS
    decimate: int = 1
    threshold_sigma: float = 3.0
    window_s: float | None = None
    predict: bool = True
    horizon_s: float = DEFAULT_HORIZON_S
    interval_s: float = DEFAULT_INTERVAL_S
    eq4_given: Mapping[str, tuple[float, float]] | None = None
    #: frequency-domain view of a time record (H1 and coherence vs the model); None: for sweeps only
    frf: bool | None = None


@dataclass
class PredictionMetrics:
    label: str
    fit_pct: float
    nrmse: float
    rmse: float


@dataclass
class Comparison:
    """Model against a time record (see the module docstring)."""

    record: Record
    replay: Replay
    options: CompareOptions
    metrics: dict[str, ChannelMetrics]
    prediction: dict[str, PredictionMetrics]
    tests: dict[str, ResidualTests]
    localisation: dict[str, Localisation]
    eps: dict[str, np.ndarray]  # normalised error ε(t) (Eq. 5) per channel, given constants if any, else fitted
    eps_source: dict[str, str]
    features: list[tuple[float, str]]
    findings: dict[str, list[str]] = field(default_factory=dict)
    wall_s: dict[str, float] = field(default_factory=dict)
    frf: dict[str, SweepFrf] | None = None  # the record in the frequency domain (a sweep, or on request)

    kind = "time"

    def verdicts(self) -> dict[str, str]:
        """Per channel: ``adequate`` (every residual test passes and nothing exceeds the localisation threshold)
        or ``fails``."""
        out = {}
        for ch, rt in self.tests.items():
            ok = rt.adequate is not False and not self.localisation[ch].windows
            out[ch] = "adequate" if ok else "fails"
        return out

    def to_dict(self) -> dict[str, Any]:
        rec, rep = self.record, self.replay
        return {
            "record": rec.path, "kind": "time", "test": rec.test, "duration_s": rec.duration_s,
            "sample_rate_Hz": rec.sample_rate_Hz, "n_samples": rec.n_samples, "drive": rep.drive_name,
            "model": {"label": rep.model_label, "parameter_set": rep.model.params.name,
                      "effects": list(rep.model.effect_names)},
            "options": {k: v for k, v in vars(self.options).items() if k != "eq4_given"},
            "verdicts": self.verdicts(),
            "metrics": {ch: m.to_dict() for ch, m in self.metrics.items()},
            "prediction": {ch: vars(p) for ch, p in self.prediction.items()},
            "prediction_method": rep.prediction.method if rep.prediction else rep.prediction_note,
            "eps_source": self.eps_source,
            "residual_tests": {ch: rt.to_dict() for ch, rt in self.tests.items()},
            "localisation": {ch: loc.to_dict() for ch, loc in self.localisation.items()},
            "model_features": [{"frequency_Hz": f, "label": lab} for f, lab in self.features],
            **({"frequency_response": {ch: s.to_dict() for ch, s in self.frf.items()}} if self.frf else {}),
            "findings": self.findings, "wall_s": self.wall_s,
        }


@dataclass
class FrfComparison:
    """Model against a frequency-response table."""

    record: FrfRecord
    replay: FrfReplay
    metrics: dict[str, FrfMetrics]
    bad_bands: dict[str, list[tuple[float, float, float, float]]]  # (f_lo, f_hi, max |dB|, max |deg|)
    features: list[tuple[float, str]]
    findings: dict[str, list[str]] = field(default_factory=dict)
    wall_s: dict[str, float] = field(default_factory=dict)
    peaks: dict[str, PeakComparison] = field(default_factory=dict)  # resonances placed between the grid's points

    kind = "frf"

    def verdicts(self) -> dict[str, str]:
        return {ch: "adequate" if not bands else "fails" for ch, bands in self.bad_bands.items()}

    def to_dict(self) -> dict[str, Any]:
        rep = self.replay
        return {
            "record": self.record.path, "kind": "frf", "test": "frf", "drive": self.record.drive,
            "drive_amplitude": self.record.drive_amplitude, "frequency_Hz": self.record.frequency_Hz,
            "model": {"label": rep.model_label, "parameter_set": rep.model.params.name,
                      "effects": list(rep.model.effect_names)},
            "verdicts": self.verdicts(), "metrics": {ch: vars(m) for ch, m in self.metrics.items()},
            "bad_bands": {ch: [{"f_lo_Hz": a, "f_hi_Hz": b, "max_amp_err_dB": c, "max_phase_err_deg": d}
                               for a, b, c, d in v] for ch, v in self.bad_bands.items()},
            "residual_tests": "not applicable to a frequency-response table (no time series)",
            "model_features": [{"frequency_Hz": f, "label": lab} for f, lab in self.features],
            "peaks": {ch: pc.to_dict() for ch, pc in self.peaks.items()},
            "findings": self.findings, "wall_s": self.wall_s,
        }


def _given(options: CompareOptions, channel: str) -> tuple[float, float] | None:
    if options.eq4_given is not None and channel in options.eq4_given:
        return options.eq4_given[channel]
    if channel == "z3":
        mon = load_monitor_settings()
        return (mon.e0z, mon.kerr_z)
    return None


def compare(model: PlantModel, record: Record | FrfRecord, options: CompareOptions | None = None,
            params: np.ndarray | None = None) -> Comparison | FrfComparison:
    """Compare ``model`` (see :func:`workbench.simulation.model_for`) with ``record``."""
    options = options or CompareOptions()
    if isinstance(record, FrfRecord):
        return _compare_frf(model, record, params)
    wall: dict[str, float] = {}
    t0 = time.perf_counter()
    rep = replay(model, record, params=params, predict=options.predict, horizon_s=options.horizon_s,
                 interval_s=options.interval_s)
    wall.update(rep.wall_s)
    t1 = time.perf_counter()
    features = model_features(model, params)
    mon = load_monitor_settings()
    metrics, pred, tests, locs, eps, eps_src, findings = {}, {}, {}, {}, {}, {}, {}
    skip = rep.t >= rep.t[0] + options.skip_s
    for ch, cr in rep.channels.items():
        given = _given(options, ch)
        m = channel_metrics(ch, cr.unit, rep.t, cr.measured, cr.simulated, skip_s=options.skip_s, given=given,
                            eps_th=mon.eps_th)
        metrics[ch] = m
        e0k = (m.eq4_given.e0, m.eq4_given.kerr) if m.eq4_given else (m.eq4_fitted.e0, m.eq4_fitted.kerr)
        eps[ch] = normalised_error(cr.simulated, cr.measured, *e0k)
        eps_src[ch] = (f"given e0 = {e0k[0]:.3g} {cr.unit}, kerr = {e0k[1]:.3g}" if m.eq4_given else
                       f"fitted per Eq. 4: e0 = {e0k[0]:.3g} {cr.unit}, kerr = {e0k[1]:.3g}")
        if rep.prediction is not None and ch in rep.prediction.predicted:
            pm, pp = rep.prediction.measured[ch], rep.prediction.predicted[ch]
            k = rep.prediction.t >= rep.t[0] + options.skip_s
            pred[ch] = PredictionMetrics(rep.prediction.label, fit_percent(pm[k], pp[k]), nrmse(pm[k], pp[k]),
                                         float(np.sqrt(np.mean((pm[k] - pp[k]) ** 2))))
        tests[ch] = residual_tests(cr.residual[skip], rep.drive[skip], channel=ch, input_name=rep.drive_name,
                                   level=options.level, max_lag=options.max_lag, decimate=options.decimate)
        locs[ch] = localise(rep.t[skip], cr.measured[skip], cr.simulated[skip], rep.drive[skip], channel=ch,
                            unit=cr.unit, drive_name=rep.drive_name, drive_unit=rep.drive_unit,
                            segments=record.segments, noise_std=cr.noise_std, eps=eps[ch][skip],
                            threshold_sigma=options.threshold_sigma, window_s=options.window_s, features=features)
        findings[ch] = _findings(ch, m, pred.get(ch), tests[ch], locs[ch])
        if record.gaps:  # lost samples (docs/records.md): left out of the comparison, and said
            findings[ch].append(record.gap_note() + ".")
    wall["analyse_s"] = time.perf_counter() - t1
    frf = None
    if options.frf or (options.frf is None and record.test == "sweep"):
        t2 = time.perf_counter()
        try:
            frf = sweep_frf(model, record.sample_rate_Hz, rep.drive_name, rep.drive_unit, rep.drive,
                            {ch: (cr.model_output, cr.unit, cr.measured, cr.simulated)
                             for ch, cr in rep.channels.items()}, params)
        except ValueError as exc:  # too short for a spectral estimate: said, not failed
            for ch in rep.channels:
                findings[ch].append(f"No frequency response of {ch}: {exc}.")
        for ch, sf in (frf or {}).items():
            findings[ch].append(_frf_finding(ch, rep.drive_name, sf))
            findings[ch].extend(sf.notes)
        wall["frf_s"] = time.perf_counter() - t2
    wall["compare_s"] = time.perf_counter() - t0
    return Comparison(record, rep, options, metrics, pred, tests, locs, eps, eps_src, features, findings, wall,
                      frf)


def _frf_finding(ch: str, drive: str, sf: SweepFrf) -> str:
    if sf.band_Hz[0] != sf.band_Hz[0]:  # no coherent band (NaN)
        return f"Frequency domain (H1 of {ch} against {drive}): no frequency where the coherence is high."
    return (f"Frequency domain (H1 of {ch} against {drive}): complex fit {sf.fit_pct:.1f} % where the coherence is "
            f"high ({sf.band_Hz[0]:.3g}–{sf.band_Hz[1]:.3g} Hz); " + sf.peaks.sentence(ch))


def _findings(ch: str, m: ChannelMetrics, p: PredictionMetrics | None, rt: ResidualTests, loc: Localisation
              ) -> list[str]:
    out = [f"{ch}: free-run fit {m.fit_pct:.2f} %" + (f", {p.label.split(' (')[0]} fit {p.fit_pct:.2f} %" if p else "")
           + "."]
    # one reading of the evidence first: the most likely hypothesis class, in numbers (localisation ranks them)
    lead = [f for f in loc.findings if f.startswith("Most likely:")]
    out.extend(lead)
    if p is not None and m.rmse > 0 and m.rmse > 2 * loc.noise_std:
        removed = 1.0 - p.rmse / m.rmse
        horizon = p.label.split("(")[1].split(",")[0]
        if removed >= 0.8:
            out.append(f"The observer's corrections remove {100 * removed:.0f} % of the RMS error ({horizon}): the "
                       "error is slow or static (offset, drift, static gain, low-frequency hysteresis) rather than in "
                       "the fast dynamics.")
        elif removed >= 0.4:
            out.append(f"The observer's corrections remove {100 * removed:.0f} % of the RMS error ({horizon}): part "
                       "of it is slow or static, but the rest survives the corrections — the fast dynamics (modes, "
                       "damping, RC pole) are also wrong.")
        else:
            out.append(f"The error survives the observer's corrections ({horizon}; only {100 * max(removed, 0):.0f} % "
                       "removed): it lives in the fast dynamics (modes, damping, RC pole) rather than in a slow drift.")
    failed = rt.failed
    if not failed and rt.adequate:
        out.append(f"All residual tests pass at the {rt.level * 100:g} % level: the residual is indistinguishable "
                   "from white noise independent of the drive.")
    for t in failed:
        out.append(f"{t.symbol} fails ({t.title}; {t.statistic:.3g} vs band {t.band:.3g}): {t.points_at}")
    out.extend(f for f in (loc.findings[1:] if loc.findings and loc.windows else loc.findings) if f not in lead)
    return out


def _compare_frf(model: PlantModel, record: FrfRecord, params: np.ndarray | None,
                 amp_tol_db: float = 1.0, phase_tol_deg: float = 10.0) -> FrfComparison:
    t0 = time.perf_counter()
    rep = replay_frf(model, record, params=params)
    features = model_features(model, params)
    metrics, bad, findings = {}, {}, {}
    f = rep.frequency_Hz
    t1 = time.perf_counter()
    outputs = {n: model_output_for(model, record.path, n, ch.model_output) for n, ch in record.responses.items()}
    try:
        peaks = table_peaks(model, record, rep.modelled, outputs, params)
    except FloatingPointError as exc:
        raise SimulationFailed(f"{record.path}: {exc}") from None
    t_peaks = time.perf_counter() - t1
    for ch in rep.measured:
        h, hm = rep.measured[ch], rep.modelled[ch]
        m = frf_metrics(ch, rep.units[ch], f, h, hm)
        # the largest peak of each side placed between the grid's points, not the grid's largest sample
        if peaks[ch].measured and peaks[ch].model:
            top_m = max(peaks[ch].measured, key=lambda p: p.magnitude)
            top_q = max(peaks[ch].model, key=lambda p: p.magnitude)
            m = replace(m, peak_measured_Hz=top_m.peak_Hz, peak_model_Hz=top_q.peak_Hz)
        metrics[ch] = m
        with np.errstate(divide="ignore", invalid="ignore"):
            db = 20 * np.log10(np.abs(hm) / np.abs(h))
        ph = np.degrees(np.angle(hm / np.where(h == 0, 1, h)))
        flag = (np.abs(db) > amp_tol_db) | (np.abs(ph) > phase_tol_deg)
        bands = []
        k = 0
        while k < f.size:
            if flag[k]:
                j = k
                while j + 1 < f.size and flag[j + 1]:
                    j += 1
                bands.append((float(f[k]), float(f[j]), float(np.nanmax(np.abs(db[k:j + 1]))),
                              float(np.max(np.abs(ph[k:j + 1])))))
                k = j + 1
            else:
                k += 1
        bad[ch] = bands
        lines = [f"{ch}: complex fit {m.fit_pct:.1f} %, amplitude error {m.amp_err_db_rms:.2f} dB RMS "
                 f"(max {m.amp_err_db_max:.2f} dB), phase error {m.phase_err_deg_rms:.1f}° RMS.",
                 peaks[ch].sentence(ch)]
        if bands:
            lines.append(f"Outside ±{amp_tol_db:g} dB / ±{phase_tol_deg:g}°: " + "; ".join(
                f"{a:.3g}–{b:.3g} Hz (max {c:.2f} dB, {d:.0f}°)" for a, b, c, d in bands[:6]) + ".")
        else:
            lines.append(f"Within ±{amp_tol_db:g} dB and ±{phase_tol_deg:g}° at every frequency.")
        lines.append("Residual correlation tests do not apply to a frequency-response table (no time series).")
        findings[ch] = lines
    return FrfComparison(record, rep, metrics, bad, features, findings,
                         {"stepped_sine_s": rep.wall_s["stepped_sine_s"], "peaks_s": t_peaks,
                          "compare_s": time.perf_counter() - t0}, peaks)
