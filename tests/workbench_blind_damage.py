"""Blind test damage for the workbench: twelve damage effects written by an outside engineer.

This set was written *blind*: without reading the workbench's discovery dictionary (``workbench/discover/``), its
documentation (``docs/workbench.md``), or the project's other hidden/foreign/unseen damage files. What was read: the
effect seam and its parameter declarations (:mod:`plant.effect`), the layout (:mod:`plant.layout`), the core laminate
and piezo coupling, a few library effects for the form of a hook, the synthetic test kinds and the size measure of
``workbench.challenges.discovery.case_record``. The forms and their parameterisations are therefore this author's
own, written the way damage is usually modelled in a lumped cantilever model — so they check whether the workbench
recognises damage it was not shown, not whether it recognises its own terms.

Conventions (the core's): section ``i`` carries ``S_i = -k_i δ_i - c_i δ̇_i + θ_i q_hi / C_ep + …`` with
``θ_i = k_i d_ep``; a loss ``r`` of section stiffness adds ``+r k_i δ_i`` to ``S_i``; ``t`` is the record's time
(s from its first sample). Every effect is a plain :class:`plant.effect.PhysicalEffect` whose parameters at their
``neutral`` value leave the nominal model unchanged.

Cracks that open on one side (breathing cracks: a fatigue crack carries compression across closed faces and
opens under tension, so the section is softer for one sign of its bending only):

``crack_s3_pos_sharp``
    section 3 loses ``loss`` of k3 while δ3 > 0, bilinear (sharp closure) — the textbook breathing crack;
``crack_s2_neg_logistic``
    section 2 loses ``loss`` of k2 while δ2 < 0, closing smoothly (logistic gate of width ``w_close``): rough crack
    faces make contact gradually, not at a point;
``crack_s1_tip_switch``
    a root crack (section 1) whose faces part while the *tip* is below zero (z3 < 0, cubic-smoothstep edge of
    half-width ``z_w``): the root's surface strain follows the tip's overall swing, not only δ1, when the
    higher modes are weak;
``crack_s3_growing_opening``
    section 3 for δ3 < 0, lost stiffness growing with the opening (linear in ``|δ3|`` up to ``delta_sat``, then
    constant): the force error is piecewise quadratic — a crack whose contact area shrinks as it opens.

Stiffness lost mid-record (an event during the test: a ply cracks through, an impact, crack growth):

``step_s1``
    section 1 loses ``loss`` of k1 at ``t_on`` (sudden through-crack at the clamp edge);
``ramp_s3``
    section 3 loses ``loss`` of k3 over ``tau`` ≈ 1 s centred on ``t_mid`` (raised-cosine): a crack running across
    the width under load;
``two_stage_s2``
    section 2 loses ``loss_a`` at ``t_a`` and another ``loss_b`` at ``t_b`` (crack arrest then regrowth);
``delam_s1``
    root delamination at ``t_on``: section 1 loses ``loss`` of k1 and gains damping ``dc`` (friction/rubbing
    between the separated plies) at the same instant.

Weak polarity of the patches (partial depolarisation of the MFC fibres, or a debonded electrode finger, leaves the
actuation authority lower for one sign of field):

``weak_positive_drive``
    all three patches lose ``w`` of their coupling θ_i while the patch voltage is positive (sharp switch on the
    sign of the terminal voltage), reciprocally (force and back-coupling current);
``patch2_weak_negative``
    only section 2's patch loses ``w`` of its coupling for negative drive, switching smoothly (tanh of
    ``v / v_w``);
``patch1_weak_on_strain``
    section 1's patch loses ``w`` of its coupling while its own section bends positive (δ1 > 0, logistic edge of
    width ``w_edge``): a partly debonded patch whose bond line lifts only when the substrate strain pulls it off.

Joint damage:

``freeplay_s2``
    free play in section 2's joint: no elastic stiffness inside ±``gap`` of δ2, full k2 outside, with sharp
    corners (a worn pin or a loosened bolt in a built-up laminate joint).

:data:`BLIND` maps each label to (class, truth values, word groups, timing): truth values are the effect's
parameter values, a time parameter given as a fraction of the record under ``<name>_frac``
(:func:`truth_values` turns them into instants); word groups are what the first sentence of a correct verdict must
contain (every group met by any one of its words, case-insensitive); timing is (time parameter, tolerance s) or
None.
"""

