"""Damage written outside the discovery dictionary, the way a rig engineer would write it (hard switches, no
smoothing, its own parameter names), as the truth of the damage-form checks of ``shm discover``
(``tests/workbench/test_discover_damage_forms.py``, issue 26 point 3): a stiffness event in section 2 at an instant
inside the
record, a breathing crack in section 2 (open for δ2 > 0), and a patch whose authority d_ep is lower for negative drive.
"""

from __future__ import annotations

from plant.effect import Parameter, PhysicalEffect
from plant.layout import B_QH, B_S, B_VA, P_C, P_C_EP, P_D_EP, P_K, X_DDELTA, X_DELTA, X_Q


class Section2StiffnessEvent(PhysicalEffect):
    """At t_event section 2 loses a share loss_k2 of its stiffness (a crack grows through it): for t ≥ t_event the
    section force gains + loss_k2 · k2 · δ2."""

    name = "truth_section2_event"
    parameters = (Parameter("loss_k2", "1", 0.0, 0.0, 0.9, "share of k2 lost at the event"),
                  Parameter("t_event", "s", 1.0, 0.0, 1e4, "instant of the event"))

    @staticmethod
    def rates(t, x, p, bus, dx, so, po):
        if t >= p[po + 1]:
            bus[B_S + 1] += p[po] * p[P_K + 1] * x[X_DELTA + 1]


class Section2BreathingCrack(PhysicalEffect):
    """A crack in section 2 that opens when the section bends positive: for δ2 > 0 the section carries only
    (1 − open_loss) k2 δ2."""

    name = "truth_section2_crack"
    parameters = (Parameter("open_loss", "1", 0.0, 0.0, 0.9, "share of k2 lost while the crack is open"),)

    @staticmethod
    def rates(t, x, p, bus, dx, so, po):
        d = x[X_DELTA + 1]
        if d > 0.0:
            bus[B_S + 1] += p[po] * p[P_K + 1] * d


class PatchWeakNegative(PhysicalEffect):
    """A partly depolarised patch: for negative drive its coupling d_ep is (1 − neg_loss) of nominal — the piezo force
    θ q_h / C_ep on every section and the back-coupling current θ δ̇ both scaled (θ = k_i d_ep)."""

    name = "truth_patch_polarity"
    parameters = (Parameter("neg_loss", "1", 0.0, 0.0, 0.9, "share of d_ep lost for negative drive"),)

    @staticmethod
    def rates(t, x, p, bus, dx, so, po):
        if bus[B_VA] < 0.0:
            for i in range(3):
                theta = p[P_K + i] * p[P_D_EP]
                bus[B_S + i] -= p[po] * theta * bus[B_QH + i] / p[P_C_EP]
                dx[X_Q + i] += p[po] * theta * x[X_DDELTA + i]


class Section2DampingEvent(PhysicalEffect):
    """At t_event section 2 starts to dissipate (1 + rise) times more (a loosened joint rubs): for t ≥ t_event the
    section force gains − rise · c2 · δ̇2."""

    name = "truth_section2_damping_event"
    parameters = (Parameter("rise", "1", 0.0, 0.0, 20.0, "relative damping added at the event"),
                  Parameter("t_event", "s", 1.0, 0.0, 1e4, "instant of the event"))

    @staticmethod
    def rates(t, x, p, bus, dx, so, po):
        if t >= p[po + 1]:
            bus[B_S + 1] -= p[po] * p[P_C + 1] * x[X_DDELTA + 1]


class Section3StiffnessEvent(PhysicalEffect):
    """At t_event section 3 loses a share loss_k3 of its stiffness: for t ≥ t_event the section force gains
    + loss_k3 · k3 · δ3."""

    name = "truth_section3_event"
    parameters = (Parameter("loss_k3", "1", 0.0, 0.0, 0.9, "share of k3 lost at the event"),
                  Parameter("t_event", "s", 1.0, 0.0, 1e4, "instant of the event"))

    @staticmethod
    def rates(t, x, p, bus, dx, so, po):
        if t >= p[po + 1]:
            bus[B_S + 2] += p[po] * p[P_K + 2] * x[X_DELTA + 2]
