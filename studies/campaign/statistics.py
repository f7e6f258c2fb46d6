"""Detection statistics: fault counts, probabilities and Wilson score intervals per deviation range."""

from __future__ import annotations

import math
from dataclasses import dataclass
from statistics import NormalDist
from typing import Any


def wilson_interval(k: int, n: int, confidence: float = 0.95) -> tuple[float, float]:
    """Wilson score interval for a binomial proportion ``k/n`` (NaNs if ``n == 0``); always ``lo <= k/n <= hi``.

    ``centre = (p + z²/2n) / (1 + z²/n)``, ``half = z/(1 + z²/n) · sqrt(p(1−p)/n + z²/4n²)``; unlike the
    normal (Wald) interval it stays inside [0, 1] and is not degenerate at 0 or ``n`` detections.
    """
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence must be in (0, 1), got {confidence!r}")
    if n < 0 or k < 0 or k > n:
        raise ValueError(f"need 0 <= k <= n, got k={k!r}, n={n!r}")
    if n == 0:
        return math.nan, math.nan
    z = NormalDist().inv_cdf(0.5 + confidence / 2.0)
    p = k / n
    denom = 1.0 + z * z / n
    centre = (p + z * z / (2.0 * n)) / denom
    half = z / denom * math.sqrt(p * (1.0 - p) / n + z * z / (4.0 * n * n))
    # In exact arithmetic 0 <= lo <= p <= hi <= 1 (lo = 0 at k = 0, hi = 1 at k = n); in floating point the edges
    # come out a hair on the wrong side of p (hi = 1 - 1e-16 < p = 1 for some n), which made error bars negative.
    return min(max(0.0, centre - half), p), max(min(1.0, centre + half), p)


@dataclass(frozen=True)
class DetectionStat:
    """Detected BIT faults among the runs of one MBIT (or ``"any"``: either MBIT) in one deviation range."""

    mbit: str  # MBIT key, or "any"
    label: str  # "MBIT.a"
    lo: float  # range, fractions
    hi: float
    n_runs: int
    n_failed: int  # integration failures (excluded from the probability)
    n_detected: int

    @property
    def n_valid(self) -> int:
        return self.n_runs - self.n_failed

    @property
    def probability(self) -> float:
        return self.n_detected / self.n_valid if self.n_valid else math.nan

    @property
    def interval(self) -> tuple[float, float]:
        return wilson_interval(self.n_detected, self.n_valid)

    @property
    def range_label(self) -> str:
        return f"{self.lo * 100:g}-{self.hi * 100:g}%"

    def row(self) -> dict[str, Any]:  # a row of fig11_table.csv (column name → cell): the file's edge
        lo, hi = self.interval
        return {"mbit": self.mbit, "label": self.label, "range_lo_pct": self.lo * 100, "range_hi_pct": self.hi * 100,
                "n_runs": self.n_runs, "n_failed": self.n_failed, "n_detected": self.n_detected,
                "probability": self.probability, "ci95_low": lo, "ci95_high": hi}
