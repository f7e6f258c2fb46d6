"""Plausibility of one rig sample (stage 1 of :meth:`firmware_sim.board.Board.tick`): a rig fault flag, a value
outside its ``[sensors]`` range of ``board.toml`` (NaN included) or a rig time that is not finite. Pure: no I/O, no
clock."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from board_config.board import BoardConfig
from drivers.link import FLAG_RIG_FAULT, FLAG_SENSOR_FAULT, RigSample

_FAULT_FLAGS = FLAG_SENSOR_FAULT | FLAG_RIG_FAULT
_INF = math.inf


@dataclass(frozen=True, slots=True)
class SampleLimits:
    """The plausible range of each sampled value (``[sensors]`` of ``board.toml``)."""

    z3: float  # m, |z3| at most
    v_patch: float  # V, |v_patch| at most
    z0dd: float  # m/s^2, |z0dd| at most
    v_battery_max: float  # V, v_battery in [0, this]

    @classmethod
    def from_config(cls, cfg: BoardConfig) -> SampleLimits:
        return cls(cfg.sensors_z3_limit, cfg.sensors_v_patch_limit, cfg.sensors_z0dd_limit, cfg.sensors_v_battery_max)


def check_sample(sample: RigSample, limits: SampleLimits) -> str:
    """Why ``sample`` cannot be trusted ('' if it can): a rig fault flag, an out-of-range value (NaN included) or a
    rig time that is not finite. The common, plausible sample passes every test and gets ''."""
    if sample.flags & _FAULT_FLAGS:
        return f"rig flags 0x{sample.flags:x} (sensor/rig fault)"
    z3 = sample.z3
    if not abs(z3) <= limits.z3:  # also catches NaN
        return f"z3 = {z3!r} m outside ±{limits.z3:g} m"
    vp = sample.v_patch
    if not abs(vp) <= limits.v_patch:
        return f"v_patch = {vp!r} V outside ±{limits.v_patch:g} V"
    acc = sample.z0dd
    if not abs(acc) <= limits.z0dd:
        return f"z0dd = {acc!r} m/s^2 outside ±{limits.z0dd:g} m/s^2"
    vb = sample.v_battery
    if not 0.0 <= vb <= limits.v_battery_max:
        return f"v_battery = {vb!r} V outside [0, {limits.v_battery_max:g}] V"
    t = sample.t
    if not -_INF < t < _INF:
        return f"rig time {t!r} is not finite"
    return ""


def plausible_samples(z3: np.ndarray, abs_v_patch: np.ndarray, abs_z0dd: np.ndarray, v_battery: np.ndarray,
                      t: np.ndarray, limits: SampleLimits) -> np.ndarray:
    """:func:`check_sample`'s range and time tests over arrays of samples (a quiet span's, whose flags are all 0:
    ``drivers.quiet_span``): True where the sample passes them (``|v_patch|``, ``|z0dd|`` given: the caller needs
    them too)."""
    good: np.ndarray = ((np.abs(z3) <= limits.z3) & (abs_v_patch <= limits.v_patch) & (abs_z0dd <= limits.z0dd)
                        & (v_battery >= 0.0) & (v_battery <= limits.v_battery_max) & np.isfinite(t))
    return good
