"""Physical effects that are NOT in the library, written only here, for the discovery challenge
(:mod:`workbench.challenges.discovery`, ``tests/workbench/test_discover.py``, ``python -m bench --only discover``).

Each is physics a rig engineer meets, written the way an engineer would write it (not as a copy of a dictionary
term): dry friction at the tip, a transport delay on the drive (second-order Padé), a saturating laser, a quadratic
laser, a clearance at the root, a one-sided stop at the tip, velocity-squared drag on mass 2 only, a laser gain that
drifts, a polarisation-dependent (sign-asymmetric) drive gain, a low-pass filter in the laser's output. ``FOREIGN``
maps each to its challenge strengths and the words the discovery's description must contain.
"""

from __future__ import annotations

import math

from plant.effect import Parameter, PhysicalEffect, StateSpec
from plant.layout import B_FM, B_S, B_VA, B_VA_DEMAND, B_Z, B_ZD, X_DELTA, Y_Z3_MEAS


class TipDryFriction(PhysicalEffect):
    """Coulomb friction of the tip against a guide: F_m3 −= F_c · tanh(ż3 / v_s), v_s = 0.1 mm/s."""

    name = "foreign_tip_friction"
    parameters = (Parameter("F_coulomb", "N", 0.0, 0.0, 1.0, "dry friction force at the tip"),)

    @staticmethod
    def rates(t, x, p, bus, dx, so, po):
        bus[B_FM + 2] -= p[po] * math.tanh(bus[B_ZD + 2] / 1e-4)


class DriveTransportDelay(PhysicalEffect):
    """The patches see the commanded voltage T late: second-order Padé delay on v_a (two states)."""

    name = "foreign_drive_delay"
    parameters = (Parameter("T_delay", "s", 0.0, 0.0, 0.05, "transport delay of the drive"),)
    states = (StateSpec("pade1", "V", 1.0), StateSpec("pade2", "V*s", 1e-3))

    @staticmethod
    def rates(t, x, p, bus, dx, so, po):
        T = p[po]
        if T <= 0.0:
            return
        u = bus[B_VA_DEMAND]
        # H(s) = (1 − sT/2 + (sT)²/12)/(1 + sT/2 + (sT)²/12), controllable canonical form
        a1 = 6.0 / T
        a0 = 12.0 / (T * T)
        dx[so + 1] += x[so]
        dx[so] += u - a1 * x[so] - a0 * x[so + 1]

    @staticmethod
    def pre(t, x, p, bus, dx, so, po):
        T = p[po]
        if T <= 0.0:
            return
        a1 = 6.0 / T
        u = bus[B_VA_DEMAND]
        bus[B_VA] = u - 2.0 * a1 * x[so]


class SaturatingLaser(PhysicalEffect):
    """The laser's reading saturates towards its range end: z3_meas = L tanh(z3 / L)."""

    name = "foreign_laser_saturation"
    parameters = (Parameter("L_sat", "m", 1.0, 1e-5, 1.0, "saturation level of the laser reading"),)

    @staticmethod
    def output(t, x, p, bus, y, so, po, yo):
        z = bus[B_Z + 2]
        y[Y_Z3_MEAS] += p[po] * math.tanh(z / p[po]) - z


class QuadraticLaser(PhysicalEffect):
    """A triangulation laser's quadratic linearity error: z3_meas += β z3²."""

    name = "foreign_laser_quadratic"
    parameters = (Parameter("beta_laser", "1/m", 0.0, -1e4, 1e4, "quadratic linearity error"),)

    @staticmethod
    def output(t, x, p, bus, y, so, po, yo):
        z = bus[B_Z + 2]
        y[Y_Z3_MEAS] += p[po] * z * z


class RootClearance(PhysicalEffect):
    """Free play in the root clamp: within ±g the root section is softer by k_play (the clamp rattles)."""

    name = "foreign_root_clearance"
    parameters = (Parameter("k_play", "N/m", 0.0, 0.0, 1e3, "stiffness lost within the play"),
                  Parameter("g_play", "m", 1e-6, 1e-9, 1e-2, "half-width of the play"))

    @staticmethod
    def rates(t, x, p, bus, dx, so, po):
        d = x[X_DELTA]
        g = p[po + 1]
        bus[B_S] += p[po] * min(max(d, -g), g)


