"""Maintenance built-in tests: channel-voltage sequences from the ``board_config`` MBIT definitions.

The differential drive ``v_a(t)`` (sine or step, seed Sec. 4.2) is split on the two channels as
``v_ch,i = common_mode + polarity_i * v_a(t)`` and then **always clamped to Table 1's voltage range**
(``board_config.load_mfc_limits()``, −500 … +1500 V). A clamp is never silent: the sequence carries a
:class:`ClampReport` (samples clamped per channel, the worst excess in volts, when it first happened), and
:func:`generate_mbit` warns (:class:`VoltageClampWarning`) or raises (``on_clamp="raise"``) when anything was
clipped. The plant sees the clamped channels, so the model and the hardware receive the same, legal drive.

Why MBIT.a carries a +100 V common-mode bias: a 600 V-amplitude differential sine with opposite channels puts
one channel at −600 V (< −500 V). A bias shared by both channels keeps them in [−500, +700] V; the laminate
bends with the differential ``(v_ch1 − v_ch2)/2`` only, so the bending drive is unchanged.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from board_config import MbitDefinition, MfcLimits, load_mfc_limits
from board_config.errors import InputError
from plant import InputSignals

ClampPolicy = Literal["warn", "raise", "report"]


class VoltageClampWarning(UserWarning):
    """An MBIT sequence had to be clamped to the MFC voltage limits."""


class MbitClampError(InputError):
    """An MBIT sequence exceeds the MFC voltage limits and clamping was refused (``on_clamp="raise"``)."""


@dataclass(frozen=True)
class ChannelClamp:
    """What clamping did to one channel."""

    channel: str  # "v_ch1" / "v_ch2"
    n_clamped: int  # samples changed by the clamp
    demand_min: float  # V, lowest demanded value before clamping
    demand_max: float  # V, highest demanded value before clamping
    worst_excess: float  # V, largest distance outside the limits (0 if none)
    first_time: float | None  # s, first clamped sample

    def describe(self) -> dict[str, Any]:
        return {"channel": self.channel, "n_clamped": self.n_clamped, "demand_min_V": self.demand_min,
                "demand_max_V": self.demand_max, "worst_excess_V": self.worst_excess,
                "first_time_s": self.first_time}


@dataclass(frozen=True)
class ClampReport:
    """Clamping of both channels to ``[voltage_min, voltage_max]`` (V)."""

    voltage_min: float
    voltage_max: float
    channels: tuple[ChannelClamp, ...]

    @property
    def clamped(self) -> bool:
        return any(c.n_clamped for c in self.channels)

    @property
    def n_clamped(self) -> int:
        return sum(c.n_clamped for c in self.channels)

    def message(self, label: str = "MBIT") -> str:
        if not self.clamped:
            return f"{label}: no clamping (all channel voltages within [{self.voltage_min:g}, {self.voltage_max:g}] V)"
        parts = [f"{c.channel}: {c.n_clamped} samples clamped, demand {c.demand_min:g}..{c.demand_max:g} V, "
                 f"worst excess {c.worst_excess:g} V, first at t={c.first_time:g} s"
                 for c in self.channels if c.n_clamped]
        return (f"{label}: channel voltages clamped to the MFC limits [{self.voltage_min:g}, {self.voltage_max:g}] V"
                f" (Table 1) — " + "; ".join(parts) + ". The applied bending drive differs from the definition;"
                " a common-mode bias may keep both channels in range.")

    def describe(self) -> dict[str, Any]:
        return {"clamped": self.clamped, "voltage_min_V": self.voltage_min, "voltage_max_V": self.voltage_max,
                "channels": [c.describe() for c in self.channels]}


def clamp_channel(t: np.ndarray, volts: np.ndarray, limits: MfcLimits, channel: str
                  ) -> tuple[np.ndarray, ChannelClamp]:
    """Clamp one channel's samples (V) to Table 1's range and describe what changed."""
    volts = np.asarray(volts, dtype=float)
    if not np.all(np.isfinite(volts)):
        raise InputError(f"{channel}: non-finite voltage demand at sample {int(np.argmax(~np.isfinite(volts)))}")
    clamped = np.clip(volts, limits.voltage_min, limits.voltage_max)
    changed = clamped != volts
    excess = np.maximum(volts - limits.voltage_max, limits.voltage_min - volts)
    info = ChannelClamp(
        channel=channel,
        n_clamped=int(changed.sum()),
        demand_min=float(volts.min()) if volts.size else 0.0,
        demand_max=float(volts.max()) if volts.size else 0.0,
        worst_excess=float(max(excess.max(), 0.0)) if volts.size else 0.0,
        first_time=float(t[np.argmax(changed)]) if changed.any() else None,
    )
    return clamped, info


def differential_waveform(defn: MbitDefinition, t: np.ndarray) -> np.ndarray:
    """The demanded differential drive ``v_a(t)`` (V) of an MBIT at times ``t`` (s)."""
    t = np.asarray(t, dtype=float)
    if defn.waveform == "sine":
        assert defn.frequency is not None
        tau = t - defn.t_start
        return np.where(tau >= 0.0, defn.amplitude * np.sin(2.0 * np.pi * defn.frequency * tau), 0.0)
    if defn.waveform == "step":
        rise = defn.rise_time if defn.rise_time is not None else defn.dt
        return defn.amplitude * np.clip((t - defn.t_start) / rise, 0.0, 1.0)
    raise InputError(f"{defn.source}: MBIT {defn.key}: unknown waveform {defn.waveform!r}")


@dataclass(frozen=True)
class MbitSequence:
    """An MBIT's channel-voltage command sequence, after clamping (SI units)."""

    definition: MbitDefinition
    t: np.ndarray  # s
    va_demand: np.ndarray  # V, differential drive as defined (before clamping)
    v_ch1: np.ndarray  # V, channel 1 command (clamped)
    v_ch2: np.ndarray  # V, channel 2 command (clamped)
    clamp: ClampReport

    @property
    def va_applied(self) -> np.ndarray:
        """Differential drive actually applied, ``(v_ch1 − v_ch2)/2`` (V)."""
        applied: np.ndarray = 0.5 * (self.v_ch1 - self.v_ch2)
        return applied

    @property
    def dt(self) -> float:
        return self.definition.dt

    def __len__(self) -> int:
        return int(self.t.size)

    def command(self, k: int) -> tuple[float, float]:
        """Channel voltages (V) of sample ``k`` (the board plays one per tick)."""
        return float(self.v_ch1[k]), float(self.v_ch2[k])

    def to_inputs(self) -> InputSignals:
        """The sequence as plant inputs (``v_ch1``, ``v_ch2``; no base acceleration)."""
        vals = np.zeros((1, self.t.size, 3))
        vals[0, :, 0] = self.v_ch1
        vals[0, :, 1] = self.v_ch2
        return InputSignals(float(self.t[0]), self.dt, vals)

    def columns(self) -> dict[str, np.ndarray]:
        """Unit-named columns for a CSV file."""
        return {"time_s": self.t, "va_demand_V": self.va_demand, "v_ch1_V": self.v_ch1, "v_ch2_V": self.v_ch2,
                "va_applied_V": self.va_applied}


