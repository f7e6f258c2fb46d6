"""Fault injection for the HIL stub: what the rig does wrong, on purpose and reproducibly (seeded).

Three layers, each independent of the transport:

* :class:`LinkFaults` — the wire: drop or corrupt a fraction of the rig's replies, add latency (with
  jitter), disconnect every endpoint at a rig time for a while. Applied by each server through a
  :class:`ReplyFaulter` (one seeded random stream per server).
* :class:`SensorFaults` — the sensors: Gaussian noise per channel, a channel stuck (frozen) from a rig time,
  including ``seq`` (a frozen sample counter = a stale sensor path). Applied by :class:`SensorFaultRig`, a
  ``RigEndpoint`` wrapper (noise is drawn once per tick, so repeated reads of one tick agree).
* :class:`TruthChanges` — the physics: relative parameter deviations (``k3=-0.3`` → truth k3 = 0.7 × nominal)
  and added physical effects (registered names or dotted paths ``package.module:Class``). These are
  handed to the truth-rig factory (:mod:`hil_stub.truth`).

The spec strings accepted here are the ones of ``shm hil serve`` (``--noise z3=2e-6``, ``--stuck z3@12.5``,
``--deviation k3=-0.3``); every bad spec is a ``ValueError`` naming the flag, the value and what is allowed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from board_config.assignments import parse_assignments as parse_assignments
from board_config.assignments import parse_number
from board_config.errors import InputError
from board_config.parameter import ParameterError, deviation_problem
from drivers.link import ActuatorCommand, RigEndpoint, RigSample

SENSOR_CHANNELS = ("z3", "v_patch", "z0dd", "v_battery")
STUCK_CHANNELS = (*SENSOR_CHANNELS, "seq")
NOISE_UNITS = {"z3": "m", "v_patch": "V", "z0dd": "m/s^2", "v_battery": "V"}


@dataclass(frozen=True)
class LinkFaults:
    """Wire faults of one rig (applied to the rig's replies on every endpoint)."""

    drop: float = 0.0  #: fraction of replies not sent, [0, 1]
    corrupt: float = 0.0  #: fraction of replies sent with one bit flipped, [0, 1]
    latency_s: float = 0.0  #: added to the sample reply of every exchange (s)
    jitter_s: float = 0.0  #: uniform extra latency in [0, jitter_s] (s)
    processing_s: float = 0.0  #: the rig's processing time for every request (each Modbus transaction) (s)
    disconnect_at_s: float | None = None  #: rig time at which every endpoint goes away (s)
    disconnect_for_s: float = 1.0  #: how long it stays away (wall-clock s)

    def __post_init__(self) -> None:
        for name in ("drop", "corrupt"):
            v = getattr(self, name)
            if not 0.0 <= v <= 1.0:
                raise InputError(f"--{name} {v!r}: a fraction of replies, allowed [0, 1]")
        if self.drop + self.corrupt > 1.0:
            raise InputError(f"--drop {self.drop} + --corrupt {self.corrupt} exceeds 1")
        for name in ("latency_s", "jitter_s", "processing_s", "disconnect_for_s"):
            v = getattr(self, name)
            if not (math.isfinite(v) and 0.0 <= v <= 60.0):
                raise InputError(f"{name}={v!r} s outside [0, 60] s")
        if self.disconnect_at_s is not None and not (math.isfinite(self.disconnect_at_s) and self.disconnect_at_s >= 0):
            raise InputError(f"disconnect_at_s={self.disconnect_at_s!r} must be a rig time >= 0 s")

    @property
    def active(self) -> bool:
        return bool(self.drop or self.corrupt or self.latency_s or self.jitter_s or self.processing_s
                    or self.disconnect_at_s is not None)


class ReplyFaulter:
    """Decides, reply by reply, what the wire does (seeded; one per server)."""

    def __init__(self, faults: LinkFaults | None, seed: int, stream: int) -> None:
        self.faults = faults or LinkFaults()
        base = [int(seed) & 0xFFFFFFFF, 0xFA17, int(stream)]
        self._rng_action = np.random.default_rng([*base, 1])  # separate streams: the order of draws
        self._rng_delay = np.random.default_rng([*base, 2])  # of one kind never shifts the other
        self.rng = np.random.default_rng([*base, 3])  # bit positions
        self.dropped = 0
        self.corrupted = 0
        self.delayed = 0

    def decide(self) -> tuple[str, float]:
        """(``"send"`` | ``"drop"`` | ``"corrupt"``, delay in s) for the next reply."""
        return self.draw_action(), self.draw_delay()

    def draw_action(self) -> str:
        """``"send"``, ``"drop"`` or ``"corrupt"`` for the next reply."""
        f = self.faults
        if not (f.drop or f.corrupt):
            return "send"
        u = float(self._rng_action.random())
        if u < f.drop:
            self.dropped += 1
            return "drop"
        if u < f.drop + f.corrupt:
            self.corrupted += 1
            return "corrupt"
        return "send"

    def draw_delay(self) -> float:
        """Latency (s) to add to the next reply."""
        f = self.faults
        if not (f.latency_s or f.jitter_s):
            return 0.0
        self.delayed += 1
        return f.latency_s + (float(self._rng_delay.random()) * f.jitter_s if f.jitter_s else 0.0)

    def flip_bit(self, data: bytes, lo: int = 0, hi: int | None = None) -> bytes:
        """``data`` with one random bit flipped in bytes ``lo..hi-1``."""
        hi = len(data) if hi is None else min(hi, len(data))
        if hi <= lo:
            return data
        buf = bytearray(data)
        pos = int(self.rng.integers(lo, hi))
        buf[pos] ^= 1 << int(self.rng.integers(0, 8))
        return bytes(buf)

    def counts(self) -> dict[str, int]:
        return {"replies_dropped": self.dropped, "replies_corrupted": self.corrupted, "replies_delayed": self.delayed}


@dataclass(frozen=True)
class SensorFaults:
    """Sensor faults: noise sigma per channel (SI), and the rig time from which a channel is stuck."""

    noise: dict[str, float] = field(default_factory=dict)
    stuck: dict[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        for k, v in self.noise.items():
            if k not in SENSOR_CHANNELS:
                raise InputError(f"--noise {k}=...: unknown channel (allowed: {', '.join(SENSOR_CHANNELS)})")
            if not (math.isfinite(v) and v >= 0):
                raise InputError(f"--noise {k}={v!r}: sigma must be >= 0 {NOISE_UNITS[k]}")
        for k, v in self.stuck.items():
            if k not in STUCK_CHANNELS:
                raise InputError(f"--stuck {k}@...: unknown channel (allowed: {', '.join(STUCK_CHANNELS)})")
            if not (math.isfinite(v) and v >= 0):
                raise InputError(f"--stuck {k}@{v!r}: the rig time must be >= 0 s")

    @property
    def active(self) -> bool:
        return bool(self.noise or self.stuck)


class SensorFaultRig:
    """A ``RigEndpoint`` wrapper adding noise and stuck channels to another endpoint's samples."""

    def __init__(self, inner: RigEndpoint, faults: SensorFaults, seed: int) -> None:
        self.inner = inner
        self.faults = faults
        self.rng = np.random.default_rng([int(seed) & 0xFFFFFFFF, 0x5E45])
        self._noise = dict.fromkeys(faults.noise, 0.0)
        self._frozen: dict[str, float | int] = {}

    def apply(self, command: ActuatorCommand) -> None:
        self.inner.apply(command)

    def advance(self, dt: float) -> None:
        self.inner.advance(dt)
        for k, sigma in self.faults.noise.items():
            self._noise[k] = float(self.rng.normal(0.0, sigma)) if sigma > 0 else 0.0

    def sample(self) -> RigSample:
        s = self.inner.sample()
        changes: dict[str, Any] = {k: getattr(s, k) + v for k, v in self._noise.items()}  # RigSample fields
        for k, t_at in self.faults.stuck.items():
            if s.t >= t_at - 1e-9:  # rig time accumulates rounding: 10 x 0.01 s is 0.0999...9 s
                if k not in self._frozen:
                    self._frozen[k] = changes.get(k, getattr(s, k))
                changes[k] = self._frozen[k]
        return replace(s, **changes) if changes else s

    def __getattr__(self, name: str):  # expose the wrapped rig's extras (e.g. link_down, environment)
        return getattr(self.inner, name)


@dataclass(frozen=True)
class TruthChanges:
    """Changes to the truth plant: relative deviations of named parameters and added effects."""

    deviations: dict[str, float] = field(default_factory=dict)
    effects: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        for k, v in self.deviations.items():
            if (reason := deviation_problem(k, v)) is not None:
                raise ParameterError(f"--deviation {k}={v!r}: {reason}")

    @property
    def active(self) -> bool:
        return bool(self.deviations or self.effects)


@dataclass(frozen=True)
class FaultPlan:
    """Everything the rig does wrong, with the seed that makes it reproducible."""

    link: LinkFaults = field(default_factory=LinkFaults)
    sensors: SensorFaults = field(default_factory=SensorFaults)
    truth: TruthChanges = field(default_factory=TruthChanges)
    seed: int = 0

    def describe(self) -> list[str]:
        out = []
        lf = self.link
        if lf.drop:
            out.append(f"drop {100 * lf.drop:g} % of replies")
        if lf.corrupt:
            out.append(f"corrupt {100 * lf.corrupt:g} % of replies (one bit)")
        if lf.latency_s or lf.jitter_s:
            out.append(f"reply latency {1e3 * lf.latency_s:g} ms + U(0, {1e3 * lf.jitter_s:g}) ms")
        if lf.processing_s:
            out.append(f"rig processing {1e3 * lf.processing_s:g} ms per request")
        if lf.disconnect_at_s is not None:
            out.append(f"disconnect at rig t = {lf.disconnect_at_s:g} s for {lf.disconnect_for_s:g} s")
        out += [f"noise on {k}: sigma {v:g} {NOISE_UNITS[k]}" for k, v in self.sensors.noise.items()]
        out += [f"{k} stuck from rig t = {v:g} s" for k, v in self.sensors.stuck.items()]
        out += [f"truth {k} × {1 + v:g}" for k, v in self.truth.deviations.items()]
        out += [f"added effect {e}" for e in self.truth.effects]
        return out


# ------------------------------------------------------------------------------------------- spec parsing


def parse_stuck(specs: list[str] | None) -> dict[str, float]:
    """``["z3@12.5", "seq@20"]`` → channel → rig time (s); ``z3`` alone means from t = 0."""
    out: dict[str, float] = {}
    for spec in specs or []:
        for part in filter(None, (p.strip() for p in spec.split(","))):
            name, sep, at = part.partition("@")
            out[name.strip()] = parse_number("--stuck", part, at.strip()) if sep else 0.0
    return out
