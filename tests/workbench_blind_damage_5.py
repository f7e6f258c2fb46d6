"""A fifth blind set of damage effects: twelve damages written from the plant's effect seam and the seed paper alone,
by someone who has not seen how the workbench discovers damage (nor the earlier sets' discovery runs); sets 1–4 and
the unseen set were read only to avoid repeating their forms.

Three families of four, the ones a monitor of this beam most needs, each varied in section, sign, sharpness,
switching variable and time profile in ways the earlier sets did not use:

* cracks that open on one side: a tip crack whose faces part while the section *moves* down (switched by the sign
  of δ̇3, smooth edge), a crack at the root/intermediate junction opened by the *kink* between the two sections
  (the relative deflection δ2 − δ1, softening section 2), a tip crack at the inboard end of section 3 opened by the
  bending of its inboard neighbour (δ2 > 0), a crack in the intermediate section softer while open (δ2 < 0) whose
  faces clap and rub while shut (stiffness lost on one side, damping added on the other);
* stiffness lost inside the record: the root and the tip sections cracking at two different instants, an
  intermediate section cracking through at the first downward overload past a deflection (an instant the motion
  decides, latched in the effect's own state), a slow root loss that began before the record and is still growing
  at its end (a linear drift, never held), a tip crack that grows in three equal jumps (pop-in) at even intervals.
  Instants are fractions of the record (``*_frac`` values, scaled by :func:`truth_values`; a negative one lies
  before the record);
* patches weak in one polarity: the root couple weak while it is *charging* (the sign of its current, i.e. of the
  drive's rate against the patch's voltage), the tip couple weak for positive charge (smooth), the root and the tip
  couples weak in *opposite* polarities of their own voltages, couple 2 whose weakness grows with the square of its
  voltage on the negative side only.

Section forces follow ``plant/effects/laminate.py``: ``bus[B.s_i]`` carries −k_i δ_i − c_i δ̇_i + θ_i q_hi/C_ep, so a
section that softens by Δk *adds* +Δk δ_i and extra damping adds −Δc δ̇_i. The piezo force of couple i is
θ_i q_hi / C_ep with θ_i = k_i d_ep (``plant/effects/piezo_coupling.py``), its back-coupling current −θ_i δ̇_i: a
couple that couples less by a fraction w takes back w of both (and of their power in ``bus[B.p_piezo]``). A patch's
charge q_i is fed through R_ep by the current (v_a − q_i/C_ep)/R_ep (``plant/effects/patch_rc.py``).

Every damage has one size parameter with ``neutral=0.0`` (healthy at 0). :data:`BLIND5` maps each label to (class,
truth values, word groups the verdict's first sentence must match, timing); :func:`run_blind5` runs one through the
one-command walk of ``workbench_unseen_damage.run_walk``. The sizes quoted on each case are ``size_sigma`` of
``workbench.challenges.discovery.case_record`` at the truth values, 2 µm noise, seed 1, on the 15 s sweep, MBIT.a and
MBIT.b (measured 2026-11-28 while writing the set).
"""

from __future__ import annotations

import math

from workbench_blind_damage_3 import CRACK, PATCH, POLARITY, STIFF, Timing, Words, patch_at, section

from plant.effect import Parameter, PhysicalEffect, StateSpec

# --- cracks that open on one side -------------------------------------------------------------------------------------


