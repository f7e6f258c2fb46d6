"""Two small effects on the tip mass, written the way a user writes an effect file (only ``plant``'s public names):
tests that need an effect of their own subclass one (their own ``name`` and ``parameters``, the hooks inherited), and
``tests/workbench/test_fit.py`` copies this file as a user's effect file.

* :class:`TipSpring`: a spring from the tip to the frame, F_m3 −= k z3 (k the first parameter, N/m);
* :class:`TipCable`: a sensor cable hanging from the tip, F_m3 −= k_c z3 + c_c ż3.
"""

from __future__ import annotations

from plant import Parameter, PhysicalEffect
from plant.layout import B_FM, B_Z, B_ZD


class TipSpring(PhysicalEffect):
    """A spring from the tip mass to the frame: F_m3 −= k z3 (the offsets seam: k is the effect's first parameter)."""

    name = "tip_spring"
    parameters = (Parameter("k_tip", "N/m", 0.0, 0.0, 100.0, "tip stiffness"),)

    @staticmethod
    def rates(t, x, p, bus, dx, so, po):
        bus[B_FM + 2] -= p[po] * bus[B_Z + 2]


class TipCable(PhysicalEffect):
    """A sensor cable hanging from the tip: spring k_c and viscous drag c_c on the tip mass."""

    name = "tip_cable"
    description = "Cable at the tip: F_m3 += −k_c z3 − c_c ż3"
    origin = "instrumentation cable clipped to the laminate tip"
    signature = "stroke slightly lower, ringing damped faster"
    parameters = (Parameter("k_cable", "N/m", 0.0, 0.0, 50.0, "cable stiffness"),
                  Parameter("c_cable", "N*s/m", 0.0, 0.0, 0.5, "cable damping"))

    @staticmethod
    def rates(t, x, p, bus, dx, so, po):
        bus[B_FM + 2] -= p[po] * bus[B_Z + 2] + p[po + 1] * bus[B_ZD + 2]
