"""Per-channel scoreboards of a fit: RMS error in SI units and in noise levels, and the fit percentage."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from workbench.fit._objective import SimBatch, rms
from workbench.fit._targets import Target


@dataclass
class ChannelScore:
    """One channel on one part (training or held-out), SI units and in units of its noise level."""

    record: str
    channel: str
    unit: str
    part: str
    n: int
    rms: float
    sigma: float
    fit_pct: float

    @property
    def rms_sigma(self) -> float:
        return self.rms / self.sigma


def channel_scores(targets: Sequence[Target], sim: SimBatch, member: int = 0) -> list[ChannelScore]:
    out = []
    for tg, y in zip(targets, sim.y):
        for part, mask in (("train", tg.train), ("held", tg.held)):
            if not mask.any():
                continue
            for j, c in enumerate(tg.channels):
                meas = tg.measured[j, mask]
                e = meas - y[member, j, mask]
                den = float(np.linalg.norm(meas - meas.mean()))
                fitp = 100.0 * (1 - float(np.linalg.norm(e)) / den) if den > 0 else float("nan")
                out.append(ChannelScore(tg.name, c, tg.units[j], part, int(mask.sum()), rms(e), float(tg.sigma[j]),
                                        fitp))
    return out
