"""The rig's environment from a scenario: base acceleration z̈0(t) (m/s^2), HV-equipment presence, and the
scheduled rig-side incidents (link outages, sensor faults, extra battery loads).

Everything is generated once, deterministically from the scenario's seed, on a uniform grid at
``RigSpec.env_rate`` (default 1 kHz): band-limited Gaussian vibration per phase (4th-order Butterworth band-pass
of white noise, scaled to the phase's rms, with 0.5 s cross-fades between phases), optional tones, the landing
touchdown transient (a decaying sine) and gusts (1−cos pulses or Hann-windowed bursts). After the scenario's end the
environment is quiet (z̈0 = 0) and the last phase's HV presence holds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import signal

from board_config.scenario import Phase, Scenario

FADE_S = 0.5  # cross-fade between phases (s)


@dataclass(frozen=True, slots=True)
class Segment:
    """Everything the scenario schedules for the rig at some time; it holds until ``until`` (s), the next start or
    end of a scheduled interval."""

    hv_present: bool
    sensor_fault: str | None  # nan, flag, frozen_seq, out_of_range or None
    link_down: bool
    extra_load: float  # A, drawn from the board cell by a failing component
    until: float


class Environment:
    """Base acceleration and HV presence as functions of rig time ``t`` (s)."""

    def __init__(self, scenario: Scenario | None, seed: int, rate: float = 1000.0) -> None:
        self.scenario = scenario
        self.seed = int(seed)
        self.rate = float(rate)
        self.dt = 1.0 / self.rate
        if scenario is None or not scenario.phases:
            self.duration = 0.0
            self.z0dd = np.zeros(2)
            self._hv = []
            self._faults: list[tuple[float, float, str]] = []
            self._outages: list[tuple[float, float]] = []
            self._loads: list[tuple[float, float, float]] = []
            return
        self.duration = scenario.duration
        n = math.ceil(self.duration * self.rate) + 2
        t = np.arange(n) * self.dt
        z = np.zeros(n)
        for i, ph in enumerate(scenario.phases):
            z += self._phase_signal(ph, i, t)
        for ev in scenario.events_of("gust"):
            z += _gust(ev.at, ev.duration, ev.peak, ev.frequency, t)
        self.z0dd = z
        self._hv = scenario.hv_intervals()
        self._faults = [(e.at, e.end, e.mode) for e in scenario.events_of("sensor_fault")]
        self._outages = [(e.at, e.end) for e in scenario.events_of("link_outage")]
        self._loads = [(e.at, e.end, e.current) for e in scenario.events_of("battery_load")]

    def _phase_signal(self, ph: Phase, index: int, t: np.ndarray) -> np.ndarray:
        i0 = max(0, math.floor((ph.start - FADE_S) * self.rate))
        i1 = min(t.size, math.ceil((ph.end + FADE_S) * self.rate) + 1)
        tt = t[i0:i1]
        out = np.zeros(t.size)
        seg = np.zeros(tt.size)
        rng = np.random.default_rng([self.seed, 7919, index])
        if ph.vibration_rms > 0.0:
            nyq = 0.5 * self.rate
            hi = min(ph.band_high, 0.45 * self.rate)
            lo = min(ph.band_low, 0.5 * hi)
            sos = signal.butter(4, [lo / nyq, hi / nyq], btype="bandpass", output="sos")
            pad = int(2.0 * self.rate)  # filter warm-up
            w = rng.standard_normal(tt.size + pad)
            v = signal.sosfilt(sos, w)[pad:]
            std = float(np.std(v))
            if std > 0:
                seg += v * (ph.vibration_rms / std)
        if ph.tone_amplitude > 0.0 and ph.tone_frequency > 0.0:
            phase0 = rng.uniform(0, 2 * np.pi)
            seg += ph.tone_amplitude * np.sin(2 * np.pi * ph.tone_frequency * tt + phase0)
        # cross-fade window: 1 inside the phase, raised-cosine ramps of FADE_S centred on its edges
        win = np.ones(tt.size)
        if ph.start > 0:
            win *= _ramp((tt - (ph.start - FADE_S / 2)) / FADE_S)
        if self.scenario is not None and ph is not self.scenario.phases[-1]:
            win *= 1.0 - _ramp((tt - (ph.end - FADE_S / 2)) / FADE_S)
        else:
            win *= tt < ph.end
        seg *= win
        if ph.kind == "landing" and ph.touchdown_peak > 0:
            tau = tt - ph.start
            m = tau >= 0
            envelope = np.exp(-tau[m] / ph.touchdown_decay) * np.minimum(1.0, tau[m] / 0.01)
            seg[m] += ph.touchdown_peak * envelope * np.cos(2 * np.pi * ph.touchdown_frequency * tau[m])
        out[i0:i1] = seg
        return out

    # --- queries ------------------------------------------------------------------------------------
    def base_acceleration(self, times: np.ndarray) -> np.ndarray:
        """z̈0 (m/s^2) at ``times`` (s), linearly interpolated on the environment grid; 0 outside it."""
        return np.interp(times, np.arange(self.z0dd.size) * self.dt, self.z0dd, left=0.0, right=0.0)

    def grid_slice(self, i0: int, i1: int) -> np.ndarray:
        """Grid samples ``i0..i1`` inclusive (zeros past the end)."""
        if i1 < self.z0dd.size:
            return self.z0dd[i0:i1 + 1]
        out = np.zeros(i1 - i0 + 1)
        if i0 < self.z0dd.size:
            out[: self.z0dd.size - i0] = self.z0dd[i0:]
        return out

    def hv_present(self, t: float) -> bool:
        for a, b in self._hv:
            if a <= t < b:
                return True
        if self._hv and self.scenario is not None and t >= self.duration:
            return self.scenario.phases[-1].hv_present
        return False

    def sensor_fault(self, t: float) -> str | None:
        """The sensor-fault mode active at ``t`` (nan, flag, frozen_seq, out_of_range) or None."""
        for a, b, mode in self._faults:
            if a <= t < b:
                return mode
        return None

    def link_down(self, t: float) -> bool:
        for a, b in self._outages:
            if a <= t < b:
                return True
        return False

    def extra_load(self, t: float) -> float:
        """Extra current drawn from the board battery at ``t`` by a failing component (A)."""
        return sum(c for a, b, c in self._loads if a <= t < b)

    def segment(self, t: float) -> Segment:
        """Everything scheduled at ``t``; it holds until ``Segment.until`` (the next start or end of a scheduled
        interval), so a caller can cache it instead of asking every tick."""
        return Segment(self.hv_present(t), self.sensor_fault(t), self.link_down(t), self.extra_load(t),
                       self.next_change(t))

    def next_change(self, t: float) -> float:
        """The next time after ``t`` at which HV presence, a sensor fault, an outage or a load starts or stops."""
        edges = [x for a, b in self._hv for x in (a, b)]
        edges += [x for a, b, _ in self._faults for x in (a, b)]
        edges += [x for a, b in self._outages for x in (a, b)]
        edges += [x for a, b, _ in self._loads for x in (a, b)]
        later = [x for x in edges if x > t + 1e-12]
        return min(later) if later else math.inf


def _ramp(s: np.ndarray) -> np.ndarray:
    """0 for s<=0, 1 for s>=1, raised cosine in between."""
    s = np.clip(s, 0.0, 1.0)
    return 0.5 - 0.5 * np.cos(np.pi * s)


def _gust(at: float, duration: float, peak: float, frequency: float, t: np.ndarray) -> np.ndarray:
    tau = (t - at) / duration
    m = (tau >= 0) & (tau <= 1)
    out = np.zeros(t.size)
    if frequency > 0:
        out[m] = peak * np.sin(np.pi * tau[m]) ** 2 * np.sin(2 * np.pi * frequency * (t[m] - at))
    else:
        out[m] = peak * 0.5 * (1.0 - np.cos(2 * np.pi * tau[m]))
    return out