class TipStop(PhysicalEffect):
    """A stop above the tip: a one-sided contact stiffness F_m3 −= k_s (z3 − gap) when z3 > gap."""

    name = "foreign_tip_stop"
    parameters = (Parameter("k_stop", "N/m", 0.0, 0.0, 1e3, "contact stiffness of the stop"),
                  Parameter("gap_stop", "m", 1e-3, 0.0, 1e-2, "gap between the tip at rest and the stop"))

    @staticmethod
    def rates(t, x, p, bus, dx, so, po):
        over = bus[B_Z + 2] - p[po + 1]
        if over > 0.0:
            bus[B_FM + 2] -= p[po] * over


class Mass2Drag(PhysicalEffect):
    """Velocity-squared drag on mass 2 only (a cable bundle clipped mid-span): F_m2 −= c |ż2| ż2."""

    name = "foreign_mass2_drag"
    parameters = (Parameter("c_drag2", "N*s^2/m^2", 0.0, 0.0, 100.0, "drag coefficient at mass 2"),)

    @staticmethod
    def rates(t, x, p, bus, dx, so, po):
        v = bus[B_ZD + 1]
        bus[B_FM + 1] -= p[po] * abs(v) * v


class DriftingLaserGain(PhysicalEffect):
    """The laser's gain drifts during the test (warming head): z3_meas = z3 (1 + r t)."""

    name = "foreign_laser_gain_drift"
    parameters = (Parameter("r_gain", "1/s", 0.0, -1.0, 1.0, "relative gain drift rate"),)

    @staticmethod
    def output(t, x, p, bus, y, so, po, yo):
        y[Y_Z3_MEAS] += p[po] * t * bus[B_Z + 2]


class PolarisedDrive(PhysicalEffect):
    """Polarisation-dependent authority: the patches act (1 + a) times harder for positive than negative drive:
    v_a → v_a (1 + a·[v_a > 0]) (a smooth step of width 5 V)."""

    name = "foreign_polarised_drive"
    parameters = (Parameter("a_pol", "1", 0.0, -0.9, 2.0, "extra authority for positive drive"),)

    @staticmethod
    def pre(t, x, p, bus, dx, so, po):
        v = bus[B_VA]
        bus[B_VA] = v * (1.0 + p[po] * 0.5 * (1.0 + math.tanh(v / 5.0)))


class LaserLowPass(PhysicalEffect):
    """The laser controller low-passes its reading (first-order, time constant τ): dw/dt = (z3 − w)/τ, z3_meas = w."""

    name = "foreign_laser_low_pass"
    parameters = (Parameter("tau_laser", "s", 0.0, 0.0, 0.05, "time constant of the laser's output filter"),)
    states = (StateSpec("w_laser", "m", 1e-4),)

    @staticmethod
    def rates(t, x, p, bus, dx, so, po):
        if p[po] > 0.0:
            dx[so] += (bus[B_Z + 2] - x[so]) / p[po]

    @staticmethod
    def output(t, x, p, bus, y, so, po, yo):
        if p[po] > 0.0:
            y[Y_Z3_MEAS] += x[so] - bus[B_Z + 2]


#: class name -> (strengths as truth values, words the description must contain (all, case-insensitive))
FOREIGN: dict[str, tuple[tuple[dict[str, float], ...], tuple[str, ...]]] = {
    "TipDryFriction": (({"F_coulomb": 2e-4}, {"F_coulomb": 1e-3}), ("mass 3", "friction")),
    "DriveTransportDelay": (({"T_delay": 2e-3}, {"T_delay": 6e-3}), ("delay", "drive")),
    "SaturatingLaser": (({"L_sat": 6e-3}, {"L_sat": 3e-3}), ("laser", "saturat")),
    "QuadraticLaser": (({"beta_laser": 5.0}, {"beta_laser": 30.0}), ("laser", "quadratic")),
    "RootClearance": (({"k_play": 60.0, "g_play": 2e-5}, {"k_play": 150.0, "g_play": 4e-5}), ("section 1",)),
    "TipStop": (({"k_stop": 5.0, "gap_stop": 2e-3}, {"k_stop": 20.0, "gap_stop": 1.5e-3}), ("mass 3", "one-sided")),
    "Mass2Drag": (({"c_drag2": 0.5}, {"c_drag2": 3.0}), ("mass 2", "square of its velocity")),
    "DriftingLaserGain": (({"r_gain": 2e-3}, {"r_gain": 1e-2}), ("laser", "drift")),
    "PolarisedDrive": (({"a_pol": 0.05}, {"a_pol": 0.2}), ("drive", "sign")),
    "LaserLowPass": (({"tau_laser": 5e-4}, {"tau_laser": 2e-3}), ("laser", "lag")),
}
