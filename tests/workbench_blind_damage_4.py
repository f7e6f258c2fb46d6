"""A fourth blind set of damage effects: twelve damages written from the plant's effect seam and the seed paper alone,
by someone who has not seen how the workbench discovers damage (nor the earlier sets' discovery runs); sets 1–3 and
the unseen set were read only to avoid repeating their forms.

Three families of four, the ones a monitor of this beam most needs, each varied in section, sign, sharpness,
switching point and time profile in ways the earlier sets did not use:

* cracks that open on one side: a mid-section crack held shut until the section bends down past an offset
  (continuous bilinear), a root crack that opens gradually downward and rubs while open (stiffness *and* damping
  switched together), a tip crack that does not close fully (its closed side keeps a share of the loss), a root crack
  open at rest that only closes once the section bends down past an offset (softer near rest and upward);
* stiffness lost inside the record: an accelerating (quadratic-in-time) loss of the intermediate section, the root
  and the intermediate section losing stiffness at one instant, a tip loss that settles exponentially over tenths of
  a second, a root loss followed by a partial recovery at a later instant (two steps of opposite sign). Instants are
  fractions of the record (``*_frac`` values, scaled by :func:`truth_values`); durations of a few tenths of a second
  are in seconds;
* patches weak in one polarity: the tip couple weak while the drive is below a negative threshold (sharp), the root
  couple fading gradually with its own positive voltage over a range, couple 2 losing active electrode area — its
  authority *and* its capacitance — for negative voltage, the tip couple whose domains switch below −v_sw and stay
  switched until +v_sw re-poles them (a polarity weakness with memory, carried in the effect's own state).

Section forces follow ``plant/effects/laminate.py``: ``bus[B.s_i]`` carries −k_i δ_i − c_i δ̇_i + θ_i q_hi/C_ep, so a
section that softens by Δk *adds* +Δk δ_i and extra damping adds −Δc δ̇_i. The piezo force of couple i is
θ_i q_hi / C_ep with θ_i = k_i d_ep (``plant/effects/piezo_coupling.py``), its back-coupling current −θ_i δ̇_i: a
couple that couples less by a fraction w takes back w of both (and of their power in ``bus[B.p_piezo]``). A patch's
charge q_i is fed through R_ep by v_a − q_i/C_ep (``plant/effects/patch_rc.py``): a capacitance lower by a share g
raises the capacitor's voltage to q_i/((1 − g) C_ep), and the current through R_ep falls accordingly.

Every damage has one size parameter with ``neutral=0.0`` (healthy at 0). :data:`BLIND4` maps each label to (class,
truth values, word groups the verdict's first sentence must match, timing); :func:`run_blind4` runs one through the
one-command walk of ``workbench_unseen_damage.run_walk``. The sizes quoted on each case are ``size_sigma`` of
``workbench.challenges.discovery.case_record`` at the truth values, 2 µm noise, seed 1, on the 15 s sweep, MBIT.a and
MBIT.b (measured 2026-11-28 while writing the set).
"""

from __future__ import annotations

import math

from workbench_blind_damage_3 import CRACK, PATCH, POLARITY, STIFF, Timing, Words, patch_at, section

from plant.effect import Parameter, PhysicalEffect, StateSpec

# --- cracks that open on one side -------------------------------------------------------------------------------------


