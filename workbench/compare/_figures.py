"""Figures of a model-vs-measurement comparison (``shm compare``): the one-screen summary per channel — overlay with
the flagged windows, residual by regime, residual spectrum with the error-carrying bands, residual against the
drive (rising and falling branches), the residual-test verdict strip and the paper's normalised error ε(t) — and
the detailed figures (overlay of all channels, k-step prediction, amplitude/rate, correlations, Bode).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from reporting.figure_layout import few_ticks, hide_colliding_texts, legend_clear_of_data
from reporting.figures import display_scale as _scale
from reporting.figures import logspaced_max as _logspaced_max
from reporting.figures import minmax_decimate as _env
from reporting.figures import pyplot as _pyplot
from reporting.figures import save_figure
from workbench.compare._comparison import Comparison, FrfComparison


def _margins(**adjust: float) -> dict[str, float]:
    kw = {"left": 0.07, "right": 0.98, "top": 0.92, "bottom": 0.09, "hspace": 0.4, "wspace": 0.25}
    kw.update(adjust)
    return kw


def _finish(fig, path: Path, **adjust: float) -> Path:
    """Fixed margins instead of tight_layout (which costs more than the drawing on long reports)."""
    return save_figure(fig, path, 80, adjust=_margins(**adjust))


def _slug(text: str) -> str:
    return "".join(c if c.isalnum() or c in "-_" else "_" for c in text)[:60]

def _regime_colours(labels: Sequence[str]) -> dict[str, Any]:
    plt = _pyplot()
    cmap = plt.get_cmap("tab20")
    uniq = list(dict.fromkeys(labels))
    return {lab: cmap((2 * i + 1) % 20) for i, lab in enumerate(uniq)}


def _shade_regimes(ax, t: np.ndarray, labels: np.ndarray, colours: dict[str, Any]) -> None:
    change = np.flatnonzero(labels[1:] != labels[:-1]) + 1
    starts = np.concatenate([[0], change])
    ends = np.concatenate([change, [labels.size]])
    for a, b in zip(starts, ends):
        ax.axvspan(t[a], t[min(b, t.size - 1)], color=colours[labels[a]], alpha=0.18, lw=0)


# ----------------------------------------------------------------------------------------------------------------
# time-record figures


def _plot_overlay(ax, cmp: Comparison, ch: str, with_windows: bool = True) -> None:
    rep = cmp.replay
    cr = rep.channels[ch]
    s, su = _scale(cr.unit)
    ax.plot(*_env(rep.t, cr.measured * s), color="k", lw=1.0, label="measured")
    ax.plot(*_env(rep.t, cr.simulated * s), color="tab:red", lw=1.0, ls="--",
            label=f"model, free run (fit {cmp.metrics[ch].fit_pct:.1f} %)")
    if with_windows:
        for w in cmp.localisation[ch].windows:
            ax.axvspan(w.start_s, w.end_s, color="tab:orange", alpha=0.15, lw=0)
    ax.set_ylabel(f"{ch} ({su})")
    ax.set_xlabel("time (s)")
    legend_clear_of_data(ax, fontsize=7)
    ax.set_title(f"{ch}: measured vs model" + ("  (orange: flagged windows)" if with_windows else ""), fontsize=9)


def _plot_residual(ax, cmp: Comparison, ch: str, legend: bool = True) -> None:
    rep = cmp.replay
    loc = cmp.localisation[ch]
    cr = rep.channels[ch]
    s, su = _scale(cr.unit)
    skip = rep.t >= rep.t[0] + cmp.options.skip_s
    t = rep.t[skip]
    colours = _regime_colours(loc.labels.tolist())
    _shade_regimes(ax, t, loc.labels, colours)
    ax.plot(*_env(t, cr.residual[skip] * s), color="k", lw=0.6)
    ax.plot(*_env(t, loc.rolling_rms * s), color="tab:blue", lw=1.2, label="rolling RMS")
    ax.axhline(loc.threshold * s, color="tab:orange", ls="--", lw=1, label=f"threshold {loc.threshold * s:.3g} {su}")
    ax.axhline(-loc.threshold * s, color="tab:orange", ls="--", lw=1)
    if legend:
        from matplotlib.patches import Patch

        handles = [Patch(color=c, alpha=0.35, label=lab) for lab, c in colours.items()][:8]
        legend_clear_of_data(ax, handles=handles + ax.get_legend_handles_labels()[0], fontsize=6, ncol=2)
    ax.set_ylabel(f"residual ({su})")
    ax.set_xlabel("time (s)")
    ax.set_title(f"{ch}: residual (measured − model), shaded by test regime", fontsize=9)


def _plot_spectrum(ax, cmp: Comparison, ch: str) -> None:
    loc = cmp.localisation[ch]
    s, su = _scale(cmp.replay.channels[ch].unit)
    f = loc.spectrum_f[1:]
    ax.loglog(*_logspaced_max(f, loc.spectrum_meas[1:] * s * s), color="0.7", lw=0.8, label="measured signal")
    ax.loglog(*_logspaced_max(f, np.maximum(loc.spectrum_resid[1:], 1e-300) * s * s), color="k", lw=0.8,
              label="residual")
    ax.axhline(loc.noise_psd * s * s, color="tab:blue", ls=":", lw=1, label="noise floor")
    share_labels = []
    for b in sorted(loc.bands, key=lambda b: -b.share):
        if b.f_hi_Hz > 0:
            ax.axvspan(b.f_lo_Hz, b.f_hi_Hz, color="tab:orange", alpha=0.3, lw=0)
            share_labels.append(ax.text(np.sqrt(b.f_lo_Hz * b.f_hi_Hz), loc.noise_psd * s * s,
                                        f"{b.share * 100:.0f}%", fontsize=7, ha="center", va="bottom",
                                        color="tab:orange", fontweight="bold"))
    feature_labels = []
    for fr, lab in cmp.features:
        if f.size and f[0] <= fr <= f[-1]:
            ax.axvline(fr, color="tab:green", lw=0.8, alpha=0.7)
            feature_labels.append(ax.text(fr, ax.get_ylim()[0], lab.split(" (")[0], rotation=90, fontsize=6,
                                          color="tab:green", va="bottom", ha="right"))
    import matplotlib.ticker as mticker

    for axis in (ax.xaxis, ax.yaxis):  # plain decade labels, no minor ticks: mathtext costs more than the plot
        axis.set_major_formatter(mticker.LogFormatter(labelOnlyBase=True))
        axis.set_minor_locator(mticker.NullLocator())
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel(f"PSD ({su}²/Hz)")
    leg = ax.legend(fontsize=6, loc="lower left")
    # labels that would run into the legend or each other are left out: the largest bands' shares first
    hide_colliding_texts([leg, *share_labels, *feature_labels])
    offset = [b for b in loc.bands if b.f_hi_Hz == 0]
    ax.set_title("residual spectrum; orange: error-carrying bands" + (
        f" (+ offset {offset[0].share * 100:.0f}%)" if offset else ""), fontsize=9)


def _plot_vs_drive(ax, cmp: Comparison, ch: str) -> None:
    """Residual against the drive, rising and falling branches; for step-like drives (no branches to speak of)
    against the measured response instead, split by the response's own direction."""
    from workbench.localise import drive_rate

    rep = cmp.replay
    ar = cmp.localisation[ch].amp_rate
    cr = rep.channels[ch]
    s, su = _scale(cr.unit)
    _, du = drive_rate(rep.t, rep.drive)
    thr = 0.01 * float(np.max(np.abs(du))) if np.any(du) else 0.0
    moving = np.count_nonzero(np.abs(du) > thr) if thr > 0 else 0
    step = max(1, rep.t.size // 6000)
    if ar is None or moving < 0.05 * rep.t.size:
        _, dy = drive_rate(rep.t, cr.measured)
        for mask, col, lab in ((dy > 0, "tab:red", "response rising"), (dy <= 0, "tab:blue", "response falling")):
            ax.plot(cr.measured[mask][::step] * s, cr.residual[mask][::step] * s, ".", ms=1.5, color=col, alpha=0.4,
                    label=lab)
        ax.set_xlabel(f"measured {ch} ({su})")
        ax.set_ylabel(f"residual ({su})")
        ax.legend(fontsize=6, markerscale=6)
        ax.set_title(f"residual vs measured {ch} (the drive is step-like: rising/falling of the response)",
                     fontsize=9)
        return
    ax.set_title(f"residual vs {rep.drive_name}: rising vs falling", fontsize=9)
    for mask, col in ((du > thr, "tab:red"), (du < -thr, "tab:blue")):
        ax.plot(rep.drive[mask][::step], cr.residual[mask][::step] * s, ".", ms=1, color=col, alpha=0.3)
    ax.plot(ar.u_centres, ar.e_rising * s, "-o", ms=3, color="tab:red", label="rising (bin mean)")
    ax.plot(ar.u_centres, ar.e_falling * s, "-o", ms=3, color="tab:blue", label="falling (bin mean)")
    ax.set_xlabel(f"{rep.drive_name} ({rep.drive_unit})")
    ax.set_ylabel(f"residual ({su})")
    ax.legend(fontsize=6, title=f"loop index {ar.loop_index:.2f}" + (" — LOOP" if ar.loop_detected else ""),
              title_fontsize=7)


def _plot_verdicts(ax, cmp: Comparison, ch: str) -> None:
    rt = cmp.tests[ch]
    names = [t.symbol for t in rt.tests]
    ratios = [t.ratio if np.isfinite(t.ratio) else 0.0 for t in rt.tests]
    cols = ["0.6" if t.passed is None else ("tab:green" if t.passed else "tab:red") for t in rt.tests]
    y = np.arange(len(names))
    ax.barh(y, np.maximum(ratios, 1e-3), color=cols)
    ax.axvline(1.0, color="k", lw=1)
    ax.set_xscale("log")
    ax.set_yticks(y, names, fontsize=8)
    ax.invert_yaxis()
    for yi, t in zip(y, rt.tests):
        ax.text(max(t.ratio if np.isfinite(t.ratio) else 1e-3, 1e-3), yi, f" {t.verdict}", va="center", fontsize=7)
    ax.set_xlabel("test statistic / band  (> 1 fails)")
    ax.set_title(f"residual tests at {rt.level * 100:g} % (family-wise per test)", fontsize=9)


def _plot_eps(ax, cmp: Comparison, ch: str) -> None:
    from board_config import load_monitor_settings

    rep = cmp.replay
    eps = cmp.eps[ch]
    ax.plot(*_env(rep.t, eps), color="k", lw=0.7)
    th = load_monitor_settings().eps_th
    ax.axhline(th, color="tab:red", ls="--", lw=1, label=f"ε_th = {th:g} (Table 3)")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("ε (Eq. 5)")
    ax.legend(fontsize=6)
    ax.set_title(f"normalised error, {cmp.eps_source[ch]}", fontsize=8)


def summary_figure(cmp: Comparison, ch: str, path: Path) -> Path:
    plt = _pyplot()
    fig, axes = plt.subplots(3, 2, figsize=(14, 10.5))
    margins = {"top": 0.93, "bottom": 0.06, "left": 0.06, "hspace": 0.35}
    fig.subplots_adjust(**_margins(**margins))  # the final layout first: legends and labels are placed on it
    _plot_overlay(axes[0, 0], cmp, ch)
    _plot_residual(axes[0, 1], cmp, ch, legend=True)
    _plot_spectrum(axes[1, 0], cmp, ch)
    _plot_vs_drive(axes[1, 1], cmp, ch)
    _plot_verdicts(axes[2, 0], cmp, ch)
    _plot_eps(axes[2, 1], cmp, ch)
    verdict = cmp.verdicts()[ch]
    fig.suptitle(f"{cmp.record.name} ({cmp.record.test}) vs {cmp.replay.model_label}: {ch} — {verdict.upper()}",
                 fontsize=12, color="tab:green" if verdict == "adequate" else "tab:red")
    return _finish(fig, path, **margins)


def overlay_figure(cmp: Comparison, path: Path) -> Path:
    plt = _pyplot()
    chans = list(cmp.replay.channels)
    fig, axes = plt.subplots(len(chans) + 1, 1, figsize=(12, 2.6 * (len(chans) + 1)), sharex=True, squeeze=False)
    fig.subplots_adjust(**_margins())
    rep = cmp.replay
    ax0 = axes[0, 0]
    ax0.plot(*_env(rep.t, rep.drive), color="tab:purple", lw=0.8)
    ax0.set_ylabel(f"{rep.drive_name} ({rep.drive_unit})")
    ax0.set_title("drive", fontsize=9)
    for i, ch in enumerate(chans, start=1):
        _plot_overlay(axes[i, 0], cmp, ch, with_windows=False)
    return _finish(fig, path)


def prediction_figure(cmp: Comparison, path: Path) -> Path | None:
    pred = cmp.replay.prediction
    if pred is None:
        return None
    plt = _pyplot()
    chans = list(pred.predicted)
    fig, axes = plt.subplots(len(chans), 2, figsize=(14, 3.2 * len(chans)), squeeze=False)
    for i, ch in enumerate(chans):
        s, su = _scale(cmp.replay.channels[ch].unit)
        ax = axes[i, 0]
        ax.plot(*_env(pred.t, pred.measured[ch] * s), color="k", lw=1, label="measured")
        fit = cmp.prediction[ch].fit_pct
        ax.plot(*_env(pred.t, pred.predicted[ch] * s), color="tab:blue", lw=1, ls="--",
                label=f"{pred.steps}-step prediction (fit {fit:.1f} %)")
        ax.set_ylabel(f"{ch} ({su})")
        ax.set_xlabel("time (s)")
        ax.legend(fontsize=7)
        ax.set_title(f"{ch}: {pred.label}", fontsize=9)
        ax = axes[i, 1]
        cr = cmp.replay.channels[ch]
        ax.plot(*_env(cmp.replay.t, cr.residual * s), color="tab:red", lw=0.6,
                label=f"free-run residual (fit {cmp.metrics[ch].fit_pct:.1f} %)")
        ax.plot(*_env(pred.t, (pred.measured[ch] - pred.predicted[ch]) * s), color="tab:blue", lw=0.6,
                label=f"prediction residual (fit {fit:.1f} %)")
        ax.set_xlabel("time (s)")
        ax.set_ylabel(f"residual ({su})")
        ax.legend(fontsize=7)
        ax.set_title("free run vs k-step prediction: what the observer's corrections remove", fontsize=9)
    fig.suptitle(f"K-STEP-AHEAD PREDICTION (not a free run): the model is corrected from the measurement every "
                 f"{pred.interval_s * 1e3:g} ms and predicts {pred.horizon_s * 1e3:g} ms ahead", fontsize=10)
    h = 3.2 * len(chans)
    return _finish(fig, path, top=1 - 0.75 / h, bottom=0.55 / h, hspace=0.5)


def amplitude_rate_figure(cmp: Comparison, ch: str, path: Path) -> Path | None:
    ar = cmp.localisation[ch].amp_rate
    if ar is None:
        return None
    plt = _pyplot()
    s, su = _scale(cmp.replay.channels[ch].unit)
    fig, axes = plt.subplots(1, 3, figsize=(15, 4))
    margins = {"bottom": 0.15, "top": 0.9}  # room below for tick labels and the axis label of a 4-inch figure
    fig.subplots_adjust(**_margins(**margins))
    _plot_vs_drive(axes[0], cmp, ch)
    axes[1].plot(ar.rate_centres, ar.e_by_rate * s, "-o", ms=3, color="k")
    axes[1].set_xlabel(f"d{ar.drive}/dt ({ar.unit}/s)")
    axes[1].set_ylabel(f"mean residual ({su})")
    axes[1].set_title(f"residual vs drive rate (correlation {ar.rate_corr:.2f})", fontsize=9)
    ys, yu = _scale(cmp.replay.channels[ch].unit)
    axes[2].plot(ar.y_centres * ys, ar.e_by_y * s, "-o", ms=3, color="k")
    axes[2].set_xlabel(f"measured {ch} ({yu})")
    axes[2].set_ylabel(f"mean residual ({su})")
    axes[2].set_title("residual vs measured response (stiffening: an odd curve)", fontsize=9)
    for ax in axes:
        ax.axhline(0, color="0.6", lw=0.8)
        few_ticks(ax.xaxis)
    return _finish(fig, path, **margins)


def correlation_figure(cmp: Comparison, ch: str, path: Path) -> Path:
    plt = _pyplot()
    rt = cmp.tests[ch]
    tests = [t for t in rt.tests if t.key != "bias"]
    fig, axes = plt.subplots(1, len(tests), figsize=(3.2 * len(tests), 3.2), squeeze=False)
    for ax, t in zip(axes[0], tests):
        col = "0.5" if t.passed is None else ("tab:green" if t.passed else "tab:red")
        ax.vlines(t.lags, 0, t.r, color=col, lw=1.5)
        ax.axhline(t.band, color="tab:blue", ls="--", lw=1)
        ax.axhline(-t.band, color="tab:blue", ls="--", lw=1)
        ax.axhline(0, color="0.5", lw=0.6)
        ax.set_title(f"{t.symbol}: {t.verdict}", fontsize=9, color=col)
        ax.set_xlabel("lag τ (samples" + (f" ×{rt.decimate}" if rt.decimate > 1 else "") + ")")
        lim = max(1.3 * t.band, 1.1 * float(np.nanmax(np.abs(t.r))) if np.any(np.isfinite(t.r)) else 1.0)
        ax.set_ylim(-lim, lim)
    axes[0, 0].set_ylabel("normalised correlation")
    fig.suptitle(f"{ch}: Billings–Voon correlation tests vs {rt.input_name}; dashed: {100 * (1 - rt.level):g} % "
                 f"family-wise band, N = {rt.n}", fontsize=9)
    return _finish(fig, path, bottom=0.17, top=0.8, left=0.05, wspace=0.3)


def residual_figure(cmp: Comparison, ch: str, path: Path) -> Path:
    plt = _pyplot()
    fig, axes = plt.subplots(2, 1, figsize=(13, 6), sharex=True)
    fig.subplots_adjust(**_margins())
    _plot_residual(axes[0], cmp, ch)
    _plot_eps(axes[1], cmp, ch)
    return _finish(fig, path)


def spectrum_figure(cmp: Comparison, ch: str, path: Path) -> Path:
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(11, 4.5))
    fig.subplots_adjust(**_margins())
    _plot_spectrum(ax, cmp, ch)
    return _finish(fig, path)


