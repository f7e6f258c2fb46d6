"""A sixth blind set of damage effects: twelve *ordinary* damages of the beam, the kinds an outside SHM engineer
checks a monitor on first, written from the plant's effect seam and the seed paper alone, by someone who has not seen
how the workbench discovers damage (nor the earlier sets' discovery runs); sets 1–5 and the unseen set were read only
for the API and to avoid repeating their exact forms.

Three families of four, varied in section, sign, size, edge and timing across the set:

* cracks that open on one side: a root crack open while the root bends up (δ1 > 0, sharp), a tip crack open while
  the tip section bends down with a tanh edge of a few µm, an intermediate crack open for δ2 > 0 whose faces also
  rub while open (the lost stiffness comes with a damping of time constant tau_rub), a root crack open for δ1 < 0
  written as the bilinear spring force it is (k1·δ1 shut, (1 − loss)·k1·δ1 open) rather than a gated change;
* stiffness lost inside the record: the tip section cracking through at one instant (sharp), the root losing
  stiffness along a straight ramp of half a second that then holds, an impact cracking the intermediate and the tip
  sections at the same instant, a part of the tip section's mass breaking off at an instant (m3 lower; the only
  damage of the set that changes an inertia, applied in the ``post`` hook where the chain's accelerations are
  known). Instants are fractions of the record (``*_frac`` values, scaled by :func:`truth_values` as set 5 does);
  the ramp's length is in seconds;
* patches weak in one polarity: the tip couple weak while its own voltage is negative (sharp), the root couple weak
  while the amplifier's drive v_a is positive (smooth), all three couples weak for their own negative voltage by
  different fractions (root most, tip least), the intermediate couple whose loss for negative voltage grows and
  saturates (tanh of −v_c2/v_ref).

Section forces follow ``plant/effects/laminate.py``: ``bus[B.s_i]`` carries −k_i δ_i − c_i δ̇_i + θ_i q_hi/C_ep, so a
section that softens by Δk *adds* +Δk δ_i and extra damping adds −Δc δ̇_i. The mass chain's ``post`` gives mass j
the absolute acceleration (S_j − S_{j+1} + F_mj)/m_j; a mass lower by a share f takes 1/(1 − f) of it, so the effect
adds f/(1 − f) of that force per m_j to the rate of δ̇_j (relative to mass j − 1). The piezo force of couple i is
θ_i q_hi / C_ep with θ_i = k_i d_ep (``plant/effects/piezo_coupling.py``), its back-coupling current −θ_i δ̇_i: a
couple that couples less by a fraction w takes back w of both (and of their power in ``bus[B.p_piezo]``). A patch's
own voltage is v_ci = q_i/C_ep (``plant/effects/patch_rc.py``); v_a is the amplifier's drive at its terminals.

Every damage has one size parameter with ``neutral=0.0`` (healthy at 0). :data:`BLIND6` maps each label to (class,
truth values, word groups the verdict's first sentence must match, timing); :func:`run_blind6` runs one through the
one-command walk of ``workbench_unseen_damage.run_walk``. The sizes quoted on each case are ``size_sigma`` of
``workbench.challenges.discovery.case_record`` at the truth values, 2 µm noise, seed 1, on the 15 s sweep, MBIT.a and
MBIT.b (measured 2026-11-29 while writing the set).
"""

from __future__ import annotations

import math

from workbench_blind_damage_3 import CRACK, PATCH, POLARITY, STIFF, Timing, Words, patch_at, section

from plant.effect import Parameter, PhysicalEffect
from plant.layout import B_QH, B_S, B_VC, P_K, X_DDELTA, X_Q

# --- cracks that open on one side -------------------------------------------------------------------------------------


