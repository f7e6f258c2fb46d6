"""Patch terminals: what sets the terminal voltage v_a (exactly one terminal per model)."""

from __future__ import annotations

from plant.effect import PhysicalEffect
from plant.layout import B_IR, X_Q


class AmplifierDrive(PhysicalEffect):
    """The high-voltage amplifier is an ideal voltage source: v_a = (v_ch1 − v_ch2)/2.

    The two channels drive the two sides at opposite voltages; only the differential part bends the
    laminate (the common part would stretch it in-plane, which the bending model does not represent).
    """

    name = "amplifier"
    role = "terminal"
    description = "Ideal voltage source on the patches: v_a = (v_ch1 − v_ch2)/2"
    origin = "Actuation mode of the rig (seed paper Fig. 4, black flows)"

    @staticmethod
    def pre(t, x, p, bus, dx, X, P, B):
        va = 0.5 * (bus[B.v_ch1] - bus[B.v_ch2])
        bus[B.va_demand] = va
        bus[B.va] = va

    @staticmethod
    def post(t, x, p, bus, dx, X, P, B):
        bus[B.i_term] = -(bus[B_IR] + bus[B_IR + 1] + bus[B_IR + 2])


class OpenCircuit(PhysicalEffect):
    """The patch couples in parallel on a high-impedance voltmeter: Σ i_R,i = 0, so v_a = mean(q_i)/C_ep.

    This is the sensing / "stored voltage" configuration of Fig. 6b (multimeter on the patches).
    """

    name = "open_circuit"
    role = "terminal"
    description = "Patches in parallel on a voltmeter (no load): v_a = mean(q_i)/C_ep"
    origin = "Sensing/harvesting mode of the rig (seed paper Fig. 4, red flows; multimeter F)"

    @staticmethod
    def pre(t, x, p, bus, dx, X, P, B):
        va = (x[X_Q] + x[X_Q + 1] + x[X_Q + 2]) / (3.0 * p[P.C_ep])
        bus[B.va_demand] = va
        bus[B.va] = va
        bus[B.i_term] = 0.0
