"""Test-only physical effects for the workbench tests (hidden in synthetic records through the plant's effect seam).

They stand in for the effects library of workbench part 2 so that part 1 can be tested on its own: a cubic
(geometric) stiffening of the tip section and a constant laser-sensor offset.
"""

from __future__ import annotations

from plant.effect import OutputSpec, Parameter, PhysicalEffect
from plant.layout import B_S, X_DELTA, Y_Z3_MEAS


class CubicTipStiffening(PhysicalEffect):
    """Geometric stiffening of section 3: an extra section force −k3c·δ3³."""

    name = "test_cubic_tip"
    description = "Cubic stiffening of the tip section (test only)"
    parameters = (Parameter("k3_cubic", "N/m^3", 2.0e6, 0.0, 1e9, "cubic stiffness of section 3"),)
    signature = "odd-order, amplitude-dependent error; residual vs deflection is an odd cubic curve"
    origin = "large-deflection geometric stiffening"

    @staticmethod
    def rates(t, x, p, bus, dx, so, po):
        d = x[X_DELTA + 2]
        bus[B_S + 2] -= p[po] * d * d * d


class LaserOffset(PhysicalEffect):
    """A constant offset of the tip laser reading."""

    name = "test_laser_offset"
    description = "Constant laser offset (test only)"
    parameters = (Parameter("laser_offset", "m", 50e-6, -1e-2, 1e-2, "offset added to the laser reading"),)
    outputs = (OutputSpec("laser_offset_out", "m"),)
    signature = "constant residual"
    origin = "sensor zero error"

    @staticmethod
    def output(t, x, p, bus, y, so, po, yo):
        y[Y_Z3_MEAS] += p[po]
        y[yo] = p[po]
