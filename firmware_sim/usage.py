"""Usage acquisition during SENSING: peak deformation, rainflow cycle counting, exceedance durations.

Pure, streaming and bounded: :class:`UsageEpisode` takes one sample per tick (``add(t, z3, z0dd)``) and keeps only
peaks, exceedance counters and the *turning points* of the tip deflection ``z3`` (a hysteresis-gated reversal
filter: a reversal is confirmed only once the signal has moved back by more than ``gate``, so sensor noise does not
become fatigue cycles). At the end, :meth:`UsageEpisode.summary` counts cycles on the turning points with the
``rainflow`` package (ASTM E1049-85 four-point algorithm; half cycles count 0.5) — with ``gate = 0`` this gives the
same cycles as ``rainflow`` on the full series (tested).

Exceedance: for each level ``L`` of ``[sensing] exceedance_levels`` (m), the time with ``|z3| >= L`` (s) and the
number of up-crossings of ``|z3|`` through ``L``.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import rainflow


class TurningPoints:
    """Streaming reversal extraction with a hysteresis gate (m). ``points`` are (t, value) pairs."""

    __slots__ = ("_cand", "_cand_t", "_dir", "_last", "_last_t", "gate", "points")

    def __init__(self, gate: float = 0.0) -> None:
        if not gate >= 0:
            raise ValueError(f"gate must be >= 0, got {gate!r}")
        self.gate = float(gate)
        self.points: list[tuple[float, float]] = []
        self._cand = math.nan  # candidate extremum
        self._cand_t = 0.0
        self._dir = 0  # +1 rising, -1 falling, 0 unknown
        self._last = math.nan
        self._last_t = 0.0

    def add(self, t: float, x: float) -> None:
        self._last, self._last_t = x, t
        if not self.points:
            self.points.append((t, x))
            self._cand, self._cand_t = x, t
            return
        d = self._dir
        if d == 1:
            if x > self._cand:
                self._cand, self._cand_t = x, t
            elif self._cand - x > self.gate:
                self.points.append((self._cand_t, self._cand))  # a peak confirmed
                self._cand, self._cand_t, self._dir = x, t, -1
        elif d == -1:
            if x < self._cand:
                self._cand, self._cand_t = x, t
            elif x - self._cand > self.gate:
                self.points.append((self._cand_t, self._cand))  # a valley confirmed
                self._cand, self._cand_t, self._dir = x, t, 1
        else:  # direction not known yet: wait until the signal leaves the gate around the first sample
            x0 = self.points[0][1]
            if x - x0 > self.gate:
                self._cand, self._cand_t, self._dir = x, t, 1
            elif x0 - x > self.gate:
                self._cand, self._cand_t, self._dir = x, t, -1

    def series(self) -> list[float]:
        """Turning-point values including the pending extremum and the last sample (for counting)."""
        vals = [v for _, v in self.points]
        if len(self.points) and (self._cand_t > self.points[-1][0]):
            vals.append(self._cand)
        if math.isfinite(self._last) and (self._last_t > (self._cand_t if vals else -math.inf)):
            vals.append(self._last)
        return vals


@dataclass(frozen=True)
class UsageSummary:
    """One usage episode (or a slice of a long one), SI units."""

    t_start: float  # s
    t_end: float  # s
    samples: int
    peak_z3: float  # m, max |z3|
    peak_z3_pos: float  # m, max z3
    peak_z3_neg: float  # m, min z3
    peak_z0dd: float  # m/s^2, max |z0dd|
    n_reversals: int
    cycles: tuple[tuple[float, float, float], ...]  # (range m, mean m, count 0.5|1)
    exceedance_levels: tuple[float, ...]  # m
    exceedance_time: tuple[float, ...]  # s, per level
    exceedance_count: tuple[int, ...]  # up-crossings per level
    bin_width: float  # m, rainflow histogram bin width
    reason: str  # why the summary was written: quiet, max_episode, brownout, hv_present, fault, end

    @property
    def duration(self) -> float:
        return self.t_end - self.t_start

    @property
    def n_cycles(self) -> float:
        """Cycle count (half cycles count 0.5)."""
        return float(sum(c for _, _, c in self.cycles))

    @property
    def max_range(self) -> float:
        return max((r for r, _, _ in self.cycles), default=0.0)

    def histogram(self) -> list[tuple[float, float, float]]:
        """Rainflow range histogram: (bin low m, bin high m, cycles)."""
        if not self.cycles:
            return []
        w = self.bin_width
        nb = math.floor(self.max_range / w) + 1
        counts = np.zeros(nb)
        for r, _, c in self.cycles:
            counts[min(int(r // w), nb - 1)] += c
        return [(i * w, (i + 1) * w, float(counts[i])) for i in range(nb) if counts[i] > 0]

    def as_record(self) -> dict[str, Any]:
        """Flat dict for the usage log (``usage_summaries`` table)."""
        return {
            "t_start_s": self.t_start, "t_end_s": self.t_end, "duration_s": self.duration, "samples": self.samples,
            "peak_z3_m": self.peak_z3, "peak_z3_pos_m": self.peak_z3_pos, "peak_z3_neg_m": self.peak_z3_neg,
            "peak_z0dd_m_s2": self.peak_z0dd, "n_reversals": self.n_reversals, "n_cycles": self.n_cycles,
            "max_range_m": self.max_range, "reason": self.reason,
            "rainflow_json": json.dumps([{"range_low_m": a, "range_high_m": b, "cycles": c}
                                         for a, b, c in self.histogram()]),
            "exceedance_json": json.dumps([{"level_m": lv, "time_s": ts, "upcrossings": n}
                                           for lv, ts, n in zip(self.exceedance_levels, self.exceedance_time,
                                                                self.exceedance_count)]),
        }


class UsageEpisode:
    """Streaming usage acquisition for one SENSING episode (one sample per tick of ``dt`` seconds)."""

    def __init__(self, t_start: float, dt: float, levels: tuple[float, ...], gate: float = 0.0,
                 bin_width: float = 0.25e-3) -> None:
        self.t_start = float(t_start)
        self.dt = float(dt)
        self.levels = tuple(float(v) for v in levels)
        self.bin_width = float(bin_width)
        self.tp = TurningPoints(gate)
        self.samples = 0
        self.peak_pos = -math.inf
        self.peak_neg = math.inf
        self.peak_acc = 0.0
        self._above = [False] * len(self.levels)
        self._time = [0.0] * len(self.levels)
        self._count = [0] * len(self.levels)
        self.t_last = self.t_start

    def add(self, t: float, z3: float, z0dd: float) -> None:
        """One sample: time (s), tip deflection (m), base acceleration (m/s^2). Non-finite values are skipped."""
        if not (math.isfinite(z3) and math.isfinite(z0dd)):
            return
        self.samples += 1
        self.t_last = t
        if z3 > self.peak_pos:
            self.peak_pos = z3
        if z3 < self.peak_neg:
            self.peak_neg = z3
        a = abs(z0dd)
        if a > self.peak_acc:
            self.peak_acc = a
        self.tp.add(t, z3)
        m = abs(z3)
        for i, lv in enumerate(self.levels):
            if m >= lv:
                self._time[i] += self.dt
                if not self._above[i]:
                    self._above[i] = True
                    self._count[i] += 1
            elif self._above[i]:
                self._above[i] = False
            else:
                break  # levels increase: none of the higher ones is reached either

    def summary(self, t_end: float, reason: str) -> UsageSummary:
        series = self.tp.series()
        cycles = rainflow_cycles(series)
        pos = self.peak_pos if self.samples else 0.0
        neg = self.peak_neg if self.samples else 0.0
        return UsageSummary(
            t_start=self.t_start, t_end=float(t_end), samples=self.samples, peak_z3=max(abs(pos), abs(neg)),
            peak_z3_pos=pos, peak_z3_neg=neg, peak_z0dd=self.peak_acc, n_reversals=len(series), cycles=cycles,
            exceedance_levels=self.levels, exceedance_time=tuple(self._time), exceedance_count=tuple(self._count),
            bin_width=self.bin_width, reason=reason)


def rainflow_cycles(series: list[float]) -> tuple[tuple[float, float, float], ...]:
    """Rainflow cycles (range, mean, count) of turning points. ``rainflow`` yields nothing for a two-point series
    (one monotone excursion) although it counts the same excursion as a half cycle inside a longer series; we count
    it as the half cycle it is."""
    if len(series) < 2:
        return ()
    if len(series) == 2:
        a, b = series
        return ((abs(b - a), 0.5 * (a + b), 0.5),) if a != b else ()
    return tuple((float(r), float(mn), float(c)) for r, mn, c, _, _ in rainflow.extract_cycles(series))


def cycles_of_series(series: np.ndarray) -> list[tuple[float, float, float]]:
    """Reference: rainflow cycles (range, mean, count) of a full series, as the ``rainflow`` package counts them."""
    return [(float(r), float(mn), float(c)) for r, mn, c, _, _ in rainflow.extract_cycles(list(map(float, series)))]