from __future__ import annotations

import math

from plant.effect import Parameter, PhysicalEffect
from plant.layout import B_QH, B_S, P_K, X_DDELTA, X_Q

# --- cracks that open on one side ---------------------------------------------------------------------------------


class CrackS3PositiveSharp(PhysicalEffect):
    """Breathing crack in section 3: k3 (1 - loss) while δ3 > 0, k3 while δ3 ≤ 0 (bilinear)."""

    name = "blind_crack_s3_pos_sharp"
    description = "Section 3 crack open for δ3 > 0 (bilinear, sharp closure)"
    origin = "Fatigue crack at the tip section whose faces close under compression"
    parameters = (
        Parameter("loss", "1", 0.0, 0.0, 0.9, "Fraction of k3 lost while the crack is open", neutral=0.0),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        d = x[X.delta3]
        if d > 0.0:
            bus[B.s3] += p[P.loss] * p[P.k3] * d


class CrackS2NegativeLogistic(PhysicalEffect):
    """Breathing crack in section 2 open for δ2 < 0, closing through a logistic gate 1/(1 + exp(δ2/w))."""

    name = "blind_crack_s2_neg_logistic"
    description = "Section 2 crack open for δ2 < 0, logistic closure of width w_close"
    origin = "Rough-faced fatigue crack: the faces come into contact gradually"
    parameters = (
        Parameter("loss", "1", 0.0, 0.0, 0.9, "Fraction of k2 lost while the crack is fully open", neutral=0.0),
        Parameter("w_close", "m", 1.0e-4, 1.0e-6, 1.0e-2, "Width of the closure (logistic scale in δ2)"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        d = x[X.delta2]
        arg = d / p[P.w_close]
        if arg > 50.0:
            arg = 50.0
        elif arg < -50.0:
            arg = -50.0
        gate = 1.0 / (1.0 + math.exp(arg))
        bus[B.s2] += p[P.loss] * p[P.k2] * d * gate


class CrackS1TipSwitch(PhysicalEffect):
    """Root crack (section 1) open while the tip is below zero: k1 (1 - loss·g(z3)), g a cubic smoothstep that is
    1 for z3 ≤ -z_w and 0 for z3 ≥ z_w."""

    name = "blind_crack_s1_tip_switch"
    description = "Section 1 crack opened by the tip's motion (z3 < 0), cubic-smoothstep edge"
    origin = "Crack at the clamp edge; the root surface strain follows the tip's swing"
    parameters = (
        Parameter("loss", "1", 0.0, 0.0, 0.9, "Fraction of k1 lost while the tip is down", neutral=0.0),
        Parameter("z_w", "m", 2.0e-4, 1.0e-6, 1.0e-2, "Half-width of the opening edge in z3"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        s = 0.5 * (1.0 - bus[B.z3] / p[P.z_w])
        if s < 0.0:
            s = 0.0
        elif s > 1.0:
            s = 1.0
        gate = s * s * (3.0 - 2.0 * s)
        bus[B.s1] += p[P.loss] * p[P.k1] * x[X.delta1] * gate


class CrackS3GrowingOpening(PhysicalEffect):
    """Section 3 crack open for δ3 < 0 whose lost stiffness grows with the opening: loss·min(|δ3|/δ_sat, 1)·k3.

    The added force is ``loss k3 δ3 |δ3| / δ_sat`` up to δ_sat (quadratic), ``loss k3 δ3`` beyond (linear)."""

    name = "blind_crack_s3_growing_opening"
    description = "Section 3 crack open for δ3 < 0, lost stiffness growing with the opening (piecewise quadratic)"
    origin = "Crack whose contact zone shrinks progressively as the faces part"
    parameters = (
        Parameter("loss_max", "1", 0.0, 0.0, 0.9, "Fraction of k3 lost at and beyond delta_sat", neutral=0.0),
        Parameter("delta_sat", "m", 2.0e-3, 1.0e-6, 0.05, "Opening at which the loss saturates"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        d = x[X.delta3]
        if d < 0.0:
            frac = -d / p[P.delta_sat]
            if frac > 1.0:
                frac = 1.0
            bus[B.s3] += p[P.loss_max] * frac * p[P.k3] * d


# --- stiffness lost mid-record ------------------------------------------------------------------------------------


class StepS1(PhysicalEffect):
    """Section 1 loses ``loss`` of k1 at ``t_on`` (a step)."""

    name = "blind_step_s1"
    description = "Section 1 stiffness lost at t_on (step)"
    origin = "A ply at the clamp edge cracks through during the test"
    parameters = (
        Parameter("loss", "1", 0.0, 0.0, 0.9, "Fraction of k1 lost after t_on", neutral=0.0),
        Parameter("t_on", "s", 5.0, 0.0, 1.0e4, "Instant of the loss"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        if t >= p[P.t_on]:
            bus[B.s1] += p[P.loss] * p[P.k1] * x[X.delta1]


class RampS3(PhysicalEffect):
    """Section 3 loses ``loss`` of k3 along a raised cosine of length ``tau`` centred on ``t_mid``."""

    name = "blind_ramp_s3"
    description = "Section 3 stiffness lost smoothly over tau around t_mid"
    origin = "A crack running across the tip section's width under load"
    parameters = (
        Parameter("loss", "1", 0.0, 0.0, 0.9, "Fraction of k3 lost at the end of the transition", neutral=0.0),
        Parameter("t_mid", "s", 5.0, 0.0, 1.0e4, "Middle of the transition"),
        Parameter("tau", "s", 1.0, 1.0e-3, 100.0, "Length of the transition"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        s = (t - p[P.t_mid]) / p[P.tau] + 0.5
        if s <= 0.0:
            return
        g = 1.0 if s >= 1.0 else 0.5 - 0.5 * math.cos(math.pi * s)
        bus[B.s3] += p[P.loss] * g * p[P.k3] * x[X.delta3]


class TwoStageS2(PhysicalEffect):
    """Section 2 loses ``loss_a`` of k2 at ``t_a`` and a further ``loss_b`` at ``t_b``."""

    name = "blind_two_stage_s2"
    description = "Section 2 stiffness lost in two steps (t_a, t_b)"
    origin = "Crack growth in stages: initiation, arrest at a ply interface, regrowth"
    parameters = (
        Parameter("loss_a", "1", 0.0, 0.0, 0.9, "Fraction of k2 lost at t_a", neutral=0.0),
        Parameter("t_a", "s", 3.0, 0.0, 1.0e4, "Instant of the first stage"),
        Parameter("loss_b", "1", 0.0, 0.0, 0.9, "Further fraction of k2 lost at t_b", neutral=0.0),
        Parameter("t_b", "s", 7.0, 0.0, 1.0e4, "Instant of the second stage"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        lost = 0.0
        if t >= p[P.t_a]:
            lost += p[P.loss_a]
        if t >= p[P.t_b]:
            lost += p[P.loss_b]
        bus[B.s2] += lost * p[P.k2] * x[X.delta2]


class DelaminationS1(PhysicalEffect):
    """At ``t_on`` section 1 loses ``loss`` of k1 and gains the viscous damping ``dc``."""

    name = "blind_delam_s1"
    description = "Root delamination at t_on: k1 lost and c1 gained at the same instant"
    origin = "Clamp-edge delamination: the separated plies bend apart (softer) and rub (dissipation)"
    parameters = (
        Parameter("loss", "1", 0.0, 0.0, 0.9, "Fraction of k1 lost after t_on", neutral=0.0),
        Parameter("dc", "N*s/m", 0.0, 0.0, 1.0, "Damping added to section 1 after t_on", neutral=0.0),
        Parameter("t_on", "s", 5.0, 0.0, 1.0e4, "Instant of the delamination"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        if t >= p[P.t_on]:
            bus[B.s1] += p[P.loss] * p[P.k1] * x[X.delta1] - p[P.dc] * x[X.ddelta1]


# --- weak polarity of the patches ---------------------------------------------------------------------------------


class WeakPositiveDrive(PhysicalEffect):
    """Every patch loses ``w`` of its coupling θ_i while the patch voltage is positive (force and current)."""

    name = "blind_weak_positive_drive"
    description = "All patches weaker by w for positive drive (sharp switch on the terminal voltage's sign)"
    origin = "Partial depolarisation of the MFC fibres: positive field drives them less"
    parameters = (
        Parameter("w", "1", 0.0, 0.0, 0.9, "Fraction of θ_i lost for positive drive", neutral=0.0),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        if bus[B.va] > 0.0:
            for i in range(3):
                dtheta = -p[P.w] * p[P_K + i] * p[P.d_ep]
                bus[B_S + i] += dtheta * bus[B_QH + i] / p[P.C_ep]
                dx[X_Q + i] -= dtheta * x[X_DDELTA + i]


class Patch2WeakNegative(PhysicalEffect):
    """Section 2's patch loses ``w`` of θ_2 for negative drive: factor 1 - w (1 - tanh(v/v_w))/2."""

    name = "blind_patch2_weak_negative"
    description = "Section 2's patch weaker by w for negative drive (tanh switch of width v_w)"
    origin = "A damaged electrode finger on the middle patch conducts only one polarity well"
    parameters = (
        Parameter("w", "1", 0.0, 0.0, 0.9, "Fraction of θ_2 lost for negative drive", neutral=0.0),
        Parameter("v_w", "V", 30.0, 0.1, 1000.0, "Voltage scale of the switch"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        g = 0.5 * (1.0 - math.tanh(bus[B.va] / p[P.v_w]))
        dtheta = -p[P.w] * g * p[P.k2] * p[P.d_ep]
        bus[B.s2] += dtheta * bus[B.qh2] / p[P.C_ep]
        dx[X.q2] -= dtheta * x[X.ddelta2]


class Patch1WeakOnStrain(PhysicalEffect):
    """Section 1's patch loses ``w`` of θ_1 while δ1 > 0 (logistic edge of width ``w_edge``)."""

    name = "blind_patch1_weak_on_strain"
    description = "Section 1's patch weaker by w while its section bends positive (δ1 > 0)"
    origin = "A partly debonded root patch whose bond line opens only under one sign of substrate strain"
    parameters = (
        Parameter("w", "1", 0.0, 0.0, 0.9, "Fraction of θ_1 lost while δ1 > 0", neutral=0.0),
        Parameter("w_edge", "m", 2.0e-5, 1.0e-7, 1.0e-3, "Width of the switch in δ1"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        arg = -x[X.delta1] / p[P.w_edge]
        if arg > 50.0:
            arg = 50.0
        elif arg < -50.0:
            arg = -50.0
        g = 1.0 / (1.0 + math.exp(arg))
        dtheta = -p[P.w] * g * p[P.k1] * p[P.d_ep]
        bus[B.s1] += dtheta * bus[B.qh1] / p[P.C_ep]
        dx[X.q1] -= dtheta * x[X.ddelta1]


# --- joint damage -------------------------------------------------------------------------------------------------


class FreePlayS2(PhysicalEffect):
    """Free play in section 2's joint: the spring force is -k2 (δ2 - clip(δ2, -gap, gap)) (sharp corners)."""

    name = "blind_freeplay_s2"
    description = "Free play ±gap in section 2's joint (no elastic stiffness inside the gap)"
    origin = "A worn pin or loosened bolt in a built-up joint of the laminate"
    parameters = (
        Parameter("gap", "m", 0.0, 0.0, 1.0e-2, "Half-width of the free play in δ2", neutral=0.0),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        d = x[X.delta2]
        g = p[P.gap]
        inside = d if -g <= d <= g else (g if d > g else -g)
        bus[B.s2] += p[P.k2] * inside


# --- the blind set ------------------------------------------------------------------------------------------------

CRACK: tuple[str, ...] = ("crack", "one-sided", "one side", "breathing", "bilinear", "only while", "only for",
                          "only when", "opens", "> 0", "< 0", "sign of")
STIFF: tuple[str, ...] = ("stiff", "softer", "k1", "k2", "k3")
DAMPING: tuple[str, ...] = ("damping", "dissipat", "c1")
GAP: tuple[str, ...] = ("free play", "clearance", "play", "dead zone", "gap", "loose")
PATCH: tuple[str, ...] = ("d_ep", "authority", "coupling", "piezo", "patch")
POLARITY: tuple[str, ...] = ("negative", "positive", "polarity", "'s sign", "sign of", "polaris")
S1: tuple[str, ...] = ("section 1", "k1")
S2: tuple[str, ...] = ("section 2", "k2")
S3: tuple[str, ...] = ("section 3", "k3")

Words = tuple[tuple[str, ...], ...]
Timing = tuple[str, float] | None

BLIND: dict[str, tuple[type[PhysicalEffect], dict[str, float], Words, Timing]] = {
    "crack_s3_pos_sharp": (CrackS3PositiveSharp, {"loss": 0.15}, (S3, CRACK), None),
    "crack_s2_neg_logistic": (CrackS2NegativeLogistic, {"loss": 0.3, "w_close": 1.0e-4}, (S2, CRACK), None),
    "crack_s1_tip_switch": (CrackS1TipSwitch, {"loss": 0.2, "z_w": 2.0e-4}, (S1, CRACK), None),
    "crack_s3_growing_opening": (CrackS3GrowingOpening, {"loss_max": 0.15, "delta_sat": 4.0e-3}, (S3, CRACK),
                                 None),
    "step_s1": (StepS1, {"loss": 0.15, "t_on_frac": 0.4}, (S1, STIFF), ("t_on", 0.2)),
    "ramp_s3": (RampS3, {"loss": 0.2, "t_mid_frac": 0.8, "tau": 1.0}, (S3, STIFF), ("t_mid", 0.5)),
    "two_stage_s2": (TwoStageS2, {"loss_a": 0.1, "t_a_frac": 0.3, "loss_b": 0.1, "t_b_frac": 0.8}, (S2, STIFF),
                     ("t_a", 0.3)),
    "delam_s1": (DelaminationS1, {"loss": 0.2, "dc": 0.06, "t_on_frac": 0.5}, ((*S1, "c1"), STIFF, DAMPING),
                 ("t_on", 0.2)),
    "weak_positive_drive": (WeakPositiveDrive, {"w": 0.2}, (PATCH, POLARITY), None),
    "patch2_weak_negative": (Patch2WeakNegative, {"w": 0.3, "v_w": 30.0},
                             (("section 2", "patch 2", "second patch", "middle patch", "theta2", "θ2"), PATCH,
                              POLARITY), None),
    "patch1_weak_on_strain": (Patch1WeakOnStrain, {"w": 0.35, "w_edge": 2.0e-5},
                              (("section 1", "patch 1", "first patch", "root patch", "theta1", "θ1", "δ1", "delta1"),
                               PATCH, (*POLARITY, "> 0", "< 0")), None),
    "freeplay_s2": (FreePlayS2, {"gap": 4.0e-5}, (S2, GAP), None),
}


def truth_values(label: str, duration_s: float) -> dict[str, float]:
    """The truth parameter values of ``label`` for a record of ``duration_s``: ``<name>_frac`` keys become
    ``<name> = frac × duration_s``."""
    from workbench_unseen_damage import values_at

    return values_at(BLIND[label][1], duration_s)


def run_blind(label: str, *, kind: str = "sweep", duration_s: float = 15.0, noise_m: float = 2e-6, seed: int = 1,
              workdir: str | None = None) -> dict[str, object]:
    """One blind case through the one-command walk (``workbench_unseen_damage.run_walk``: synth → ``diagnose`` with
    its discovery step → the first sentence scored → the fix refitted as ``shm fit --add`` does)."""
    from workbench_unseen_damage import run_walk

    cls, _, groups, timing = BLIND[label]
    return run_walk(label, cls, lambda d: truth_values(label, d), groups, timing, kind=kind, duration_s=duration_s,
                    noise_m=noise_m, seed=seed, workdir=workdir)
