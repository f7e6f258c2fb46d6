"""The comparison report (``shm compare``): one self-contained HTML page (images embedded) and JSON.

The first thing on the page for each record is a one-screen summary figure (:mod:`workbench.compare._figures`),
followed by the findings in words and the verdict table. Detailed figures and tables follow.
"""

from __future__ import annotations

import html
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from board_config.json_values import to_jsonable
from reporting.figures import display_scale as _scale
from reporting.html_page import img_tag, table
from workbench.compare._comparison import Comparison, FrfComparison
from workbench.compare._figures import write_figures

_CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;margin:1.2em auto;max-width:1400px;color:#222}
h1{font-size:1.5em} h2{font-size:1.25em;border-bottom:2px solid #ccc;margin-top:2em} h3{font-size:1.05em}
table{border-collapse:collapse;margin:0.6em 0;font-size:0.88em} td,th{border:1px solid #ccc;padding:3px 7px;
text-align:left;vertical-align:top} th{background:#f2f2f2} .pass{color:#1a7f37;font-weight:bold}
.FAIL,.fails{color:#c62828;font-weight:bold} .adequate{color:#1a7f37;font-weight:bold} .na{color:#888}
img{max-width:100%;border:1px solid #ddd;margin:0.3em 0} .find li{margin:0.25em 0} .small{font-size:0.85em;color:#555}
code{background:#f5f5f5;padding:0 3px}
"""



def _img(path: Path | None) -> str:
    return img_tag(path, style=None)


_table = table


def _q(x: float, unit: str) -> str:
    s, su = _scale(unit)
    return f"{x * s:.4g} {su}" if np.isfinite(x) else "—"


def _time_header(cmp: Comparison) -> list[str]:
    """The record's heading, what was compared, and the verdict per channel."""
    rec, rep = cmp.record, cmp.replay
    parts = [f"<h2>{html.escape(rec.name)} — {html.escape(rec.test)}</h2>"]
    parts.append(f"<p class='small'>{html.escape(rec.path)}: {rec.n_samples} samples, {rec.duration_s:.4g} s at "
                 f"{rec.sample_rate_Hz:.4g} Hz; drive {rep.drive_name}; model <b>{html.escape(rep.model_label)}</b> "
                 f"(effects: {', '.join(rep.model.effect_names)}); transient skip {cmp.options.skip_s:g} s.</p>")
    verdicts = cmp.verdicts()
    parts.append(_table(["channel", "verdict", "free-run fit", "k-step fit", "RMSE", "max |error|", "mean ε",
                         "ε > ε_th"],
                        [[ch, f"<span class='{v}'>{v.upper()}</span>", f"{cmp.metrics[ch].fit_pct:.2f} %",
                          f"{cmp.prediction[ch].fit_pct:.2f} %" if ch in cmp.prediction else "—",
                          _q(cmp.metrics[ch].rmse, cmp.metrics[ch].unit),
                          _q(cmp.metrics[ch].max_abs_error, cmp.metrics[ch].unit),
                          f"{(cmp.metrics[ch].eps_given or cmp.metrics[ch].eps_fitted).mean:.3g}",
                          f"{(cmp.metrics[ch].eps_given or cmp.metrics[ch].eps_fitted).frac_above_th * 100:.1f} %"]
                         for ch, v in verdicts.items()], raw=True))
    return parts


def _channel_evidence(cmp: Comparison, ch: str) -> list[str]:
    """A channel's readings of the evidence (hypothesis classes) and its residual tests."""
    parts = []
    hyp = cmp.localisation[ch].hypotheses
    if hyp:
        parts.append(f"<h3>{html.escape(ch)}: readings of the evidence, most likely first</h3>")
        parts.append(_table(["hypothesis class", "share explained beyond a gain error", "in numbers"],
                            [[html.escape(h.kind), f"{100 * h.score:.0f} %", html.escape(h.sentence)]
                             for h in hyp], raw=True))
    rt = cmp.tests[ch]
    parts.append(f"<h3>{html.escape(ch)}: residual tests (level α = {rt.level:g} per test, {rt.max_lag} lags, "
                 f"N = {rt.n}, input {html.escape(rt.input_name)})</h3>")
    parts.append(_table(["test", "what it checks", "statistic", "band", "p (adj.)", "verdict",
                         "a failure points at"],
                        [[html.escape(t.symbol), html.escape(t.title), f"{t.statistic:.4g}", f"{t.band:.4g}",
                          f"{t.p_value:.2g}" if not t.p_value < 1e-16 else "&lt; 1e-16",
                          f"<span class='{'na' if t.passed is None else t.verdict}'>{t.verdict}</span>",
                          html.escape(t.points_at + (f" [{t.note}]" if t.note else ""))]
                         for t in rt.tests], raw=True))
    return parts


def _channel_localisation(cmp: Comparison, ch: str) -> list[str]:
    """Where a channel's error sits: windows over the threshold, test regimes, branches, frequency bands."""
    loc = cmp.localisation[ch]
    u = loc.unit
    parts = [f"<h3>{html.escape(ch)}: windows above {_q(loc.threshold, u)} "
             f"({cmp.options.threshold_sigma:g} σ; noise σ = {_q(loc.noise_std, u)}, "
             f"{html.escape(loc.noise_source)}; rolling window {loc.window_s:.3g} s)</h3>"]
    if loc.windows:
        parts.append(_table(["start (s)", "end (s)", "regime", "peak |e|", "RMS e", "share of squared error"],
                            [[f"{w.start_s:.4g}", f"{w.end_s:.4g}", w.regime, _q(w.peak_abs_error, u),
                              _q(w.rms_error, u), f"{w.share_sq_error * 100:.1f} %"] for w in loc.windows]))
    else:
        parts.append("<p>No window exceeds the threshold.</p>")
    parts.append("<h3>By test regime</h3>" + _table(
        ["regime", "duration (s)", "RMS e", "mean e", "share of squared error", "time flagged", "mean ε", "max ε"],
        [[r.label, f"{r.duration_s:.4g}", _q(r.rms_error, u), _q(r.mean_error, u),
          f"{r.share_sq_error * 100:.1f} %", f"{r.frac_flagged * 100:.0f} %", f"{r.eps_mean:.3g}",
          f"{r.eps_max:.3g}"] for r in loc.regimes]))
    if loc.branches:
        parts.append("<h3>Rising vs falling branches</h3>" + _table(
            ["branch", "samples", "RMS e", "mean e", "mean ε", "max ε"],
            [[b.label, b.n, _q(b.rms_error, u), _q(b.mean_error, u), f"{b.eps_mean:.3g}", f"{b.eps_max:.3g}"]
             for b in loc.branches]))
    parts.append("<h3>Error-carrying frequency bands (above the noise floor)</h3>" + (_table(
        ["band", "share", "RMS content", "what sits there"],
        [["0 Hz (offset)" if b.f_hi_Hz == 0 else f"{b.f_lo_Hz:.3g}–{b.f_hi_Hz:.3g} Hz", f"{b.share * 100:.1f} %",
          _q(b.rms_error, u), b.near] for b in loc.bands]) if loc.bands else
        "<p>No band rises significantly above the noise floor.</p>"))
    return parts


def _channel_metrics(cmp: Comparison, ch: str) -> str:
    """A channel's metrics table: fit, errors, the paper's Eq. 4 fitted (and given), the k-step prediction."""
    m, u = cmp.metrics[ch], cmp.localisation[ch].unit
    rows = [["fit % (1 − NRMSE), free run", f"{m.fit_pct:.3f} %"], ["NRMSE", f"{m.nrmse:.4g}"],
            ["RMSE", _q(m.rmse, u)], ["max |error|", _q(m.max_abs_error, u)], ["mean error", _q(m.mean_error, u)],
            ["Eq. 4 fitted: e0, kerr, R²", f"{_q(m.eq4_fitted.e0, u)}, {m.eq4_fitted.kerr:.4g}, "
                                           f"{m.eq4_fitted.r2:.3g}"],
            ["ε (fitted e0/kerr): mean / p95 / max / > ε_th",
             f"{m.eps_fitted.mean:.3g} / {m.eps_fitted.p95:.3g} / {m.eps_fitted.max:.3g} / "
             f"{m.eps_fitted.frac_above_th * 100:.1f} %"]]
    if m.eq4_given and m.eps_given:
        rows += [["Eq. 4 given: e0, kerr", f"{_q(m.eq4_given.e0, u)}, {m.eq4_given.kerr:.4g}"],
                 ["ε (given): mean / p95 / max / > ε_th",
                  f"{m.eps_given.mean:.3g} / {m.eps_given.p95:.3g} / {m.eps_given.max:.3g} / "
                  f"{m.eps_given.frac_above_th * 100:.1f} %"]]
    if ch in cmp.prediction:
        p = cmp.prediction[ch]
        rows.append([p.label, f"fit {p.fit_pct:.3f} %, NRMSE {p.nrmse:.4g}, RMSE {_q(p.rmse, u)}"])
    return "<h3>Metrics</h3>" + _table(["quantity", "value"], rows)


def _time_section(cmp: Comparison, figs: dict[str, list[Path]]) -> str:
    rep = cmp.replay
    parts = _time_header(cmp)
    for ch in rep.channels:
        paths = figs[ch]
        parts.append(f"<h3>{html.escape(ch)}: where the model fails (one screen)</h3>")
        parts.append(_img(paths[0]))
        parts.append("<ul class='find'>" + "".join(f"<li>{html.escape(f)}</li>" for f in cmp.findings[ch]) + "</ul>")
        parts += _channel_evidence(cmp, ch)
        parts += _channel_localisation(cmp, ch)
        parts.append(_channel_metrics(cmp, ch))
        parts.append("<h3>Detailed figures</h3>" + "".join(_img(p) for p in paths[1:]))
    parts.append("<h3>Overlay of all channels</h3>" + _img(figs["_overlay"][0]))
    if figs["_prediction"] and rep.prediction is not None:
        parts.append("<h3>k-step-ahead prediction (labelled second figure)</h3>" + _img(figs["_prediction"][0]))
        parts.append(f"<p class='small'>{html.escape(rep.prediction.method)}; {html.escape(rep.prediction.gain_note)}."
                     "</p>")
    else:
        parts.append(f"<p class='small'>No k-step prediction: {html.escape(rep.prediction_note)}.</p>")
    return "\n".join(parts)


def _resonances(cmp: FrfComparison, ch: str) -> str:
    """'15.73 / 17.07' per resonance (placed between the table's frequencies), else the grid's largest samples."""
    pc = cmp.peaks.get(ch)
    if pc is None or not pc.measured:
        return f"{cmp.metrics[ch].peak_measured_Hz:.4g} / {cmp.metrics[ch].peak_model_Hz:.4g}"
    return "; ".join(f"{p.frequency_Hz:.4g} / {q.frequency_Hz:.4g}" if q else f"{p.frequency_Hz:.4g} / —"
                     for p, q in pc.pairs)


def _frf_section(cmp: FrfComparison, fig: Path) -> str:
    rec, rep = cmp.record, cmp.replay
    parts = [f"<h2>{html.escape(rec.name)} — frequency response</h2>",
             f"<p class='small'>{html.escape(rec.path)}: {rec.frequency_Hz.size} frequencies "
             f"{rec.frequency_Hz[0]:.3g}–{rec.frequency_Hz[-1]:.3g} Hz, drive {rec.drive} amplitude "
             f"{rec.drive_amplitude:g} (SI); model <b>{html.escape(rep.model_label)}</b> "
             "(stepped sine at the same amplitude).</p>"]
    parts.append(_table(["channel", "verdict", "complex fit", "amp. error RMS / max (dB)", "phase error RMS / max (°)",
                         "resonance measured / model (Hz)"],
                        [[ch, f"<span class='{v}'>{v.upper()}</span>", f"{cmp.metrics[ch].fit_pct:.1f} %",
                          f"{cmp.metrics[ch].amp_err_db_rms:.2f} / {cmp.metrics[ch].amp_err_db_max:.2f}",
                          f"{cmp.metrics[ch].phase_err_deg_rms:.1f} / {cmp.metrics[ch].phase_err_deg_max:.1f}",
                          _resonances(cmp, ch)]
                         for ch, v in cmp.verdicts().items()], raw=True))
    parts.append(_img(fig))
    for lines in cmp.findings.values():
        parts.append("<ul class='find'>" + "".join(f"<li>{html.escape(x)}</li>" for x in lines) + "</ul>")
    return "\n".join(parts)


def write_report(comparisons: Sequence[Comparison | FrfComparison], out: str | Path,
                 title: str = "Model vs measurement") -> dict[str, Path]:
    """PNG figures, ``report.html`` (self-contained) and ``compare.json`` in ``out``; returns their paths."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    sections = []
    overview = []
    for cmp in comparisons:
        figs = write_figures(cmp, out)
        if isinstance(cmp, FrfComparison):
            sections.append(_frf_section(cmp, figs["_bode"][0]))
        else:
            sections.append(_time_section(cmp, figs))
        for ch, v in cmp.verdicts().items():
            fails = ""
            if isinstance(cmp, Comparison):
                fails = ", ".join(t.symbol for t in cmp.tests[ch].failed) or "—"
                fit = f"{cmp.metrics[ch].fit_pct:.2f} %"
                where = "; ".join(b.near or f"{b.f_lo_Hz:.3g}–{b.f_hi_Hz:.3g} Hz" for b in
                                  cmp.localisation[ch].bands[:2]) or "—"
            else:
                fit = f"{cmp.metrics[ch].fit_pct:.1f} % (complex)"
                where = "; ".join(f"{a:.3g}–{b:.3g} Hz" for a, b, _, _ in cmp.bad_bands[ch][:3]) or "—"
            overview.append([html.escape(cmp.record.name), html.escape(cmp.record.test), html.escape(ch),
                             f"<span class='{v}'>{v.upper()}</span>", fit, html.escape(fails), html.escape(where)])
    model_label = comparisons[0].replay.model_label if comparisons else ""
    doc = [
        "<!DOCTYPE html><html><head><meta charset='utf-8'>",
        f"<title>{html.escape(title)}</title><style>{_CSS}</style></head><body>",
        f"<h1>{html.escape(title)}: {html.escape(model_label)}</h1>",
        "<p class='small'>Residual = measured − model. Fit % = 100·(1 − ‖y − ŷ‖/‖y − mean y‖) (MATLAB compare). "
        "ε = |y_md − y_hw| / (|y_hw| + e0/kerr), the seed paper's Eq. 5. Residual tests: bias, whiteness, "
        "input cross-correlation and the Billings–Voon nonlinear tests, each at family level α with bands corrected "
        "for the number of effectively independent lags. Generated by <code>shm compare</code>.</p>",
        "<h2>Overview</h2>",
        _table(["record", "test", "channel", "verdict", "fit", "failed tests", "where (bands)"], overview, raw=True),
        *sections,
        "</body></html>",
    ]
    html_path = out / "report.html"
    html_path.write_text("\n".join(doc), encoding="utf-8")
    json_path = out / "compare.json"
    json_path.write_text(json.dumps(report_json(comparisons), indent=2, allow_nan=False), encoding="utf-8")
    return {"html": html_path, "json": json_path}


def report_json(comparisons: Sequence[Comparison | FrfComparison]) -> dict[str, Any]:
    """The report's numbers as JSON-able data (non-finite numbers become null)."""
    return to_jsonable({"records": [c.to_dict() for c in comparisons]})
