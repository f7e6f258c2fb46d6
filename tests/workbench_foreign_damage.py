"""Damage written outside the project, for the harder not-in-the-library challenge (issue 26 point 5).

Each class is a ``PhysicalEffect`` written by hand, the way a structural engineer would write the damage — not
generated from, nor copied out of, the discovery dictionary (``workbench/discover/_dictionary.py``), and in forms the
dictionary does not name on purpose:

* a breathing crack: a section's spring is softer only while the crack is open (δ_i > 0), in section 2 and at the
  root (section 1);
* damage *events*: a section's stiffness drops by a fraction at an instant inside the record; a section's damping
  rises at an instant (a loosened bolt starting to rub);
* a patch that lost authority in one polarity: its piezo force is weaker while the drive is negative;
* free play in the root clamp with a smooth edge (the clamp's share of the root stiffness lost within ±g).

The section force convention is the core's (``plant/effects/laminate.py``): ``bus[B_S + i]`` carries
``-k_i δ_i - c_i δ̇_i + …``; an effect that softens adds ``+Δk δ``. ``DAMAGE`` maps each class to its challenge
strengths and the physics check of the diagnose verdict's first sentence (see
:class:`workbench.challenges.discovery.PhysicsCheck`). Time events carry their instant as a fraction of the record
(``t_event_frac``): the challenge sets ``t_event`` for each record.
"""

from __future__ import annotations

import math

from plant.effect import Parameter, PhysicalEffect
from plant.layout import B_QH, B_S, B_VA, P_C, P_C_EP, P_D_EP, P_K, X_DDELTA, X_DELTA


class BreathingCrackSection2(PhysicalEffect):
    """A crack in section 2 that opens for δ2 > 0: there the section's spring is k2 (1 − a), else k2."""

    name = "foreign_crack_s2"
    parameters = (Parameter("a_crack2", "1", 0.0, 0.0, 0.9, "stiffness lost while the crack is open"),)

    @staticmethod
    def rates(t, x, p, bus, dx, so, po):
        d = x[X_DELTA + 1]
        if d > 0.0:
            bus[B_S + 1] += p[po] * p[P_K + 1] * d


class BreathingCrackRoot(PhysicalEffect):
    """A crack at the root (section 1) that opens for δ1 < 0 (the other face): k1 (1 − a) there, else k1."""

    name = "foreign_crack_root"
    parameters = (Parameter("a_crack1", "1", 0.0, 0.0, 0.9, "stiffness lost while the crack is open"),)

    @staticmethod
    def rates(t, x, p, bus, dx, so, po):
        d = x[X_DELTA]
        if d < 0.0:
            bus[B_S] += p[po] * p[P_K] * d


class StiffnessDropEvent(PhysicalEffect):
    """Section 2 loses a fraction f of its stiffness at the instant t_event (a crack runs): k2 → k2 (1 − f)."""

    name = "foreign_k2_drop"
    parameters = (Parameter("f_drop", "1", 0.0, 0.0, 0.9, "stiffness lost at the event"),
                  Parameter("t_event", "s", 1.0, 0.0, 1e3, "instant of the event"))

    @staticmethod
    def rates(t, x, p, bus, dx, so, po):
        if t >= p[po + 1]:
            bus[B_S + 1] += p[po] * p[P_K + 1] * x[X_DELTA + 1]


class DampingRiseEvent(PhysicalEffect):
    """From the instant t_event the root section dissipates (1 + r) times more: c1 → c1 (1 + r) (a bolt starts to
    rub)."""

    name = "foreign_c1_rise"
    parameters = (Parameter("r_damp", "1", 0.0, 0.0, 20.0, "relative damping added at the event"),
                  Parameter("t_event", "s", 1.0, 0.0, 1e3, "instant of the event"))

    @staticmethod
    def rates(t, x, p, bus, dx, so, po):
        if t >= p[po + 1]:
            bus[B_S] -= p[po] * p[P_C] * x[X_DDELTA]


class NegativePolarityPatch(PhysicalEffect):
    """Depoled patches: while the drive is negative the piezo force of every section is (1 − b) of what d_ep gives
    (the coefficient d_ep is lower in that polarity; the charge side is left as it was)."""

    name = "foreign_negative_polarity"
    parameters = (Parameter("b_neg", "1", 0.0, 0.0, 0.9, "share of d_ep lost for negative drive"),)

    @staticmethod
    def rates(t, x, p, bus, dx, so, po):
        if bus[B_VA] < 0.0:
            for i in range(3):
                bus[B_S + i] -= p[po] * p[P_K + i] * p[P_D_EP] * bus[B_QH + i] / p[P_C_EP]


class RootFreePlay(PhysicalEffect):
    """Play of ±g in the root clamp: within it the root carries only (1 − f) k1, with a smooth edge —
    force −k1 δ1 + f k1 g tanh(δ1 / g)."""

    name = "foreign_root_free_play"
    parameters = (Parameter("f_play", "1", 0.0, 0.0, 1.0, "share of the root stiffness lost within the play"),
                  Parameter("g_root", "m", 1e-5, 1e-8, 1e-2, "half-width of the play"))

    @staticmethod
    def rates(t, x, p, bus, dx, so, po):
        g = p[po + 1]
        bus[B_S] += p[po] * p[P_K] * g * math.tanh(x[X_DELTA] / g)


#: the words a verdict may use for a time event's instant (checked with the number, see PhysicsCheck.t_event)
_EVENT = ("at t", "t =", "t0", "instant", "event", "from t", "after t")
_CRACK = ("crack", "one-sided", "one side", "breathing", "bilinear", "only while", "only for", "only when", "opens")

#: class name -> (strengths as truth values, groups of words the first sentence must contain: every group, any word
#: of a group, case-insensitive; "t_event" in a strength is a fraction of the record: the instant is checked)
DAMAGE: dict[str, tuple[tuple[dict[str, float], ...], tuple[tuple[str, ...], ...]]] = {
    "BreathingCrackSection2": (({"a_crack2": 0.2}, {"a_crack2": 0.3}), (("section 2", "k2"), _CRACK)),
    "BreathingCrackRoot": (({"a_crack1": 0.2}, {"a_crack1": 0.3}), (("section 1", "k1", "root"), _CRACK)),
    "StiffnessDropEvent": (({"f_drop": 0.15, "t_event_frac": 0.55}, {"f_drop": 0.3, "t_event_frac": 0.45}),
                           (("section 2", "k2"), ("stiff", "k2", "softer"), _EVENT)),
    "DampingRiseEvent": (({"r_damp": 1.0, "t_event_frac": 0.5}, {"r_damp": 3.0, "t_event_frac": 0.6}),
                         (("section 1", "c1", "root"), ("damping", "c1", "dissipat"), _EVENT)),
    "NegativePolarityPatch": (({"b_neg": 0.15}, {"b_neg": 0.3}),
                              (("d_ep", "drive", "patch", "authority", "piezo"),
                               ("negative", "polarity", "'s sign", "sign of", "polaris", "one-sided"))),
    "RootFreePlay": (({"f_play": 0.3, "g_root": 3e-5}, {"f_play": 0.6, "g_root": 5e-5}),
                     (("section 1", "k1", "root"), ("free play", "clearance", "play", "dead zone", "gap", "loose"))),
}
