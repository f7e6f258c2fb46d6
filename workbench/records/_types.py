"""What a measurement record is: :class:`Record` (time domain), :class:`FrfRecord` (frequency response), their
channels and segments, the format tags and the quantities the plant knows, and :class:`RecordError`.

Reading and writing live in :mod:`workbench.records` (the entry points) and the ``record_*`` modules beside it.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numpy as np

from board_config.errors import InputError
from board_config.physical_constants import G0
from plant.layout import N_INPUTS, U_V_CH1, U_V_CH2, U_Z0DD
from plant.signals import InputSignals
from workbench.records._units import Unit

FORMAT = "mfc-shm-record/1"
FRF_FORMAT = "mfc-shm-frf/1"

#: Model inputs a record may carry (``va`` is the differential drive, expanded to v_ch1 = +va, v_ch2 = -va).
INPUT_QUANTITIES: dict[str, str] = {"v_ch1": "V", "v_ch2": "V", "z0dd": "m/s^2", "va": "V"}
#: SI unit expected for the quantities the plant knows (others may carry any known unit).
KNOWN_QUANTITY_UNITS: dict[str, str] = {
    "time": "s", **INPUT_QUANTITIES,
    **{f"z{i}": "m" for i in (1, 2, 3)}, **{f"delta{i}": "m" for i in (1, 2, 3)}, "z3_meas": "m",
    **{f"q{i}": "C" for i in (1, 2, 3)}, **{f"qh{i}": "C" for i in (1, 2, 3)},
    **{f"v_patch{i}": "V" for i in (1, 2, 3)}, "v_stored": "V",
}
#: Test kinds the tools recognise (for regime labels); any other string is accepted as "other".
TEST_KINDS = ("mbit-a", "mbit-b", "step", "sine", "sweep", "frf", "free", "other")
TERMINALS = ("amplifier", "open_circuit")


class RecordError(InputError):
    """A record file is wrong. The message names the file, where (line/sample, column or key) and why."""

    def __init__(self, file: str | Path, reason: str, *, line: int | None = None, column: str | None = None,
                 key: str | None = None, where: str | None = None) -> None:
        self.file, self.reason, self.line, self.column, self.key = str(file), reason, line, column, key
        parts = [self.file]
        if where is not None:
            parts.append(where)
        elif line is not None:
            parts.append(f"line {line}")
        if column is not None:
            parts.append(f"column '{column}'")
        if key is not None:
            parts.append(f"metadata key '{key}'")
        super().__init__(": ".join([", ".join(parts), reason]))


@dataclass(frozen=True)
class Channel:
    """One column of a record, in SI units. ``name`` is the quantity (``z3``), ``column`` the header (``z3_mm``)."""

    name: str
    column: str
    unit: Unit
    values: np.ndarray
    role: str  # "input" | "output"
    model_output: str | None = None
    sensor: str | None = None
    position_m: float | None = None
    noise_std: float | None = None  # SI
    description: str = ""

    @property
    def si_unit(self) -> str:
        return self.unit.si


@dataclass(frozen=True)
class Segment:
    """A labelled stretch of a test (a regime): ``[start_s, end_s)``."""

    start_s: float
    end_s: float
    label: str


@dataclass(frozen=True)
class Gap:
    """A stretch of lost samples (docs/records.md, "Lost samples"): ``n_samples`` rows from ``start_s`` to
    ``end_s`` (both inclusive, s) whose measured values are missing; they are left out of the record."""

    start_s: float
    end_s: float
    n_samples: int


@dataclass(frozen=True)
class Record:
    """A time-domain measurement record (SI units inside).

    ``gaps``: stretches of lost samples left out of ``t`` and the channels (an empty cell in a CSV record written
    with ``missing = "empty"``, a NaN with ``missing = "nan"``). ``input_track``: when rows were left out, the
    record's full time base (s) and the model inputs ``(samples, 3)`` at every row, so that the inputs the rig
    received at a lost sample still drive the model (:meth:`input_signals`).
    """

    path: str
    test: str
    t: np.ndarray
    channels: Mapping[str, Channel]
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    segments: tuple[Segment, ...] = ()
    terminal: str | None = None
    meta: Mapping[str, Any] = field(default_factory=dict)
    gaps: tuple[Gap, ...] = ()
    input_track: tuple[np.ndarray, np.ndarray] | None = None

    kind = "time"

    @property
    def lost_samples(self) -> int:
        """How many rows were lost (left out of the record)."""
        return sum(g.n_samples for g in self.gaps)

    def gap_note(self) -> str:
        """One sentence for a report: how many samples were lost and where ('' when none were)."""
        if not self.gaps:
            return ""
        where = ", ".join(f"{g.start_s:.6g} s" if g.n_samples == 1 else f"{g.start_s:.6g}-{g.end_s:.6g} s"
                          for g in self.gaps[:5])
        more = f" and {len(self.gaps) - 5} more" if len(self.gaps) > 5 else ""
        return (f"{self.name}: {self.lost_samples} lost sample(s) in {len(self.gaps)} gap(s) (at {where}{more}) "
                "left out; the model is driven through them by the record's inputs")

    def __getitem__(self, name: str) -> np.ndarray:
        try:
            return self.channels[name].values
        except KeyError:
            raise KeyError(f"{self.path}: no channel '{name}' (channels: {', '.join(self.channels)})") from None

    @property
    def name(self) -> str:
        return Path(self.path).stem

    @property
    def n_samples(self) -> int:
        return int(self.t.size)

    @property
    def dt(self) -> float:
        """Median sample interval (s)."""
        return float(np.median(np.diff(self.t)))

    @property
    def sample_rate_Hz(self) -> float:
        return 1.0 / self.dt

    @property
    def duration_s(self) -> float:
        return float(self.t[-1] - self.t[0])

    @property
    def uniform(self) -> bool:
        """True when every interval is within 0.1 % of the median (the usual logger case)."""
        d = np.diff(self.t)
        return bool(np.max(np.abs(d - self.dt)) <= 1e-3 * self.dt)

    def input_matrix(self) -> np.ndarray:
        """The plant's inputs ``(samples, 3)`` [v_ch1 V, v_ch2 V, z0dd m/s^2] at the record's times."""
        u = np.zeros((self.n_samples, N_INPUTS))
        if "va" in self.inputs:
            u[:, U_V_CH1] += self["va"]
            u[:, U_V_CH2] -= self["va"]
        for name, idx in (("v_ch1", U_V_CH1), ("v_ch2", U_V_CH2), ("z0dd", U_Z0DD)):
            if name in self.inputs:
                u[:, idx] += self[name]
        return u

    def input_signals(self) -> InputSignals:
        """The inputs as :class:`plant.InputSignals` on a uniform grid (linearly resampled if the log jitters).

        A record with lost samples is driven by its full input track (the rows left out included)."""
        if self.input_track is not None:
            t_all, u_all = self.input_track
            d = np.diff(t_all)
            dt = float(np.median(d))
            if np.max(np.abs(d - dt)) <= 1e-3 * dt:
                return InputSignals(float(t_all[0]), dt, u_all)
        u = self.input_matrix()
        if self.uniform:
            return InputSignals(float(self.t[0]), self.dt, u)
        n = round(self.duration_s / self.dt) + 1
        grid = self.t[0] + self.dt * np.arange(n)
        ug = np.column_stack([np.interp(grid, self.t, u[:, j]) for j in range(N_INPUTS)])
        return InputSignals(float(self.t[0]), self.dt, ug)

    def drive(self) -> tuple[str, str, np.ndarray]:
        """The primary excitation for analysis: ``(name, SI unit, values)``.

        The differential voltage ``va = (v_ch1 - v_ch2)/2`` when the record drives the patches, else the
        base acceleration ``z0dd``. (The common mode of the channels does not bend the laminate.)
        """
        u = self.input_matrix()
        va = 0.5 * (u[:, U_V_CH1] - u[:, U_V_CH2])
        z = u[:, U_Z0DD]
        # compare activity relative to a typical full scale of each input (600 V, 1 g)
        if np.ptp(va) / 600.0 >= np.ptp(z) / G0 and np.ptp(va) > 0:
            return "va", "V", va
        return "z0dd", "m/s^2", z

    def slice(self, start_s: float, end_s: float) -> Record:
        """The part of the record with ``start_s <= t < end_s`` (for train/held-out splits)."""
        k = (self.t >= start_s) & (self.t < end_s)
        if np.count_nonzero(k) < 2:
            raise RecordError(self.path, f"slice [{start_s}, {end_s}) s holds fewer than 2 samples",
                              where=f"t = {self.t[0]:g} .. {self.t[-1]:g} s")
        chans = {n: replace(c, values=c.values[k]) for n, c in self.channels.items()}
        segs = tuple(Segment(max(s.start_s, start_s), min(s.end_s, end_s), s.label) for s in self.segments
                     if s.end_s > start_s and s.start_s < end_s)
        gaps = tuple(g for g in self.gaps if start_s <= g.start_s and g.end_s < end_s)
        track = None
        if self.input_track is not None and gaps:
            t_all, u_all = self.input_track
            keep = (t_all >= self.t[k][0]) & (t_all <= self.t[k][-1])
            track = (t_all[keep], u_all[keep])
        return replace(self, t=self.t[k], channels=MappingProxyType(chans), segments=segs, gaps=gaps,
                       input_track=track)


@dataclass(frozen=True)
class FrfChannel:
    """Measured frequency response of one output to the drive, SI ratio units (e.g. m/V)."""

    name: str
    unit_si: str
    response: np.ndarray  # complex, output amplitude / drive amplitude, phase relative to the drive
    coherence: np.ndarray | None = None
    model_output: str | None = None


@dataclass(frozen=True)
class FrfRecord:
    """A frequency-response table: stepped-sine amplitude and phase of outputs per frequency."""

    path: str
    frequency_Hz: np.ndarray
    drive: str  # "va" | "v_ch1" | "v_ch2" | "z0dd"
    drive_amplitude: float  # SI (V or m/s^2)
    responses: Mapping[str, FrfChannel]
    bias_V: float = 0.0
    terminal: str | None = None
    meta: Mapping[str, Any] = field(default_factory=dict)
    test: str = "frf"

    kind = "frf"

    @property
    def name(self) -> str:
        return Path(self.path).stem

    @property
    def outputs(self) -> tuple[str, ...]:
        return tuple(self.responses)


def full_rows(record: Record) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """The record's time (s) and channels (SI) on every row, the lost samples included as NaN (the inputs at a
    lost row from the record's input track). For a record without gaps: its own arrays."""
    if not record.gaps or record.input_track is None:
        return record.t, {n: ch.values for n, ch in record.channels.items()}
    t_all, u_all = record.input_track
    at = np.searchsorted(t_all, record.t)
    cols: dict[str, np.ndarray] = {}
    for n, ch in record.channels.items():
        v = np.full(t_all.size, np.nan)
        v[at] = ch.values
        if ch.role == "input" and n in ("v_ch1", "v_ch2", "z0dd"):
            v = u_all[:, {"v_ch1": U_V_CH1, "v_ch2": U_V_CH2, "z0dd": U_Z0DD}[n]].copy()
        cols[n] = v
    return t_all, cols