class RootCrackOpensUp(PhysicalEffect):
    """A transverse crack at the root (section 1) on the face put in tension when the root bends up: for δ1 > 0 the
    section carries (1 − crack_loss)·k1, for δ1 ≤ 0 the faces bear and it carries k1 (sharp switch at δ1 = 0)."""

    name = "blind6_root_crack_opens_up"
    description = "Section 1 softer by crack_loss·k1 while δ1 > 0 (breathing crack, sharp closure)"
    origin = "Fatigue crack at the clamp edge, where the bending moment is largest; it breathes with the root's bending"
    parameters = (
        Parameter("crack_loss", "1", 0.0, 0.0, 0.9, "Fraction of k1 lost while δ1 > 0", neutral=0.0),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        opening = max(x[X.delta1], 0.0)
        bus[B.s1] += p[P.crack_loss] * p[P.k1] * opening


class TipCrackOpensDownSmooth(PhysicalEffect):
    """A crack in the tip section (3) open while the section bends down: the lost share of k3 is
    crack_loss·½(1 − tanh(δ3/edge)), with an edge of a few µm (the faces' roughness) — nearly bilinear, but smooth."""

    name = "blind6_tip_crack_opens_down"
    description = "Section 3 softer by crack_loss·k3 while δ3 < 0 (tanh edge over a few µm of δ3)"
    origin = "Crack in the outer third of the laminate with rough faces that meet over a few micrometres of closing"
    parameters = (
        Parameter("crack_loss", "1", 0.0, 0.0, 0.9, "Fraction of k3 lost with the crack open (δ3 < 0)", neutral=0.0),
        Parameter("edge", "m", 5.0e-6, 1.0e-8, 1.0e-3, "Deflection δ3 over which the faces meet"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        d = x[X.delta3]
        share = 0.5 - 0.5 * math.tanh(d / p[P.edge])
        bus[B.s3] += share * p[P.crack_loss] * p[P.k3] * d


class MidCrackRubsOpenUp(PhysicalEffect):
    """A crack in the intermediate section (2) open for δ2 > 0 (sharp) whose faces rub while open: the open crack
    takes crack_loss·k2 out of the spring and dissipates through a damping of the same lost stiffness times a rubbing
    time constant, crack_loss·k2·tau_rub (none while shut)."""

    name = "blind6_mid_crack_rubs_open_up"
    description = ("Section 2 softer by crack_loss·k2 and damping higher by crack_loss·k2·tau_rub while δ2 > 0 "
                   "(open crack that rubs)")
    origin = "Mode-I crack with a shear component: its faces slide on each other while it is open"
    parameters = (
        Parameter("crack_loss", "1", 0.0, 0.0, 0.9, "Fraction of k2 lost while δ2 > 0", neutral=0.0),
        Parameter("tau_rub", "s", 5.0e-4, 0.0, 0.1, "Damping of the open crack per unit of lost stiffness"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        if x[X.delta2] > 0.0:
            dk = p[P.crack_loss] * p[P.k2]
            bus[B.s2] += dk * (x[X.delta2] - p[P.tau_rub] * x[X.ddelta2])


class RootBilinearSpringDown(PhysicalEffect):
    """The root section (1) as a bilinear spring: its elastic force is k1·δ1 for δ1 ≥ 0 and (1 − crack_loss)·k1·δ1
    for δ1 < 0 (a crack on the upper face, open when the root bends down). The core already carries −k1·δ1; the
    effect replaces it by the bilinear force."""

    name = "blind6_root_bilinear_spring_down"
    description = "Section 1 spring force k1·δ1 for δ1 ≥ 0, (1 − crack_loss)·k1·δ1 for δ1 < 0 (bilinear)"
    origin = "Crack on the upper face of the root laminate, opened by downward bending and shut by upward bending"
    parameters = (
        Parameter("crack_loss", "1", 0.0, 0.0, 0.9, "Share of k1 the spring lacks for δ1 < 0", neutral=0.0),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        k = p[P.k1]
        d = x[X.delta1]
        spring = k * d if d >= 0.0 else (1.0 - p[P.crack_loss]) * k * d
        bus[B.s1] += k * d - spring


# --- stiffness lost inside the record ---------------------------------------------------------------------------------


class TipCracksThrough(PhysicalEffect):
    """The tip section (3) cracks through at t_crack: from then on it carries (1 − k_loss)·k3 (sharp step)."""

    name = "blind6_tip_cracks_through"
    description = "Section 3 stiffness lower by k_loss·k3 from t_crack on (step)"
    origin = "A ply of the outer third snaps under an overload during the test"
    parameters = (
        Parameter("k_loss", "1", 0.0, 0.0, 0.9, "Fraction of k3 lost after t_crack", neutral=0.0),
        Parameter("t_crack", "s", 10.0, 0.0, 1.0e4, "Instant of the crack"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        lost = p[P.k_loss] if t >= p[P.t_crack] else 0.0
        bus[B.s3] += lost * p[P.k3] * x[X.delta3]


class RootRampHalfSecond(PhysicalEffect):
    """The root section (1) loses stiffness along a straight ramp from t_begin to t_begin + ramp_s (half a second):
    loss(t) = k_loss·clip((t − t_begin)/ramp_s, 0, 1), held at k_loss after."""

    name = "blind6_root_ramp_half_second"
    description = "Section 1 stiffness lower by k_loss·k1, along a linear ramp of ramp_s from t_begin, then held"
    origin = "A delamination running across the root under load and arresting at the clamp plate's edge"
    parameters = (
        Parameter("k_loss", "1", 0.0, 0.0, 0.9, "Fraction of k1 lost at the end of the ramp", neutral=0.0),
        Parameter("t_begin", "s", 4.0, 0.0, 1.0e4, "Instant the loss starts"),
        Parameter("ramp_s", "s", 0.5, 1.0e-3, 1.0e3, "Duration of the ramp"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        s = (t - p[P.t_begin]) / p[P.ramp_s]
        s = 0.0 if s < 0.0 else (1.0 if s > 1.0 else s)
        bus[B.s1] += s * p[P.k_loss] * p[P.k1] * x[X.delta1]


class MidTipImpact(PhysicalEffect):
    """An impact on the outer half of the beam at t_hit cracks the intermediate (2) and the tip (3) sections at
    once: both lose k_loss of their stiffness at that instant (one step in two sections)."""

    name = "blind6_mid_tip_impact"
    description = "Sections 2 and 3 stiffness lower by k_loss·k2 and k_loss·k3 from t_hit on (impact)"
    origin = "A hail stone or a dropped tool hits the beam between the intermediate and the tip patches"
    parameters = (
        Parameter("k_loss", "1", 0.0, 0.0, 0.9, "Fraction of k2 and of k3 lost after t_hit", neutral=0.0),
        Parameter("t_hit", "s", 7.5, 0.0, 1.0e4, "Instant of the impact"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        if t >= p[P.t_hit]:
            a = p[P.k_loss]
            bus[B.s2] += a * p[P.k2] * x[X.delta2]
            bus[B.s3] += a * p[P.k3] * x[X.delta3]


class TipMassBreaksOff(PhysicalEffect):
    """A part of the tip section (a corner of the laminate, or the reflector glued on it for the laser) breaks off
    at t_off: the tip mass is (1 − mass_loss)·m3 from then on. Mass 3's absolute acceleration becomes
    F3/((1 − f) m3) instead of F3/m3, F3 = S3 + F_m3 the force on it: the effect adds f/(1 − f)·F3/m3 to δ̈3 in the
    ``post`` hook, once every force is on the bus."""

    name = "blind6_tip_mass_breaks_off"
    description = "Tip mass m3 lower by mass_loss·m3 from t_off on (a part falls off)"
    origin = "A chipped tip corner or a reflector target coming unglued during the test"
    parameters = (
        Parameter("mass_loss", "1", 0.0, 0.0, 0.9, "Fraction of m3 lost after t_off", neutral=0.0),
        Parameter("t_off", "s", 5.0, 0.0, 1.0e4, "Instant the part falls off"),
    )

    @staticmethod
    def post(t, x, p, bus, dx, X, P, B):
        if t >= p[P.t_off]:
            f = p[P.mass_loss]
            dx[X.ddelta3] += f / (1.0 - f) * (bus[B.s3] + bus[B.fm3]) / p[P.m3]


# --- patches weak in one polarity -------------------------------------------------------------------------------------


class Patch3WeakNegativeVoltage(PhysicalEffect):
    """The tip couple (3) couples less by weak_loss while its own voltage is negative (v_c3 < 0, sharp): force and
    back-coupling current both lower; healthy for v_c3 ≥ 0."""

    name = "blind6_patch3_weak_negative_v"
    description = "Couple 3 couples less by weak_loss while v_c3 < 0 (sharp switch on the patch's own voltage)"
    origin = "Tip MFCs partly depoled by reverse fields: their remaining polarisation responds weakly to negative field"
    parameters = (
        Parameter("weak_loss", "1", 0.0, 0.0, 0.9, "Fraction of couple 3's coupling lost for v_c3 < 0", neutral=0.0),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        if bus[B.vc3] < 0.0:
            lost_theta = p[P.weak_loss] * p[P.k3] * p[P.d_ep]
            f = lost_theta * bus[B.qh3] / p[P.C_ep]
            bus[B.s3] -= f
            bus[B.p_piezo] -= f * x[X.ddelta3]
            dx[X.q3] += lost_theta * x[X.ddelta3]


class Patch1WeakPositiveDrive(PhysicalEffect):
    """The root couple (1) couples less while the amplifier's drive v_a is positive: lost share
    weak_loss·½(1 + tanh(v_a/v_edge)) — smooth over v_edge, healthy for negative drive."""

    name = "blind6_patch1_weak_positive_drive"
    description = "Couple 1 couples less by weak_loss while v_a > 0 (tanh edge over v_edge of the drive)"
    origin = "Root MFC with a cracked electrode finger that lifts off under the field of one polarity of the drive"
    parameters = (
        Parameter("weak_loss", "1", 0.0, 0.0, 0.9, "Fraction of couple 1's coupling lost for v_a > 0", neutral=0.0),
        Parameter("v_edge", "V", 25.0, 1.0e-3, 1.0e3, "Drive over which the weakness switches"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        w = p[P.weak_loss] * 0.5 * (1.0 + math.tanh(bus[B.va] / p[P.v_edge]))
        lost_theta = w * p[P.k1] * p[P.d_ep]
        f = lost_theta * bus[B.qh1] / p[P.C_ep]
        bus[B.s1] -= f
        bus[B.p_piezo] -= f * x[X.ddelta1]
        dx[X.q1] += lost_theta * x[X.ddelta1]


class AllPatchesWeakNegative(PhysicalEffect):
    """All three couples couple less while their own voltage is negative (tanh edge over v_edge), by different
    fractions: weak_loss for the root couple, ratio2·weak_loss for the intermediate one, ratio3·weak_loss for the
    tip one (the patches aged unequally under the same reverse fields)."""

    name = "blind6_all_patches_weak_negative"
    description = ("Couples 1, 2, 3 couple less by weak_loss, ratio2·weak_loss, ratio3·weak_loss while their own "
                   "voltage v_ci < 0 (smooth over v_edge)")
    origin = "Partial depolarisation of every MFC by reverse fields, largest at the root where the strain is highest"
    parameters = (
        Parameter("weak_loss", "1", 0.0, 0.0, 0.9, "Fraction of couple 1's coupling lost for v_c1 < 0", neutral=0.0),
        Parameter("ratio2", "1", 0.75, 0.0, 1.0, "Couple 2's loss as a share of couple 1's"),
        Parameter("ratio3", "1", 0.5, 0.0, 1.0, "Couple 3's loss as a share of couple 1's"),
        Parameter("v_edge", "V", 10.0, 1.0e-3, 1.0e3, "Voltage over which each weakness switches"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        for i in range(3):
            share = 1.0 if i == 0 else (p[P.ratio2] if i == 1 else p[P.ratio3])
            w = share * p[P.weak_loss] * 0.5 * (1.0 - math.tanh(bus[B_VC + i] / p[P.v_edge]))
            lost_theta = w * p[P_K + i] * p[P.d_ep]
            f = lost_theta * bus[B_QH + i] / p[P.C_ep]
            bus[B_S + i] -= f
            bus[B.p_piezo] -= f * x[X_DDELTA + i]
            dx[X_Q + i] += lost_theta * x[X_DDELTA + i]


class Patch2NegativeLossSaturates(PhysicalEffect):
    """The intermediate couple (2) loses coupling for negative voltage, more the stronger the field but saturating:
    w = weak_loss·tanh(max(0, −v_c2)/v_ref) — none for v_c2 ≥ 0, ≈ 0.76·weak_loss at −v_ref, weak_loss far below."""

    name = "blind6_patch2_negative_saturating"
    description = "Couple 2 couples less by weak_loss·tanh(−v_c2/v_ref) for v_c2 < 0 (saturating, negative only)"
    origin = ("Intermediate MFCs whose fatigued domains back-switch under reverse field: the share switched grows "
              "with the field until all the loose domains have switched")
    parameters = (
        Parameter("weak_loss", "1", 0.0, 0.0, 0.9, "Fraction of couple 2's coupling lost far below −v_ref",
                  neutral=0.0),
        Parameter("v_ref", "V", 80.0, 1.0e-3, 1.5e3, "Negative voltage scale of the saturation"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        reverse = max(0.0, -bus[B.vc2])
        w = p[P.weak_loss] * math.tanh(reverse / p[P.v_ref])
        lost_theta = w * p[P.k2] * p[P.d_ep]
        f = lost_theta * bus[B.qh2] / p[P.C_ep]
        bus[B.s2] -= f
        bus[B.p_piezo] -= f * x[X.ddelta2]
        dx[X.q2] += lost_theta * x[X.ddelta2]


# --- the set ----------------------------------------------------------------------------------------------------------

#: where a mass change sits, and that it is a mass (the verdict may write "m3 lower", "the tip mass fell")
TIP_MASS: tuple[str, ...] = ("m3", "mass 3", "tip mass", "section 3")
MASS: tuple[str, ...] = ("mass", "m3", "inertia", "lighter")
#: every couple, not one of them (the verdict may write "all three couples", "patches 1–3")
ALL_PATCHES: tuple[str, ...] = ("all three", "all patches", "all the patches", "all couples", "all the couples",
                                "every patch", "every couple", "each patch", "each couple", "patches 1", "couples 1",
                                "1, 2 and 3", "1–3", "1-3")

#: label → (class, truth values, word groups, timing). Above each case: its size_sigma (case_record, 2 µm, seed 1)
#: on the 15 s sweep, MBIT.a (20 s) and MBIT.b (3 s), measured 2026-11-29 11:20–11:30 UTC; a 0.0 (or near it) on
#: MBIT.b is a damage its one-way positive step never reaches (the other sign), so that record cannot show it; the
#: tip mass's change is near 0 on MBIT.a too (a 0.1 Hz drive is quasi-static: no inertia in it).
BLIND6: dict[str, tuple[type[PhysicalEffect], dict[str, float], Words, Timing]] = {
    # cracks that open on one side
    # size_sigma sweep 135, MBIT.a 114, MBIT.b 103
    "root_crack_opens_up": (RootCrackOpensUp, {"crack_loss": 0.20}, (section(1), CRACK), None),
    # size_sigma sweep 429, MBIT.a 73, MBIT.b 3.2 (the step bends δ3 down only in its first overshoots)
    "tip_crack_opens_down": (TipCrackOpensDownSmooth, {"crack_loss": 0.15, "edge": 5.0e-6},
                             (section(3), CRACK), None),
    # size_sigma sweep 341, MBIT.a 152, MBIT.b 148
    "mid_crack_rubs_open_up": (MidCrackRubsOpenUp, {"crack_loss": 0.25, "tau_rub": 5.0e-4},
                               (section(2), CRACK), None),
    # size_sigma sweep 72, MBIT.a 56, MBIT.b 0.0 (δ1 ≥ 0 on the step: the crack never opens)
    "root_bilinear_spring_down": (RootBilinearSpringDown, {"crack_loss": 0.12}, (section(1), CRACK), None),
    # stiffness lost inside the record
    # size_sigma sweep 909, MBIT.a 76, MBIT.b 62
    "tip_cracks_through": (TipCracksThrough, {"k_loss": 0.20, "t_crack_frac": 0.70}, (section(3), STIFF),
                           ("t_crack", 0.5)),
    # size_sigma sweep 175, MBIT.a 93, MBIT.b 65
    "root_ramp_half_second": (RootRampHalfSecond, {"k_loss": 0.15, "t_begin_frac": 0.20, "ramp_s": 0.5},
                              (section(1), STIFF), ("t_begin", 0.5)),
    # size_sigma sweep 808, MBIT.a 118, MBIT.b 87
    "mid_tip_impact": (MidTipImpact, {"k_loss": 0.12, "t_hit_frac": 0.50}, (section(2), section(3), STIFF),
                       ("t_hit", 0.5)),
    # size_sigma sweep 659, MBIT.a 0.005 (0.1 Hz is quasi-static: no inertia to see), MBIT.b 4.1 (only the
    # late ringing of the step, which has mostly died out by t_off = 1.05 s)
    "tip_mass_breaks_off": (TipMassBreaksOff, {"mass_loss": 0.10, "t_off_frac": 0.35}, (TIP_MASS, MASS),
                            ("t_off", 0.5)),
    # patches weak in one polarity
    # size_sigma sweep 93, MBIT.a 165, MBIT.b 0.0 (v_c3 ≥ 0 on the step)
    "patch3_weak_negative_v": (Patch3WeakNegativeVoltage, {"weak_loss": 0.40}, (patch_at(3), PATCH, POLARITY),
                               None),
    # size_sigma sweep 84, MBIT.a 114, MBIT.b 101
    "patch1_weak_positive_drive": (Patch1WeakPositiveDrive, {"weak_loss": 0.25, "v_edge": 25.0},
                                   (patch_at(1), PATCH, POLARITY), None),
    # size_sigma sweep 247, MBIT.a 371, MBIT.b 0.1 (every v_ci ≥ 0 on the step but for the tanh edge)
    "all_patches_weak_negative": (AllPatchesWeakNegative,
                                  {"weak_loss": 0.40, "ratio2": 0.75, "ratio3": 0.5, "v_edge": 10.0},
                                  (ALL_PATCHES, PATCH, POLARITY), None),
    # size_sigma sweep 96, MBIT.a 144, MBIT.b 0.0 (v_c2 ≥ 0 on the step)
    "patch2_negative_saturating": (Patch2NegativeLossSaturates, {"weak_loss": 0.35, "v_ref": 80.0},
                                   (patch_at(2), PATCH, POLARITY), None),
}


def truth_values(label: str, duration_s: float) -> dict[str, float]:
    """The truth values of ``label`` for a record of ``duration_s``: a ``*_frac`` value becomes frac × duration_s
    under the name without the suffix."""
    from workbench_unseen_damage import values_at

    return values_at(BLIND6[label][1], duration_s)


def run_blind6(label: str, *, kind: str = "sweep", duration_s: float = 15.0, noise_m: float = 2e-6, seed: int = 1,
               workdir: str | None = None) -> dict[str, object]:
    from workbench_unseen_damage import run_set_case

    return run_set_case(BLIND6, label, kind=kind, duration_s=duration_s, noise_m=noise_m, seed=seed, workdir=workdir)
