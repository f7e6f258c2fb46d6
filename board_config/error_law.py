"""The seed paper's model-error law and the normalised error built on it — one implementation for the board's
condition monitor (Eq. 11, z3 with ``MonitorSettings.e0z``/``kerr_z``) and the workbench's metrics (Eq. 5, any
channel with a fitted or given ``e0``/``kerr``).

The model error grows linearly with the amplitude of the variable, Eq. (4)::

    |y_md - y_hw| = e0 + kerr * |y_hw|

and the normalised error divides by that law, Eq. (5) / Eq. (11)::

    eps = |y_md - y_hw| / (|y_hw| + e0 / kerr)

Argument order everywhere: the **model** first, the **measurement** (hardware) second — only the measurement
enters the denominator. Edges (reachable from the workbench, whose ``e0``/``kerr`` are fitted; the monitor's
settings are validated ``e0z > 0``, ``kerr_z > 0``):

* ``kerr <= 0``: undefined (NaN): the error does not grow with the amplitude, Eq. (5) divides by an infinite floor;
* a zero denominator (``e0 = 0`` and a zero measurement): ``0`` for a zero error, ``inf`` for a non-zero one;
* a NaN model or measurement gives NaN, an infinite one NaN or inf (the monitor counts any non-finite error as an
  invalid sample).

Pure: this module imports nothing else of ours.
"""

from __future__ import annotations

import math
from typing import overload

import numpy as np
from numpy.typing import ArrayLike


@overload
def normalised_error(model: float, measured: float, e0: float, kerr: float) -> float: ...
@overload
def normalised_error(model: ArrayLike, measured: ArrayLike, e0: float, kerr: float) -> np.ndarray: ...


def normalised_error(model: ArrayLike, measured: ArrayLike, e0: float, kerr: float) -> float | np.ndarray:
    """Eq. 5/11: ``|model - measured| / (|measured| + e0/kerr)`` (1), in the unit of ``model``/``measured`` and
    ``e0`` (m for z3). Two floats give a float (the board's 100 Hz loop); anything else gives an array, element by
    element, bit-identical to the float form."""
    if isinstance(model, float | int) and isinstance(measured, float | int):
        if kerr <= 0.0:
            return math.nan
        error = abs(model - measured)
        den = abs(measured) + e0 / kerr
        if den == 0.0:  # e0 = 0 at a zero measurement
            return error * math.inf if error else 0.0  # inf, or NaN for a NaN error
        return error / den
    measured_a = np.asarray(measured, dtype=float)  # the model minus a float array is float as well
    if kerr <= 0.0:
        return np.full(np.broadcast_shapes(np.shape(model), measured_a.shape), np.nan)
    with np.errstate(divide="ignore", invalid="ignore"):  # inf - inf, x / 0, 0 / 0: see the edges above
        error = np.abs(np.subtract(model, measured_a))
        den = np.abs(measured_a) + e0 / kerr
        eps = error / den  # a zero denominator: inf for an error, NaN for none (set to 0 below)
    return np.where((den == 0.0) & (error == 0.0), 0.0, eps)