def bode_figure(cmp: FrfComparison, path: Path) -> Path:
    plt = _pyplot()
    rep = cmp.replay
    chans = list(rep.measured)
    fig, axes = plt.subplots(2, len(chans), figsize=(7 * len(chans), 7), squeeze=False, sharex=True)
    f = rep.frequency_Hz
    for j, ch in enumerate(chans):
        h, hm = rep.measured[ch], rep.modelled[ch]
        a, p = axes[0, j], axes[1, j]
        a.loglog(f, np.abs(h), "ko-", ms=3, lw=1, label="measured")
        a.loglog(f, np.abs(hm), "r--", lw=1.2, label=f"model (fit {cmp.metrics[ch].fit_pct:.1f} %)")
        p.semilogx(f, np.degrees(np.unwrap(np.angle(h))), "ko-", ms=3, lw=1)
        p.semilogx(f, np.degrees(np.unwrap(np.angle(hm))), "r--", lw=1.2)
        for lo, hi, _, _ in cmp.bad_bands[ch]:
            for ax in (a, p):
                ax.axvspan(lo * 0.97, hi * 1.03, color="tab:orange", alpha=0.25, lw=0)
        for fr, _ in cmp.features:
            if f[0] <= fr <= f[-1]:
                for ax in (a, p):
                    ax.axvline(fr, color="tab:green", lw=0.8, alpha=0.6)
        if ch in cmp.peaks:  # resonances placed between the table's points (workbench.compare._frf_peaks)
            from workbench.compare._frf_figures import mark_resonances

            mark_resonances(a, cmp.peaks[ch])
        a.set_ylabel(f"|{ch}| / {rep.record.drive} ({rep.units[ch]})")
        a.legend(fontsize=7)
        dunit = "m/s²" if rep.record.drive == "z0dd" else "V"
        a.set_title(f"{ch}: stepped sine, {rep.record.drive} amplitude {rep.record.drive_amplitude:.4g} {dunit}; "
                    "orange: out of tolerance", fontsize=9)
        p.set_ylabel("phase (deg)")
        p.set_xlabel("frequency (Hz)")
    return _finish(fig, path, left=0.13 / max(1, len(chans)) + 0.03, hspace=0.15)



