"""The frequency-domain panel of a time record in ``shm compare`` (a sweep): H1 measured vs the model's, coherence,
and the resonance peaks of both (see :mod:`workbench.compare._frf`); the resonance markers an FRF table's Bode
figure also draws."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from reporting.figures import display_scale, pyplot, save_figure
from workbench.compare._frf import PeakComparison, SweepFrf
from workbench.compare._frf_estimate import COHERENT


def mark_resonances(ax: Any, peaks: PeakComparison, scale: float = 1.0) -> None:
    """Mark each resonance of ``peaks`` a little above its fitted maximum on a magnitude axis: ▼ measured,
    ▽ model (labelled once each for the legend)."""
    for found, colour, who in ((peaks.measured, "k", "measured"), (peaks.model, "tab:red", "model")):
        for i, p in enumerate(found):
            ax.plot([p.peak_Hz], [p.magnitude * scale * 1.25], marker="v", ms=7, ls="none",
                    mfc=colour if who == "measured" else "none", mec=colour,
                    label=f"{who} resonance{'s' if len(found) > 1 else ''}" if i == 0 else None)


def sweep_frf_figure(sf: SweepFrf, path: Path, title: str) -> Path:
    """Magnitude, phase and coherence of ``sf`` over the frequencies the drive reached; measured points whose
    coherence is below :data:`COHERENT` drawn pale; peaks marked (▼ measured, ▽ model). Legends sit right of the
    axes, clear of the data."""
    plt = pyplot()
    em, es = sf.measured, sf.model
    f = em.frequency_Hz
    k = em.driven & (f > 0)
    if sf.band_Hz[0] == sf.band_Hz[0]:  # a coherent band exists: show it with a margin on either side
        k &= (f >= sf.band_Hz[0] / 1.5) & (f <= sf.band_Hz[1] * 1.5)
    good = k & em.trusted()
    scale, shown = display_scale(sf.unit.split("/")[0])
    unit = f"{shown}/{sf.unit.split('/', 1)[1]}" if "/" in sf.unit else sf.unit
    fig, (am, ph, co) = plt.subplots(3, 1, figsize=(10, 8.2), sharex=True, height_ratios=[2.2, 1.4, 1])
    am.loglog(f[k], np.abs(em.h1[k]) * scale, color="0.75", lw=0.8, label=f"measured H1, γ² < {COHERENT:g}")
    am.loglog(f[good], np.abs(em.h1[good]) * scale, "k.", ms=2.5, label="measured H1")
    am.loglog(f[k], np.abs(es.h1[k]) * scale, color="tab:red", ls="--", lw=1.2,
              label=f"model H1 (fit {sf.fit_pct:.1f} %)")
    if sf.linear is not None:
        am.loglog(f[k], np.abs(sf.linear[k]) * scale, color="tab:blue", lw=0.8, alpha=0.7,
                  label="model linearised at rest")
    mark_resonances(am, sf.peaks, scale)
    ph.semilogx(f[good], np.degrees(np.unwrap(np.angle(em.h1[good]))), "k.", ms=2.5)
    ph.semilogx(f[k], np.degrees(np.unwrap(np.angle(es.h1[k]))), color="tab:red", ls="--", lw=1.2)
    co.semilogx(f[k], em.coherence[k], color="k", lw=0.9, label="measured γ²")
    co.axhline(COHERENT, color="tab:orange", ls=":", lw=1, label=f"threshold {COHERENT:g}")
    co.set_ylim(0, 1.05)
    import matplotlib.ticker as mticker

    # plain 1-2-5 labels on the shared log axis, none on the minor ticks (a narrow band's minor labels collide)
    co.xaxis.set_major_locator(mticker.LogLocator(subs=(1.0, 2.0, 5.0)))
    co.xaxis.set_major_formatter(mticker.FormatStrFormatter("%g"))
    co.xaxis.set_minor_formatter(mticker.NullFormatter())
    am.set_ylabel(f"|{sf.channel}| / {sf.drive} ({unit})")
    ph.set_ylabel("phase (deg)")
    co.set_ylabel("coherence γ²")
    co.set_xlabel("frequency (Hz)")
    am.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0)
    co.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0)
    lines = [f"{p.frequency_Hz:.4g} Hz vs {q.frequency_Hz:.4g} Hz" if q else f"{p.frequency_Hz:.4g} Hz vs —"
             for p, q in sf.peaks.pairs]
    am.set_title(f"{title}: {sf.channel} against {sf.drive}, H1 (resolution {em.resolution_Hz:.3g} Hz, "
                 f"{em.n_segments} segments)\nresonances measured vs model: " + ("; ".join(lines) or "none"),
                 fontsize=9)
    return save_figure(fig, path, 80, adjust={"left": 0.09, "right": 0.76, "top": 0.9, "bottom": 0.07,
                                              "hspace": 0.12})