class MidCrackPastOffset(PhysicalEffect):
    """A crack in the intermediate section (2) held shut by a compressive residual stress: it opens only once the
    section bends down past d_open (δ2 < −d_open); beyond that point the section carries (1 − crack_loss) k2 for the
    part beyond — a continuous bilinear spring with a sharp corner at δ2 = −d_open."""

    name = "blind4_mid_crack_past_offset"
    description = "Section 2 softer by crack_loss·k2 for the part of δ2 below −d_open (bilinear, offset switch)"
    origin = ("Fatigue crack at a ply drop of the intermediate section, kept closed by the residual (cure) stress of "
              "the laminate until the bending strain overcomes it")
    parameters = (
        Parameter("crack_loss", "1", 0.0, 0.0, 0.9, "Fraction of k2 lost beyond the opening point", neutral=0.0),
        Parameter("d_open", "m", 4.0e-4, 0.0, 1.0e-2, "Downward deflection δ2 at which the crack starts to open"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        beyond = x[X.delta2] + p[P.d_open]
        if beyond < 0.0:
            bus[B.s2] += p[P.crack_loss] * p[P.k2] * beyond


class RootCrackRubsWhileOpen(PhysicalEffect):
    """A crack in the root section (1) that opens gradually while the section bends down (δ1 < 0, gate
    ½(1 − tanh(δ1/edge_width))) and whose faces rub while open: the open crack loses crack_loss of k1 and adds
    damping c_gain·crack_loss·c1, both through the same gate."""

    name = "blind4_root_crack_rubs"
    description = ("Section 1 stiffness lower by crack_loss·k1 and damping higher by c_gain·crack_loss·c1 while "
                   "δ1 < 0 (smooth edge over edge_width)")
    origin = ("Transverse crack at the clamp edge under the root patches: it opens under the tension of downward "
              "bending, and its rough faces slide and rub while it is open")
    parameters = (
        Parameter("crack_loss", "1", 0.0, 0.0, 0.9, "Fraction of k1 lost with the crack open", neutral=0.0),
        Parameter("edge_width", "m", 1.5e-4, 1.0e-6, 1.0e-2, "Deflection δ1 over which the crack opens"),
        Parameter("c_gain", "1", 2.0, 0.0, 50.0, "Damping added while open, per unit crack_loss, as a share of c1"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        gate = p[P.crack_loss] * 0.5 * (1.0 - math.tanh(x[X.delta1] / p[P.edge_width]))
        bus[B.s1] += gate * (p[P.k1] * x[X.delta1] - p[P.c_gain] * p[P.c1] * x[X.ddelta1])


class TipCrackClosesPartly(PhysicalEffect):
    """A crack in the tip section (3) open for δ3 > 0 whose faces no longer mate (a mismatch, debris): it loses
    crack_loss of k3 while open and still closed_share of that loss while shut (δ3 ≤ 0) — one-sided, but the closed
    side is not healthy either. Sharp switch at δ3 = 0."""

    name = "blind4_tip_crack_closes_partly"
    description = "Section 3 softer by crack_loss·k3 for δ3 > 0 and by closed_share·crack_loss·k3 for δ3 ≤ 0"
    origin = ("Tip-section crack whose faces were displaced by a shear slip: when it closes they touch on a part of "
              "their area only, so the compressive side carries less than a healthy section")
    parameters = (
        Parameter("crack_loss", "1", 0.0, 0.0, 0.9, "Fraction of k3 lost while δ3 > 0", neutral=0.0),
        Parameter("closed_share", "1", 0.4, 0.0, 1.0, "Share of that loss left while the crack is shut"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        d = x[X.delta3]
        share = 1.0 if d > 0.0 else p[P.closed_share]
        bus[B.s3] += share * p[P.crack_loss] * p[P.k3] * d


class RootCrackOpenAtRest(PhysicalEffect):
    """A root crack (section 1) propped open at rest: its faces stand d_close apart, so the section carries
    (1 − crack_loss) k1 at rest and upward, and takes its full stiffness back for the part beyond δ1 < −d_close,
    where the faces meet. Added force crack_loss·k1·max(δ1, −d_close): the lost force saturates on the closing side."""

    name = "blind4_root_crack_open_at_rest"
    description = "Section 1 softer by crack_loss·k1 for δ1 > −d_close, healthy increment beyond (faces meet)"
    origin = ("Root crack wedged open by fretting debris or a plastic zone at its tip: open with no load, closed only "
              "once the downward bending has taken up the gap")
    parameters = (
        Parameter("crack_loss", "1", 0.0, 0.0, 0.9, "Fraction of k1 lost while the crack is open", neutral=0.0),
        Parameter("d_close", "m", 2.5e-4, 0.0, 1.0e-2, "Downward deflection δ1 at which the faces meet"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        d = max(x[X.delta1], -p[P.d_close])
        bus[B.s1] += p[P.crack_loss] * p[P.k1] * d


# --- stiffness lost inside the record ---------------------------------------------------------------------------------


class MidAcceleratingLoss(PhysicalEffect):
    """The intermediate section (2) loses stiffness at an accelerating rate from t_start: loss(t) =
    k_loss·min(1, ((t − t_start)/t_grow)²) — zero slope at the onset, steepest at the end, then held."""

    name = "blind4_mid_accelerating_loss"
    description = "Section 2 stiffness lower by k_loss·((t − t_start)/t_grow)² from t_start, held after t_grow"
    origin = ("Fatigue crack growing under the test's load at a rate that rises with its length (Paris law): "
              "slow at first, faster and faster until it reaches a stiffener")
    parameters = (
        Parameter("k_loss", "1", 0.0, 0.0, 0.9, "Fraction of k2 lost at the end of the growth", neutral=0.0),
        Parameter("t_start", "s", 4.0, 0.0, 1.0e4, "Instant the loss starts"),
        Parameter("t_grow", "s", 8.0, 1.0e-3, 1.0e4, "Duration of the growth to the full loss"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        s = min(1.0, max(0.0, (t - p[P.t_start]) / p[P.t_grow]))
        bus[B.s2] += p[P.k_loss] * s * s * p[P.k2] * x[X.delta2]


class RootMidLossAtOnce(PhysicalEffect):
    """An impact at the end of the root patches cracks the root (1) and the intermediate (2) sections together at
    t_hit: both lose the same fraction k_loss of their stiffness at once (step)."""

    name = "blind4_root_mid_loss_at_once"
    description = "Sections 1 and 2 stiffness lower by k_loss·k1 and k_loss·k2 from t_hit on (one step in both)"
    origin = "Impact (a dropped tool) at the junction of the root and intermediate sections: two sections crack at once"
    parameters = (
        Parameter("k_loss", "1", 0.0, 0.0, 0.9, "Fraction of k1 and of k2 lost after t_hit", neutral=0.0),
        Parameter("t_hit", "s", 6.0, 0.0, 1.0e4, "Instant of the impact"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        if t >= p[P.t_hit]:
            bus[B.s1] += p[P.k_loss] * p[P.k1] * x[X.delta1]
            bus[B.s2] += p[P.k_loss] * p[P.k2] * x[X.delta2]


class TipLossSettling(PhysicalEffect):
    """The tip section (3) cracks at t_on and the crack runs on for a few tenths of a second, slowing as it goes:
    loss(t) = k_loss·(1 − exp(−(t − t_on)/tau)) — steepest at the onset (a kink), settling exponentially."""

    name = "blind4_tip_loss_settling"
    description = "Section 3 stiffness lower by k_loss·(1 − exp(−(t − t_on)/tau)) from t_on (first-order settling)"
    origin = ("Crack started by an overload at t_on that runs on under the vibration and arrests as its driving "
              "force falls")
    parameters = (
        Parameter("k_loss", "1", 0.0, 0.0, 0.9, "Fraction of k3 lost once the crack has arrested", neutral=0.0),
        Parameter("t_on", "s", 8.0, 0.0, 1.0e4, "Instant the crack starts"),
        Parameter("tau", "s", 0.15, 1.0e-3, 1.0e3, "Time constant of the crack's run"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        if t > p[P.t_on]:
            s = 1.0 - math.exp(-(t - p[P.t_on]) / p[P.tau])
            bus[B.s3] += p[P.k_loss] * s * p[P.k3] * x[X.delta3]


class RootLossPartlyRecovered(PhysicalEffect):
    """The root section (1) loses k_loss of its stiffness at t_on (step); at t_back part of it comes back (step),
    leaving kept·k_loss lost: two steps of opposite sign, the second smaller."""

    name = "blind4_root_loss_partly_recovered"
    description = "Section 1 stiffness lower by k_loss from t_on, by kept·k_loss from t_back on (partial recovery)"
    origin = ("An overload opens a delamination at the root at t_on; when the clamp's preload re-seats the plies at "
              "t_back its faces close again and carry part of the load, the rest stays lost")
    parameters = (
        Parameter("k_loss", "1", 0.0, 0.0, 0.9, "Fraction of k1 lost between t_on and t_back", neutral=0.0),
        Parameter("t_on", "s", 4.5, 0.0, 1.0e4, "Instant of the loss"),
        Parameter("t_back", "s", 10.0, 0.0, 1.0e4, "Instant of the partial recovery"),
        Parameter("kept", "1", 0.4, 0.0, 1.0, "Share of the loss left after t_back"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        if t >= p[P.t_on]:
            share = p[P.kept] if t >= p[P.t_back] else 1.0
            bus[B.s1] += share * p[P.k_loss] * p[P.k1] * x[X.delta1]


# --- patches weak in one polarity -------------------------------------------------------------------------------------


class Patch3WeakBelowReverseDrive(PhysicalEffect):
    """The tip couple (3) loses weak_loss of its coupling while the drive is below a negative threshold
    (v_a < −v_th, sharp switch): the reverse field past −v_th partly back-switches the fatigued fibres' domains,
    reversibly; for v_a ≥ −v_th it is healthy."""

    name = "blind4_patch3_weak_reverse_drive"
    description = "Couple 3 couples less by weak_loss while v_a < −v_th (sharp, offset threshold in the drive)"
    origin = "Fatigued tip MFCs whose coercive field has dropped: a reverse drive past −v_th depoles them for a while"
    parameters = (
        Parameter("weak_loss", "1", 0.0, 0.0, 0.9, "Fraction of couple 3's coupling lost below −v_th", neutral=0.0),
        Parameter("v_th", "V", 100.0, 0.0, 1.0e3, "Reverse drive magnitude beyond which the couple is weak"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        if bus[B.va] < -p[P.v_th]:
            w = p[P.weak_loss]
            theta = p[P.k3] * p[P.d_ep]
            force = w * theta * bus[B.qh3] / p[P.C_ep]
            bus[B.s3] -= force
            bus[B.p_piezo] -= force * x[X.ddelta3]
            dx[X.q3] += w * theta * x[X.ddelta3]


class Patch1FadesWithPositiveVoltage(PhysicalEffect):
    """The root couple (1) loses coupling gradually as its own voltage rises on the positive side: the lost share
    grows linearly from 0 at v_c1 = 0 to weak_loss at v_c1 = v_full and stays there above; negative voltage is
    healthy. (A share of a smooth range, not a switch.)"""

    name = "blind4_patch1_fades_positive"
    description = "Couple 1 couples less by weak_loss·clip(v_c1/v_full, 0, 1) (gradual over 0 … v_full, positive only)"
    origin = ("Root MFCs with a cracked interdigitated electrode that a positive field pries open progressively: "
              "more fingers lose contact the higher the positive voltage")
    parameters = (
        Parameter("weak_loss", "1", 0.0, 0.0, 0.9, "Fraction of couple 1's coupling lost at v_c1 ≥ v_full",
                  neutral=0.0),
        Parameter("v_full", "V", 250.0, 1.0e-3, 1.5e3, "Patch voltage at which the whole loss is reached"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        w = p[P.weak_loss] * min(1.0, max(0.0, bus[B.vc1] / p[P.v_full]))
        theta = p[P.k1] * p[P.d_ep]
        force = w * theta * bus[B.qh1] / p[P.C_ep]
        bus[B.s1] -= force
        bus[B.p_piezo] -= force * x[X.ddelta1]
        dx[X.q1] += w * theta * x[X.ddelta1]


class Patch2AreaLostNegative(PhysicalEffect):
    """Couple 2 loses a share g = area_loss·½(1 − tanh(v_c2/edge_v)) of its active electrode area while its own
    voltage is negative: its capacitance falls to (1 − g) C_ep, so the capacitor's voltage is q2/((1 − g) C_ep) and
    the current through R_ep falls by g·v_c2/((1 − g) R_ep); its coupling θ2 falls to (1 − g) θ2 (back-coupling
    current lower by g θ2 δ̇2). The force per unit charge is unchanged; per volt of drive it is (1 − g) lower."""

    name = "blind4_patch2_area_lost_negative"
    description = "Couple 2's authority and capacitance lower by area_loss while v_c2 < 0 (smooth edge over edge_v)"
    origin = ("Electrode of the intermediate MFCs partly lifted from the fibres: a negative voltage pulls it off "
              "(electrostatic and piezo strain of opposite sign), so a part of the patch is disconnected")
    parameters = (
        Parameter("area_loss", "1", 0.0, 0.0, 0.9, "Share of couple 2's active area lost for v_c2 < 0", neutral=0.0),
        Parameter("edge_v", "V", 15.0, 1.0e-3, 1.0e3, "Width of the switch in v_c2"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        g = p[P.area_loss] * 0.5 * (1.0 - math.tanh(bus[B.vc2] / p[P.edge_v]))
        di = -g * bus[B.vc2] / ((1.0 - g) * p[P.R_ep])
        bus[B.ir2] += di
        dx[X.q2] += di + g * p[P.k2] * p[P.d_ep] * x[X.ddelta2]


class Patch3SwitchesBelowAndStays(PhysicalEffect):
    """The tip couple (3) has an imprinted, fatigued poling: driving its own voltage below −v_sw switches a share of
    its domains (switched share s → 1 with time constant tau_sw), and they stay switched until the voltage rises
    above +v_sw, which re-poles them (s → 0). Between the two the share holds: a polarity weakness with memory,
    the couple coupling less by weak_loss·s."""

    name = "blind4_patch3_switch_latch"
    description = "Couple 3 couples less by weak_loss·s; s → 1 while v_c3 < −v_sw, → 0 while v_c3 > v_sw, else held"
    origin = ("Ferroelectric domain switching of the tip MFCs: an imprinted, fatigued PZT switches at a low reverse "
              "field and is re-poled only by a forward field of similar size (a butterfly loop)")
    parameters = (
        Parameter("weak_loss", "1", 0.0, 0.0, 0.9, "Fraction of couple 3's coupling lost when switched", neutral=0.0),
        Parameter("v_sw", "V", 150.0, 0.0, 1.0e3, "Voltage magnitude that switches (−) and re-poles (+) the domains"),
        Parameter("tau_sw", "s", 5.0e-3, 1.0e-5, 10.0, "Time constant of the switching"),
    )
    states = (StateSpec("switched3", "1", 1.0, 0.0),)

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        s = x[X.switched3]
        v = bus[B.vc3]
        if v < -p[P.v_sw]:
            dx[X.switched3] = (1.0 - s) / p[P.tau_sw]
        elif v > p[P.v_sw]:
            dx[X.switched3] = -s / p[P.tau_sw]
        else:
            dx[X.switched3] = 0.0
        w = p[P.weak_loss] * s
        theta = p[P.k3] * p[P.d_ep]
        force = w * theta * bus[B.qh3] / p[P.C_ep]
        bus[B.s3] -= force
        bus[B.p_piezo] -= force * x[X.ddelta3]
        dx[X.q3] += w * theta * x[X.ddelta3]


# --- the set ----------------------------------------------------------------------------------------------------------

#: a one-sided stiffness switched at an offset (the verdict may write the switching point, "δ2 < −0.4 mm")
OFFSET_CRACK: tuple[str, ...] = (*CRACK, "< −", "< -", "> −", "> -", "beyond", "past", "offset", "gap", "closed",
                                 "closes", "saturat")
#: a polarity switched at a threshold of the drive (the verdict may write "v_a < −100 V")
SIGNED: tuple[str, ...] = (*POLARITY, "< −", "< -", "below", "one-sided")

#: label → (class, truth values, word groups, timing). Above each case: its size_sigma (case_record, 2 µm, seed 1)
#: on the 15 s sweep, MBIT.a (20 s) and MBIT.b (3 s), measured 2026-11-28 06:40–06:50 UTC; a 0.0 on MBIT.b is a
#: damage its one-way step never reaches (the other sign), so that record cannot show it.
BLIND4: dict[str, tuple[type[PhysicalEffect], dict[str, float], Words, Timing]] = {
    # cracks that open on one side
    # size_sigma sweep 334, MBIT.a 125, MBIT.b 0.0 (the step never bends section 2 down past −0.4 mm)
    "mid_crack_past_offset": (MidCrackPastOffset, {"crack_loss": 0.30, "d_open": 4.0e-4},
                              (section(2), OFFSET_CRACK), None),
    # size_sigma sweep 177, MBIT.a 137, MBIT.b 0.3 (δ1 stays ≥ 0 on the step: the crack never opens)
    "root_crack_rubs": (RootCrackRubsWhileOpen, {"crack_loss": 0.25, "edge_width": 1.5e-4, "c_gain": 2.0},
                        (section(1), CRACK), None),
    # size_sigma sweep 269, MBIT.a 36, MBIT.b 46
    "tip_crack_closes_partly": (TipCrackClosesPartly, {"crack_loss": 0.07, "closed_share": 0.4},
                                (section(3), CRACK), None),
    # size_sigma sweep 279, MBIT.a 197, MBIT.b 177
    "root_crack_open_at_rest": (RootCrackOpenAtRest, {"crack_loss": 0.30, "d_close": 2.5e-4},
                                (section(1), OFFSET_CRACK), None),
    # stiffness lost inside the record
    # size_sigma sweep 263, MBIT.a 61, MBIT.b 44
    "mid_accelerating_loss": (MidAcceleratingLoss, {"k_loss": 0.18, "t_start_frac": 0.30, "t_grow_frac": 0.60},
                              (section(2), STIFF), ("t_start", 1.5)),
    # size_sigma sweep 230, MBIT.a 66, MBIT.b 51
    "root_mid_loss_at_once": (RootMidLossAtOnce, {"k_loss": 0.07, "t_hit_frac": 0.45},
                              (section(1), section(2), STIFF), ("t_hit", 0.5)),
    # size_sigma sweep 324, MBIT.a 27, MBIT.b 17
    "tip_loss_settling": (TipLossSettling, {"k_loss": 0.06, "t_on_frac": 0.55, "tau": 0.15},
                          (section(3), STIFF), ("t_on", 0.5)),
    # size_sigma sweep 125, MBIT.a 136, MBIT.b 97
    "root_loss_partly_recovered": (RootLossPartlyRecovered,
                                   {"k_loss": 0.25, "t_on_frac": 0.30, "t_back_frac": 0.65, "kept": 0.4},
                                   (section(1), STIFF), ("t_on", 0.5)),
    # patches weak in one polarity
    # size_sigma sweep 91, MBIT.a 165, MBIT.b 0.0 (a positive step: the drive is never below −v_th)
    "patch3_weak_reverse_drive": (Patch3WeakBelowReverseDrive, {"weak_loss": 0.40, "v_th": 100.0},
                                  (patch_at(3), PATCH, SIGNED), None),
    # size_sigma sweep 98, MBIT.a 181, MBIT.b 161
    "patch1_fades_positive": (Patch1FadesWithPositiveVoltage, {"weak_loss": 0.40, "v_full": 250.0},
                              (patch_at(1), PATCH, POLARITY), None),
    # size_sigma sweep 118, MBIT.a 184, MBIT.b 0.0 (v_c2 ≥ 0 on the step)
    "patch2_area_lost_negative": (Patch2AreaLostNegative, {"area_loss": 0.35, "edge_v": 15.0},
                                  (patch_at(2), PATCH, POLARITY), None),
    # size_sigma sweep 101, MBIT.a 165, MBIT.b 0.0 (never driven below −v_sw: nothing switches)
    "patch3_switch_latch": (Patch3SwitchesBelowAndStays, {"weak_loss": 0.40, "v_sw": 150.0, "tau_sw": 5.0e-3},
                            (patch_at(3), PATCH, POLARITY), None),
}


def truth_values(label: str, duration_s: float) -> dict[str, float]:
    """The truth values of ``label`` for a record of ``duration_s``: a ``*_frac`` value becomes frac × duration_s
    under the name without the suffix."""
    from workbench_unseen_damage import values_at

    return values_at(BLIND4[label][1], duration_s)


def run_blind4(label: str, *, kind: str = "sweep", duration_s: float = 15.0, noise_m: float = 2e-6, seed: int = 1,
               workdir: str | None = None) -> dict[str, object]:
    from workbench_unseen_damage import run_set_case

    return run_set_case(BLIND4, label, kind=kind, duration_s=duration_s, noise_m=noise_m, seed=seed, workdir=workdir)