class TipCrackOpensMovingDown(PhysicalEffect):
    """A crack in the tip section (3) whose faces part while the section moves down (δ̇3 < 0) and are pressed shut
    while it moves up: the section loses crack_loss of k3 through the gate ½(1 − tanh(δ̇3/v_edge)) — a breathing
    crack switched by the sign of the rate, not of the deflection."""

    name = "blind5_tip_crack_moving_down"
    description = "Section 3 softer by crack_loss·k3 while δ̇3 < 0 (switched by the rate, smooth edge over v_edge)"
    origin = ("Tip crack filled with a viscous film (moisture, fretting paste): the film's drag pulls the faces "
              "apart while the section swings down and squeezes them shut while it swings up")
    parameters = (
        Parameter("crack_loss", "1", 0.0, 0.0, 0.9, "Fraction of k3 lost while δ̇3 < 0", neutral=0.0),
        Parameter("v_edge", "m/s", 2.0e-4, 1.0e-7, 1.0, "Rate δ̇3 over which the crack switches"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        gate = 0.5 * (1.0 - math.tanh(x[X.ddelta3] / p[P.v_edge]))
        bus[B.s3] += p[P.crack_loss] * gate * p[P.k3] * x[X.delta3]


class MidCrackOnKink(PhysicalEffect):
    """A crack at the junction of the root and intermediate sections (the end of the root patches) lying in section
    2 and opened by the kink between the two sections: while δ2 − δ1 > 0 (sharp switch) section 2 loses crack_loss
    of k2. Neither section's own sign decides; their difference does."""

    name = "blind5_mid_crack_on_kink"
    description = "Section 2 softer by crack_loss·k2 while δ2 − δ1 > 0 (switched by the relative deflection)"
    origin = ("Crack at the stiffness discontinuity where the root patches end: its opening follows the jump of "
              "curvature across the junction, the difference of the two sections' bending")
    parameters = (
        Parameter("crack_loss", "1", 0.0, 0.0, 0.9, "Fraction of k2 lost while δ2 − δ1 > 0", neutral=0.0),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        if x[X.delta2] - x[X.delta1] > 0.0:
            bus[B.s2] += p[P.crack_loss] * p[P.k2] * x[X.delta2]


class TipCrackOnMidBend(PhysicalEffect):
    """A crack at the inboard end of the tip section (3), at the junction with the intermediate section, opened by
    the bending of its inboard neighbour: while δ2 > 0 (sharp switch) section 3 loses crack_loss of k3."""

    name = "blind5_tip_crack_on_mid_bend"
    description = "Section 3 softer by crack_loss·k3 while δ2 > 0 (switched by the inboard neighbour's deflection)"
    origin = ("Crack where the tip patches end, opened by the curvature of the intermediate section that carries "
              "most of the bending moment at the junction")
    parameters = (
        Parameter("crack_loss", "1", 0.0, 0.0, 0.9, "Fraction of k3 lost while δ2 > 0", neutral=0.0),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        if x[X.delta2] > 0.0:
            bus[B.s3] += p[P.crack_loss] * p[P.k3] * x[X.delta3]


class MidCrackClapsWhenShut(PhysicalEffect):
    """A crack in the intermediate section (2) open for δ2 < 0, where it loses crack_loss of k2, whose rough faces
    clap together and rub while shut (δ2 ≥ 0), adding c_gain·crack_loss·c2 of damping there: the stiffness is lost
    on one side, the energy on the other. Sharp switch at δ2 = 0."""

    name = "blind5_mid_crack_claps"
    description = ("Section 2 softer by crack_loss·k2 while δ2 < 0, damping higher by c_gain·crack_loss·c2 while "
                   "δ2 ≥ 0 (contact friction of the shut faces)")
    origin = ("Fatigue crack with a rough, mismatched fracture surface: open it carries no load, shut its asperities "
              "slide on each other and dissipate")
    parameters = (
        Parameter("crack_loss", "1", 0.0, 0.0, 0.9, "Fraction of k2 lost while δ2 < 0", neutral=0.0),
        Parameter("c_gain", "1", 3.0, 0.0, 50.0, "Damping added while shut, per unit crack_loss, as a share of c2"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        d = x[X.delta2]
        if d < 0.0:
            bus[B.s2] += p[P.crack_loss] * p[P.k2] * d
        else:
            bus[B.s2] -= p[P.c_gain] * p[P.crack_loss] * p[P.c2] * x[X.ddelta2]


# --- stiffness lost inside the record ---------------------------------------------------------------------------------


class RootThenTipLoss(PhysicalEffect):
    """The root section (1) cracks at t_root and the tip section (3) at the later t_tip, each losing the same
    fraction k_loss of its stiffness (two steps in two sections at two instants)."""

    name = "blind5_root_then_tip_loss"
    description = "Section 1 stiffness lower by k_loss·k1 from t_root, section 3 by k_loss·k3 from t_tip (two steps)"
    origin = ("An overload cracks the root at the clamp edge; the load it sheds onto the outer laminate then cracks "
              "the tip section a few seconds later")
    parameters = (
        Parameter("k_loss", "1", 0.0, 0.0, 0.9, "Fraction of k1 (from t_root) and of k3 (from t_tip) lost",
                  neutral=0.0),
        Parameter("t_root", "s", 4.0, 0.0, 1.0e4, "Instant the root cracks"),
        Parameter("t_tip", "s", 9.0, 0.0, 1.0e4, "Instant the tip cracks"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        if t >= p[P.t_root]:
            bus[B.s1] += p[P.k_loss] * p[P.k1] * x[X.delta1]
        if t >= p[P.t_tip]:
            bus[B.s3] += p[P.k_loss] * p[P.k3] * x[X.delta3]


class MidLossAfterOverload(PhysicalEffect):
    """The intermediate section (2) cracks through the first time it is bent down past d_crit (δ2 < −d_crit): a
    state ``cracked2`` latches from 0 to 1 (time constant 1 ms) and stays, and from then on the section carries
    (1 − k_loss) k2 for both signs. The instant is not a clock's: the motion decides it."""

    name = "blind5_mid_loss_after_overload"
    description = "Section 2 stiffness lower by k_loss·k2 from the first time δ2 < −d_crit on (overload, latched)"
    origin = ("A through-thickness crack initiated by the first downward overload of the intermediate section past "
              "its strain allowable; once started it does not close again")
    parameters = (
        Parameter("k_loss", "1", 0.0, 0.0, 0.9, "Fraction of k2 lost once cracked", neutral=0.0),
        Parameter("d_crit", "m", 9.0e-4, 0.0, 1.0e-2, "Downward deflection δ2 that starts the crack"),
    )
    states = (StateSpec("cracked2", "1", 1.0, 0.0),)

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        s = x[X.cracked2]
        dx[X.cracked2] = (1.0 - s) / 1.0e-3 if x[X.delta2] < -p[P.d_crit] else 0.0
        bus[B.s2] += p[P.k_loss] * s * p[P.k2] * x[X.delta2]


class RootDriftStartedBefore(PhysicalEffect):
    """The root section (1) has been losing stiffness at a steady rate since t_start, before the record began, and
    is still losing it at its end: loss(t) = k_loss·clip((t − t_start)/t_span, 0, 1) with t_start < 0 and
    t_start + t_span past the record — already part-lost at t = 0, a straight drift throughout, never held."""

    name = "blind5_root_drift_started_before"
    description = "Section 1 stiffness lower by k_loss·(t − t_start)/t_span, a drift begun before the record"
    origin = ("Moisture ingress (or creep of the clamp's epoxy) at the root, progressing over tens of seconds of "
              "the heated test: the record catches the loss under way")
    parameters = (
        Parameter("k_loss", "1", 0.0, 0.0, 0.9, "Fraction of k1 lost at t_start + t_span", neutral=0.0),
        Parameter("t_start", "s", -5.0, -1.0e4, 1.0e4, "Instant the drift began (before the record: negative)"),
        Parameter("t_span", "s", 30.0, 1.0e-3, 1.0e4, "Duration of the drift to the full loss"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        s = min(1.0, max(0.0, (t - p[P.t_start]) / p[P.t_span]))
        bus[B.s1] += p[P.k_loss] * s * p[P.k1] * x[X.delta1]


class TipLossInJumps(PhysicalEffect):
    """A crack in the tip section (3) that grows by pop-in: three equal jumps of k_loss/3 each, at t_first,
    t_first + t_gap and t_first + 2·t_gap (a staircase)."""

    name = "blind5_tip_loss_in_jumps"
    description = "Section 3 stiffness lower by k_loss/3 at each of t_first, t_first + t_gap, t_first + 2 t_gap"
    origin = ("Crack advancing by bursts: it arrests at each tougher ply and jumps on when the load has opened "
              "it enough (crack pop-in, as acoustic emission hears it)")
    parameters = (
        Parameter("k_loss", "1", 0.0, 0.0, 0.9, "Fraction of k3 lost after the third jump", neutral=0.0),
        Parameter("t_first", "s", 4.0, 0.0, 1.0e4, "Instant of the first jump"),
        Parameter("t_gap", "s", 2.0, 1.0e-3, 1.0e4, "Time between jumps"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        n = 0.0
        for j in range(3):
            if t >= p[P.t_first] + j * p[P.t_gap]:
                n += 1.0
        bus[B.s3] += p[P.k_loss] * n / 3.0 * p[P.k3] * x[X.delta3]


# --- patches weak in one polarity -------------------------------------------------------------------------------------


class Patch1WeakWhileCharging(PhysicalEffect):
    """The root couple (1) loses weak_loss of its coupling while it is being charged: while the current into it
    through R_ep, i_1 = (v_a − v_c1)/R_ep, is positive (the drive rising against the patch's voltage), by the share
    max(0, tanh(i_1/i_edge)) — none at rest, nearly all of it once i_1 ≫ i_edge; while it discharges it is healthy.
    A weakness in one polarity of the drive's rate."""

    name = "blind5_patch1_weak_charging"
    description = ("Couple 1 couples less by weak_loss·max(0, tanh(i_1/i_edge)) while charging, "
                   "i_1 = (v_a − v_c1)/R_ep (one polarity of the drive's rate)")
    origin = ("Fatigued root MFCs whose domain walls are pinned by migrating defects: the walls' (extrinsic) share of "
              "the strain is lost while the field rises in the poling sense and comes back while it falls")
    parameters = (
        Parameter("weak_loss", "1", 0.0, 0.0, 0.9, "Fraction of couple 1's coupling lost while charging",
                  neutral=0.0),
        Parameter("i_edge", "A", 2.0e-4, 1.0e-9, 1.0, "Charging current over which the weakness switches"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        i1 = (bus[B.va] - bus[B.vc1]) / p[P.R_ep]
        w = p[P.weak_loss] * max(0.0, math.tanh(i1 / p[P.i_edge]))
        theta = p[P.k1] * p[P.d_ep]
        force = w * theta * bus[B.qh1] / p[P.C_ep]
        bus[B.s1] -= force
        bus[B.p_piezo] -= force * x[X.ddelta1]
        dx[X.q1] += w * theta * x[X.ddelta1]


class Patch3WeakPositiveCharge(PhysicalEffect):
    """The tip couple (3) loses weak_loss of its coupling while its own effective charge q_h3 is positive, gate
    ½(1 + tanh(q_h3/q_edge)); healthy for negative charge."""

    name = "blind5_patch3_weak_positive_charge"
    description = "Couple 3 couples less by weak_loss while q_h3 > 0 (smooth over q_edge)"
    origin = ("Tip MFCs with a cracked electrode bus on their positive side: the charge of that sign reaches only "
              "part of the fibres")
    parameters = (
        Parameter("weak_loss", "1", 0.0, 0.0, 0.9, "Fraction of couple 3's coupling lost for q_h3 > 0", neutral=0.0),
        Parameter("q_edge", "C", 1.0e-4, 1.0e-9, 1.0e-1, "Charge over which the weakness switches"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        w = p[P.weak_loss] * 0.5 * (1.0 + math.tanh(bus[B.qh3] / p[P.q_edge]))
        theta = p[P.k3] * p[P.d_ep]
        force = w * theta * bus[B.qh3] / p[P.C_ep]
        bus[B.s3] -= force
        bus[B.p_piezo] -= force * x[X.ddelta3]
        dx[X.q3] += w * theta * x[X.ddelta3]


class Patches1And3OppositePolarity(PhysicalEffect):
    """The root couple (1) is weak while its own voltage is positive and the tip couple (3) while its own voltage is
    negative, each losing weak_loss of its coupling (gates ½(1 ± tanh(v_ci/edge_v))): two patches weak in opposite
    polarities."""

    name = "blind5_patches13_opposite_polarity"
    description = "Couple 1 couples less by weak_loss for v_c1 > 0, couple 3 for v_c3 < 0 (smooth over edge_v)"
    origin = ("A re-poling after repair with the leads of one side swapped: the root couple was driven against its "
              "poling in one sense, the tip couple in the other, each partly depoled for that polarity")
    parameters = (
        Parameter("weak_loss", "1", 0.0, 0.0, 0.9, "Fraction of coupling lost in each couple's weak polarity",
                  neutral=0.0),
        Parameter("edge_v", "V", 20.0, 1.0e-3, 1.0e3, "Width of the switches in v_c1 and v_c3"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        w1 = p[P.weak_loss] * 0.5 * (1.0 + math.tanh(bus[B.vc1] / p[P.edge_v]))
        theta1 = p[P.k1] * p[P.d_ep]
        force1 = w1 * theta1 * bus[B.qh1] / p[P.C_ep]
        bus[B.s1] -= force1
        bus[B.p_piezo] -= force1 * x[X.ddelta1]
        dx[X.q1] += w1 * theta1 * x[X.ddelta1]
        w3 = p[P.weak_loss] * 0.5 * (1.0 - math.tanh(bus[B.vc3] / p[P.edge_v]))
        theta3 = p[P.k3] * p[P.d_ep]
        force3 = w3 * theta3 * bus[B.qh3] / p[P.C_ep]
        bus[B.s3] -= force3
        bus[B.p_piezo] -= force3 * x[X.ddelta3]
        dx[X.q3] += w3 * theta3 * x[X.ddelta3]


class Patch2WeakerWithNegativeSquare(PhysicalEffect):
    """Couple 2 loses coupling in proportion to the square of its own voltage on the negative side only:
    w = min(1, weak_loss·(min(v_c2, 0)/v_ref)²) — weak_loss at v_c2 = −v_ref, healthy for positive voltage."""

    name = "blind5_patch2_weaker_negative_square"
    description = "Couple 2 couples less by weak_loss·(v_c2/v_ref)² for v_c2 < 0 (grows with the negative voltage)"
    origin = ("Electrode of the intermediate MFCs partly lifted from the fibres: the electrostatic pressure of a field "
              "against the poling (∝ E²) peels more of it the stronger the negative voltage")
    parameters = (
        Parameter("weak_loss", "1", 0.0, 0.0, 1.0, "Fraction of couple 2's coupling lost at v_c2 = −v_ref",
                  neutral=0.0),
        Parameter("v_ref", "V", 500.0, 1.0e-3, 1.5e3, "Negative voltage magnitude at which weak_loss is lost"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        u = min(bus[B.vc2], 0.0) / p[P.v_ref]
        w = min(1.0, p[P.weak_loss] * u * u)
        theta = p[P.k2] * p[P.d_ep]
        force = w * theta * bus[B.qh2] / p[P.C_ep]
        bus[B.s2] -= force
        bus[B.p_piezo] -= force * x[X.ddelta2]
        dx[X.q2] += w * theta * x[X.ddelta2]


# --- the set ----------------------------------------------------------------------------------------------------------

#: a patch weak in one sense of its charging (the verdict may write "while charging", "dv_a/dt > 0")
RATE_POLARITY: tuple[str, ...] = (*POLARITY, "charging", "rising", "falling", "v̇", "/dt")

#: label → (class, truth values, word groups, timing). Above each case: its size_sigma (case_record, 2 µm, seed 1)
#: on the 15 s sweep, MBIT.a (20 s) and MBIT.b (3 s), measured 2026-11-28 17:51–17:56 UTC; a 0.0 (or near it) on
#: MBIT.b is a damage its one-way positive step never reaches (the other sign), so that record cannot show it.
BLIND5: dict[str, tuple[type[PhysicalEffect], dict[str, float], Words, Timing]] = {
    # cracks that open on one side
    # size_sigma sweep 268, MBIT.a 166, MBIT.b 47
    "tip_crack_moving_down": (TipCrackOpensMovingDown, {"crack_loss": 0.10, "v_edge": 2.0e-4},
                              (section(3), CRACK), None),
    # size_sigma sweep 350, MBIT.a 152, MBIT.b 151 (quasi-static the kink is sub-µm: it switches on the dynamic lag)
    "mid_crack_on_kink": (MidCrackOnKink, {"crack_loss": 0.25}, (section(2), CRACK), None),
    # size_sigma sweep 286, MBIT.a 51, MBIT.b 66
    "tip_crack_on_mid_bend": (TipCrackOnMidBend, {"crack_loss": 0.10}, (section(3), CRACK), None),
    # size_sigma sweep 351, MBIT.a 137, MBIT.b 2.2 (δ2 ≥ 0 on the step: only the shut side's damping)
    "mid_crack_claps": (MidCrackClapsWhenShut, {"crack_loss": 0.25, "c_gain": 3.0}, (section(2), CRACK), None),
    # stiffness lost inside the record
    # size_sigma sweep 372, MBIT.a 55, MBIT.b 40
    "root_then_tip_loss": (RootThenTipLoss, {"k_loss": 0.06, "t_root_frac": 0.25, "t_tip_frac": 0.60},
                           (section(1), section(3), STIFF), ("t_root", 0.5)),
    # size_sigma sweep 372, MBIT.a 92, MBIT.b 0.0 (cracks at ≈ 10.2 s, 6.0 s; the step never bends δ2 down)
    "mid_loss_after_overload": (MidLossAfterOverload, {"k_loss": 0.15, "d_crit": 9.0e-4}, (section(2), STIFF), None),
    # size_sigma sweep 234, MBIT.a 115, MBIT.b 83
    "root_drift_started_before": (RootDriftStartedBefore,
                                  {"k_loss": 0.30, "t_start_frac": -0.5, "t_span_frac": 2.0},
                                  (section(1), STIFF), None),
    # size_sigma sweep 324, MBIT.a 26, MBIT.b 20
    "tip_loss_in_jumps": (TipLossInJumps, {"k_loss": 0.06, "t_first_frac": 0.25, "t_gap_frac": 0.20},
                          (section(3), STIFF), ("t_first", 0.5)),
    # patches weak in one polarity
    # size_sigma sweep 164, MBIT.a 169, MBIT.b 38 (the step charges the patch for a few R_ep C_ep only)
    "patch1_weak_charging": (Patch1WeakWhileCharging, {"weak_loss": 0.40, "i_edge": 2.0e-4},
                             (patch_at(1), PATCH, RATE_POLARITY), None),
    # size_sigma sweep 97, MBIT.a 183, MBIT.b 161
    "patch3_weak_positive_charge": (Patch3WeakPositiveCharge, {"weak_loss": 0.40, "q_edge": 1.0e-4},
                                    (patch_at(3), PATCH, POLARITY), None),
    # size_sigma sweep 146, MBIT.a 215, MBIT.b 141
    "patches13_opposite_polarity": (Patches1And3OppositePolarity, {"weak_loss": 0.35, "edge_v": 20.0},
                                    (patch_at(1), patch_at(3), PATCH, POLARITY), None),
    # size_sigma sweep 24, MBIT.a 189, MBIT.b 0.0 (v_c2 ≥ 0 on the step)
    "patch2_weaker_negative_square": (Patch2WeakerWithNegativeSquare, {"weak_loss": 0.40, "v_ref": 500.0},
                                      (patch_at(2), PATCH, POLARITY), None),
}


def truth_values(label: str, duration_s: float) -> dict[str, float]:
    """The truth values of ``label`` for a record of ``duration_s``: a ``*_frac`` value becomes frac × duration_s
    under the name without the suffix."""
    from workbench_unseen_damage import values_at

    return values_at(BLIND5[label][1], duration_s)


def run_blind5(label: str, *, kind: str = "sweep", duration_s: float = 15.0, noise_m: float = 2e-6, seed: int = 1,
               workdir: str | None = None) -> dict[str, object]:
    from workbench_unseen_damage import run_set_case

    return run_set_case(BLIND5, label, kind=kind, duration_s=duration_s, noise_m=noise_m, seed=seed, workdir=workdir)
