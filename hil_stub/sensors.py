"""The rig's sensors: what the board reads of the truth plant, with seeded Gaussian noise and scheduled faults."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from drivers.link import FLAG_LIMIT_REFUSED, FLAG_SENSOR_FAULT, RigSample

#: rows of standard-normal noise drawn at once (one row per sample: z3, v_patch, z0dd)
NOISE_ROWS = 1000
_LIST_CHUNK = 32  # rows turned into lists at a time for per-sample reads (quiet spans read the array itself)


@dataclass(slots=True)
class TruthReading:
    """Noise-free sensor quantities at a tick boundary (SI): the tip displacement as the laser sees it (m), the
    patch terminal voltage (V), the cell's terminal voltage (V; NaN when the cell is not part of the active plant)
    and the base acceleration (m/s^2)."""

    z3: float
    v_patch: float
    v_battery: float
    z0dd: float


@dataclass(frozen=True)
class SensorNoise:
    """1-sigma white noise of the laser (m), the patch-voltage channel (V) and the base accelerometer (m/s^2)."""

    z3: float
    v_patch: float
    accel: float


class RigSensors:
    """Turns a :class:`TruthReading` into a :class:`~drivers.link.RigSample`: adds noise drawn from the rig's seeded
    generator (one row per sample, so a sample is repeatable) and applies a scheduled sensor fault (``nan``: the
    laser reads NaN; ``flag``: the sample carries ``FLAG_SENSOR_FAULT``; ``out_of_range``: the laser reads 1 m;
    ``frozen_seq`` is the rig's: no new sample)."""

    def __init__(self, noise: SensorNoise, seed: int) -> None:
        self.noise = noise
        self._rng = np.random.default_rng([seed, 104729])
        self._rows_array = np.empty((0, 3))  # the rows drawn ahead (NOISE_ROWS at a time)
        self._i = 0  # the next unused row of _rows_array
        self._rows: list[list[float]] = []  # rows _lo .. _lo + len - 1 as lists (fast per-sample reads)
        self._lo = 0

    def _next_row(self) -> list[float]:
        """Row ``_i`` (drawing the next NOISE_ROWS when used up), via a short list chunk of the array."""
        if self._i >= self._rows_array.shape[0]:
            self._rows_array = self._rng.standard_normal((NOISE_ROWS, 3))
            self._i = 0
        self._lo = self._i
        self._rows = self._rows_array[self._i: self._i + _LIST_CHUNK].tolist()
        self._i += 1
        return self._rows[0]

    def peek_noisy(self, z3: np.ndarray, v_patch: np.ndarray, z0dd: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The next ``len(z3)`` samples' noisy z3 (m), v_patch (V) and z0dd (m/s^2) from their noise-free values,
        without drawing (the same arithmetic as :meth:`sample`, element by element); shorter when fewer noise rows
        are drawn ahead (empty: the next :meth:`sample` draws)."""
        nz = self._rows_array[self._i: self._i + z3.shape[0]]
        n = nz.shape[0]
        noise = self.noise
        return (z3[:n] + noise.z3 * nz[:, 0], v_patch[:n] + noise.v_patch * nz[:, 1],
                z0dd[:n] + noise.accel * nz[:, 2])

    def skip(self, m: int) -> None:
        """Consume ``m`` rows peeked with :meth:`peek_noisy` (as ``m`` calls of :meth:`sample` would)."""
        self._i += m

    def sample(self, seq: int, t: float, reading: TruthReading, v_battery: float, fault: str | None,
               hv_present: bool, refused: bool) -> RigSample:
        """The sample ``seq`` at ``t`` (s); ``v_battery`` (V) is the cell's terminal voltage (``reading``'s, or the
        rig's own when the cell is outside the plant)."""
        j = self._i - self._lo
        if 0 <= j < len(self._rows):
            nz = self._rows[j]
            self._i += 1
        else:
            nz = self._next_row()
        noise = self.noise
        z3 = reading.z3 + noise.z3 * nz[0]
        vp = reading.v_patch + noise.v_patch * nz[1]
        zdd = reading.z0dd + noise.accel * nz[2]
        flags = FLAG_LIMIT_REFUSED if refused else 0
        if fault is not None:
            if fault == "nan":
                z3 = math.nan
            elif fault == "flag":
                flags |= FLAG_SENSOR_FAULT
            elif fault == "out_of_range":
                z3 = 1.0
        return RigSample(seq, t, z3, vp, zdd, v_battery, hv_present, flags)
