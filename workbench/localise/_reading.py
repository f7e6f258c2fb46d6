"""One reading of the evidence: hypothesis classes ranked by what their signature explains, and the findings of a
:class:`Localisation` in words."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from workbench.localise._results import Hypothesis, Localisation
from workbench.localise._spectrum import dominant_frequency

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


@dataclass(frozen=True)
class _Evidence:
    """The residual ``e`` beside the modelled response ``yhat`` (and what is derived from it once for every class):
    ``yc`` the modelled deflection from its start, ``v``/``acc`` its rate and acceleration, ``vs`` the rate's RMS,
    ``rel_t`` the time as a share of the record, ``base`` what a plain gain error (e ≈ a + b·ŷ) explains."""

    t: np.ndarray
    e: np.ndarray
    yhat: np.ndarray
    u: np.ndarray
    y: np.ndarray
    unit: str
    rel_t: np.ndarray
    yc: np.ndarray
    v: np.ndarray
    acc: np.ndarray
    vs: float
    base: float


def _evidence(t: np.ndarray, e: np.ndarray, yhat: np.ndarray, u: np.ndarray, y: np.ndarray, unit: str) -> _Evidence:
    yc = yhat - yhat[0]
    v = np.gradient(yhat, t)
    return _Evidence(t, e, yhat, u, y, unit, (t - t[0]) / max(float(t[-1] - t[0]), 1e-12), yc, v, np.gradient(v, t),
                     max(_rms(v), 1e-300), _r2(e, [yc]))


def _sign_asymmetric(ev: _Evidence) -> Hypothesis | None:
    """An even function of the deflection (None when either side of the deflection is too rarely visited)."""
    e, yc, unit = ev.e, ev.yc, ev.unit
    pos, neg = yc > 0.05 * np.ptp(yc), yc < -0.05 * np.ptp(yc)
    sc = _r2(e, [yc, np.abs(yc)]) - ev.base
    if not (pos.sum() > 0.1 * e.size and neg.sum() > 0.1 * e.size):
        return None
    ep, en = _rms(e[pos]), _rms(e[neg])
    big, small = ("positive", "negative") if ep >= en else ("negative", "positive")
    return Hypothesis("sign-asymmetric", sc, f"the error is {max(ep, en) / max(min(ep, en), 1e-300):.2g}× "
                      f"larger for {big} than for {small} deflection (RMS {_fmt(max(ep, en), unit)} vs "
                      f"{_fmt(min(ep, en), unit)}): sign-dependent physics (one-sided contact, polarisation-"
                      "dependent coupling, asymmetric sensor)")


def _amplitude_dependent(ev: _Evidence) -> Hypothesis:
    """Odd growth with the deflection."""
    e, yc = ev.e, ev.yc
    q = np.abs(yc)
    hi, lo = q >= np.quantile(q, 2 / 3), q <= np.quantile(q, 1 / 3)
    ratio_hi = _rms(e[hi]) / max(_rms(yc[hi]), 1e-300)
    ratio_lo = _rms(e[lo]) / max(_rms(yc[lo]), 1e-300)
    return Hypothesis("amplitude-dependent", _r2(e, [yc, yc ** 3]) - ev.base,
                      f"the relative error is {ratio_hi / max(ratio_lo, 1e-300):.2g}× larger in the largest third "
                      f"of the deflection than in the smallest ({100 * ratio_hi:.3g} % vs {100 * ratio_lo:.3g} %): "
                      "amplitude-dependent stiffness or damping (Duffing, drag, saturation)")


def _rate_dependent(ev: _Evidence) -> Hypothesis:
    e, v = ev.e, ev.v
    fast, slow = np.abs(v) >= np.quantile(np.abs(v), 2 / 3), np.abs(v) <= np.quantile(np.abs(v), 1 / 3)
    return Hypothesis("rate-dependent", _r2(e, [ev.yc, v, np.abs(v) * v / ev.vs]) - ev.base,
                      f"the error follows the velocity: RMS {_fmt(_rms(e[fast]), ev.unit)} in the fastest third of "
                      f"the motion vs {_fmt(_rms(e[slow]), ev.unit)} in the slowest (damping, drag, a lag)")


def _switching(ev: _Evidence) -> Hypothesis:
    """Switching at zero crossings of the velocity (a ±g square wave)."""
    e = ev.e
    sw = np.tanh(ev.v / (0.01 * ev.vs))
    sc_sw = _r2(e, [ev.yc, ev.v, sw]) - _r2(e, [ev.yc, ev.v])
    coef = float(np.dot(e - e.mean(), sw - sw.mean()) / max(np.dot(sw - sw.mean(), sw - sw.mean()), 1e-300))
    return Hypothesis("switching at zero crossings", sc_sw,
                      f"the residual switches by ±{_fmt(abs(coef), ev.unit)} each time the motion reverses (a square "
                      f"wave on the sign of the velocity explains {100 * max(sc_sw, 0):.0f} % of it beyond a "
                      "viscous term): dry friction, a clearance or backlash")


def _time_varying(ev: _Evidence) -> Hypothesis:
    e, yc, u = ev.e, ev.yc, ev.u
    thirds = np.array_split(np.arange(e.size), 3)
    # relative to the modelled response in each third (a sweep's response changes size with frequency)
    r_first = _rms(e[thirds[0]]) / max(_rms(yc[thirds[0]]), 1e-300)
    r_last = _rms(e[thirds[-1]]) / max(_rms(yc[thirds[-1]]), 1e-300)
    steady = dominant_frequency(ev.t, u) is not None or np.ptp(u) == 0
    return Hypothesis("time-varying", _r2(e, [yc, ev.rel_t * yc, ev.rel_t]) - ev.base,
                      f"the residual grows in time: {100 * r_first:.3g} % of the response in the first third of "
                      f"the record, {100 * r_last:.3g} % in the last ({r_last / max(r_first, 1e-300):.2g}×): "
                      "a gain or zero drifting during the test (temperature, creep, a warming sensor)"
                      + ("" if steady else " — but the drive changes its character in time (a sweep: time is also "
                         "frequency); confirm on a record with a steady drive"))


def _shifted_dynamics(ev: _Evidence, features: Sequence[tuple[float, str]]) -> Hypothesis:
    """The error in phase with the modelled velocity/acceleration, or a measured mode away from the modelled one."""
    sc_dyn = _r2(ev.e, [ev.yc, ev.v, ev.acc]) - ev.base
    words = "the dynamics are shifted: the error is in phase with the modelled velocity/acceleration"
    modes = [f for f, lab in features if lab.startswith("mode")]
    if modes:
        ms = mode_shift(ev.t, ev.u, ev.y, ev.yhat, modes[0])
        if ms is not None and abs(ms[0] / ms[1] - 1) > 0.01:
            rel = ms[0] / ms[1] - 1
            words = (f"measured mode 1 is {abs(100 * rel):.2g} % {'lower' if rel < 0 else 'higher'} than modelled "
                     f"({ms[0]:.3g} vs {ms[1]:.3g} Hz): a stiffness or mass is wrong, or something "
                     f"{'softens' if rel < 0 else 'stiffens'} the structure")
            sc_dyn = max(sc_dyn, 0.0) + 0.05
    return Hypothesis("shifted dynamics", sc_dyn, words)


def hypotheses(t: np.ndarray, e: np.ndarray, yhat: np.ndarray, u: np.ndarray, y: np.ndarray, sigma: float,
               unit: str = "", features: Sequence[tuple[float, str]] = (), drive_name: str = "drive"
               ) -> list[Hypothesis]:
    """Rank the hypothesis classes (:data:`HYPOTHESIS_KINDS`) by the share of the residual variance their
    signature adds beyond a plain gain error (e ≈ a + b·ŷ), best first; none when the residual is noise."""
    t, e, yhat, u = (np.asarray(a, float) for a in (t, e, yhat, u))
    if e.size < 20 or _rms(e) <= 1.5 * sigma:
        return []
    ev = _evidence(t, e, yhat, u, y, unit)
    asymmetric = _sign_asymmetric(ev)
    out: list[Hypothesis] = [] if asymmetric is None else [asymmetric]
    out += [_amplitude_dependent(ev), _rate_dependent(ev), _switching(ev), _time_varying(ev),
            _shifted_dynamics(ev, features)]
    # sensor-only: a memoryless map of the deflection explains it better than any class above
    stat = _r2(e, [ev.yc, ev.yc ** 2, ev.yc ** 3])
    others = max(ev.base + h.score for h in out)
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


def describe_findings(loc: Localisation, t: np.ndarray, e: np.ndarray, sigma: float) -> list[str]:
    """The findings of ``loc`` in sentences, most telling first (noise level, hypotheses, regimes, drift, bands,
    loops, branches)."""
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