def write_figures(cmp: Comparison | FrfComparison, out: Path) -> dict[str, list[Path]]:
    """Write every PNG of one comparison into ``out``; returns them by channel (plus ``_overlay``/``_prediction``)."""
    out.mkdir(parents=True, exist_ok=True)
    slug = _slug(cmp.record.name)
    if isinstance(cmp, FrfComparison):
        return {"_bode": [bode_figure(cmp, out / f"{slug}_bode.png")]}
    figs: dict[str, list[Path]] = {}
    for ch in cmp.replay.channels:
        base = f"{slug}_{_slug(ch)}"
        # the summary carries the residual, spectrum and ε views; residual_figure / spectrum_figure draw them
        # larger on request (they are left out here to keep a 60 s record's report to a few seconds)
        paths = [summary_figure(cmp, ch, out / f"{base}_summary.png")]
        ar = amplitude_rate_figure(cmp, ch, out / f"{base}_amplitude_rate.png")
        if ar:
            paths.append(ar)
        paths.append(correlation_figure(cmp, ch, out / f"{base}_correlation.png"))
        if cmp.frf and ch in cmp.frf:  # the record in the frequency domain (a sweep): workbench.compare._frf_figures
            from workbench.compare._frf_figures import sweep_frf_figure

            paths.append(sweep_frf_figure(cmp.frf[ch], out / f"{base}_frf.png", cmp.record.name))
        figs[ch] = paths
    figs["_overlay"] = [overlay_figure(cmp, out / f"{slug}_overlay.png")]
    pred = prediction_figure(cmp, out / f"{slug}_prediction.png")
    figs["_prediction"] = [pred] if pred else []
    return figs