def generate_mbit(defn: MbitDefinition, limits: MfcLimits | None = None, on_clamp: ClampPolicy = "warn"
                  ) -> MbitSequence:
    """Generate an MBIT's channel commands, clamped to Table 1 (``limits``; default the shipped table).

    ``on_clamp``: ``"warn"`` (default) emits a :class:`VoltageClampWarning` when anything was clamped,
    ``"raise"`` raises :class:`MbitClampError` instead, ``"report"`` leaves it to the caller to surface
    ``sequence.clamp`` (the report is attached in every case).
    """
    if on_clamp not in ("warn", "raise", "report"):
        raise ValueError(f"on_clamp must be 'warn', 'raise' or 'report', got {on_clamp!r}")
    limits = limits if limits is not None else load_mfc_limits()
    if defn.frequency is not None and defn.frequency > limits.frequency_max:
        raise InputError(f"{defn.source}: mbit.{defn.key}.frequency: {defn.frequency:g} Hz is above the MFC "
                         f"operational range (DC..{limits.frequency_max:g} Hz, Table 1)")
    t = np.arange(defn.n_samples) / defn.sample_rate
    va = differential_waveform(defn, t)
    p1, p2 = defn.channel_polarity
    v1, c1 = clamp_channel(t, defn.common_mode + p1 * va, limits, "v_ch1")
    v2, c2 = clamp_channel(t, defn.common_mode + p2 * va, limits, "v_ch2")
    report = ClampReport(limits.voltage_min, limits.voltage_max, (c1, c2))
    if report.clamped:
        if on_clamp == "raise":
            raise MbitClampError(f"{defn.source}: " + report.message(defn.label))
        if on_clamp == "warn":
            warnings.warn(report.message(defn.label), VoltageClampWarning, stacklevel=2)
    return MbitSequence(defn, t, va, v1, v2, report)
