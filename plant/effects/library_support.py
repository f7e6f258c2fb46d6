"""Support for the effects library: fit ranges and the data an effect's ``guess`` may read.

A library effect (creep, stiffening, air damping, ...) declares what the workbench needs on each parameter's own
declaration (:class:`plant.effect.Parameter`; docs/effects.md lists every field and why):

``neutral=``
    the value at which the effect leaves the response exactly unchanged (the nominal model);
``fit=``
    a :class:`FitRange` (search interval, linear, logarithmic or symmetric-log scaling) for each parameter the
    workbench fits; those without one stay at their value (e.g. a literature coefficient whose product with
    another parameter is all the data can identify); ``fit_by_default=False`` keeps a declared range for an
    explicit ``--free NAME`` only;
``challenge=``
    (weak, medium, strong): the values the hidden-effect challenge hides the effect at;

and, on the class, ``library_order`` (optional: where the reports list it; the first eight are 1..8, without it an
effect comes after them) and ``short_name`` (optional: a short column label for the challenge's confusion matrix).
An effect's guess clips into a declared range with ``cls.fit_range(NAME).clip(value)``.

Membership needs no list: every effect of role ``"effect"`` in a file of ``plant/effects`` is registered on import
and is in the library (:func:`plant.effect.library_effects`).

The ``guess(data)`` hook of an effect receives a mapping with any of these keys (all optional; an effect
falls back to its defaults for what is missing):

``"t_s"``        1-D time array (s);
``"inputs"``     ``{"v_ch1": V, "v_ch2": V, "z0dd": m/s^2}`` arrays on ``t_s``;
``"measured"``   measured channels by model output name (``"z3_meas"`` in m, ``"v_stored"`` in V, ...);
``"predicted"``  every output of the current model (without the effect) by name, on ``t_s``;
``"params"``     the current model's parameter values by name (SI).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from board_config.parameter import FitRange

__all__ = ["FitRange", "param", "regress", "residual", "series", "time_axis"]


def series(data: Mapping[str, Any] | None, group: str, name: str) -> np.ndarray | None:
    """``data[group][name]`` as a float array, or None when absent or malformed."""
    if not data:
        return None
    table = data.get(group)
    if not isinstance(table, Mapping) or name not in table:
        return None
    arr = np.asarray(table[name], dtype=float).ravel()
    return arr if arr.size and np.all(np.isfinite(arr)) else None


def residual(data: Mapping[str, Any] | None, channel: str = "z3_meas") -> tuple[np.ndarray, np.ndarray] | None:
    """(measured − predicted, predicted) on ``channel``, or None when either is missing."""
    meas = series(data, "measured", channel)
    pred = series(data, "predicted", channel)
    if meas is None or pred is None or meas.size != pred.size:
        return None
    return meas - pred, pred


def param(data: Mapping[str, Any] | None, name: str, default: float) -> float:
    """A model parameter from ``data["params"]``, else ``default``."""
    if data and isinstance(data.get("params"), Mapping) and name in data["params"]:
        value = float(data["params"][name])
        if math.isfinite(value):
            return value
    return default


def time_axis(data: Mapping[str, Any] | None, n: int) -> np.ndarray:
    """``data["t_s"]`` if it has ``n`` samples, else sample indices (s unknown)."""
    t = None if not data else data.get("t_s")
    if t is not None:
        arr = np.asarray(t, dtype=float).ravel()
        if arr.size == n:
            return arr
    return np.arange(n, dtype=float)


def regress(y: np.ndarray, x: np.ndarray) -> float:
    """Least-squares slope b of y ≈ b·x (through the origin); 0 when x carries nothing."""
    den = float(np.dot(x, x))
    return float(np.dot(x, y) / den) if den > 0 else 0.0
