"""A second blind set of damage effects: twelve damages written from the plant's effect seam and the seed paper alone,
by someone who has not seen how the workbench discovers damage.

Three families of four, each varied in section, sign, sharpness, switching variable and time profile:

* one-sided cracks (bilinear stiffness): a section whose stiffness depends on the sign or size of a deformation;
* stiffness lost mid-record: the instants are fractions of the record (``*_frac`` values, scaled by
  :func:`truth_values`);
* weak polarity / patch damage: patches that couple less for one drive polarity, on the sign of their own charge, or
  that saturate.

Section forces follow ``plant/effects/laminate.py``: ``bus[B.s_i]`` carries −k_i δ_i − c_i δ̇_i + θ_i q_hi/C_ep, so a
section that softens by Δk *adds* +Δk δ_i and extra damping adds −Δc δ̇_i. The piezo force of couple i is
θ_i q_hi / C_ep with θ_i = k_i d_ep (``plant/effects/piezo_coupling.py``), its back-coupling current −θ_i δ̇_i: a
couple that couples less by a fraction w takes back w of both (and of their power in ``bus[B.p_piezo]``).

Every damage has one size parameter with ``neutral=0.0`` (healthy at 0). :data:`BLIND2` maps each label to (class,
truth values, word groups the verdict's first sentence must match, timing); :func:`run_blind2` runs one through the
one-command walk of ``workbench_unseen_damage.run_walk``.
"""

from __future__ import annotations

import math

from plant.effect import Parameter, PhysicalEffect
from plant.layout import B_QH, B_S, B_VC, P_K, X_DDELTA, X_Q

# --- one-sided cracks ------------------------------------------------------------------------------------------------


class RootCrackOpensDown(PhysicalEffect):
    """A fatigue crack at the root (section 1) on the face that is in tension when δ1 < 0: it opens, and the
    section loses a fraction of its stiffness, only while δ1 < 0; closed, the faces bear and the section is whole.
    Sharp closure (bilinear spring, kink at δ1 = 0)."""

    name = "blind2_root_crack_down"
    description = "Breathing crack at the root: k1 lower by crack_loss while δ1 < 0 (sharp bilinear)"
    origin = ("Transverse matrix crack near the clamp, where the bending moment is largest; it opens under tension of "
              "its face and closes under compression")
    parameters = (
        Parameter("crack_loss", "1", 0.0, 0.0, 0.9, "Fraction of k1 lost while the crack is open (δ1 < 0)",
                  neutral=0.0),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        d1 = x[X.delta1]
        if d1 < 0.0:
            bus[B.s1] += p[P.crack_loss] * p[P.k1] * d1


class MidCrackOpensUpSmooth(PhysicalEffect):
    """A crack in the intermediate section (2) opening for δ2 > 0, with rough faces that come into contact
    progressively: the lost stiffness fades in over a closure width w, loss·k2·½(1 + tanh(δ2/w))."""

    name = "blind2_mid_crack_up_smooth"
    description = "Breathing crack in section 2: k2 lower by crack_loss for δ2 > 0, smooth closure over closure_width"
    origin = "Crack with rough, mismatched faces (fibre bridging): contact builds up over a finite closing displacement"
    parameters = (
        Parameter("crack_loss", "1", 0.0, 0.0, 0.9, "Fraction of k2 lost when the crack is fully open (δ2 > 0)",
                  neutral=0.0),
        Parameter("closure_width", "m", 3.0e-4, 1.0e-6, 1.0e-2, "Deformation δ2 over which the faces close"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        d2 = x[X.delta2]
        gate = 0.5 * (1.0 + math.tanh(d2 / p[P.closure_width]))
        bus[B.s2] += p[P.crack_loss] * p[P.k2] * d2 * gate


class TipCrackPastGapDamped(PhysicalEffect):
    """A crack in the tip section (3) that stays shut until δ3 exceeds a gap g (residual compressive stress or a
    wedge of debris holds it closed); beyond the gap the section is softer, k3 lower by loss on the part beyond g
    (force continuous at g), and the rubbing faces add damping c_open while it is open."""

    name = "blind2_tip_crack_gap_damped"
    description = "Crack in section 3 opening only for δ3 > gap: k3 lower by crack_loss beyond the gap, +c_open"
    origin = "Crack held shut by residual stress up to an opening threshold; friction of its faces while open"
    parameters = (
        Parameter("crack_loss", "1", 0.0, 0.0, 0.9, "Fraction of k3 lost beyond the gap", neutral=0.0),
        Parameter("gap", "m", 6.0e-4, 0.0, 1.0e-2, "Deformation δ3 at which the crack starts to open"),
        Parameter("c_open", "N*s/m", 0.0, 0.0, 1.0, "Extra damping of section 3 while the crack is open",
                  neutral=0.0),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        over = x[X.delta3] - p[P.gap]
        if over > 0.0:
            bus[B.s3] += p[P.crack_loss] * p[P.k3] * over - p[P.c_open] * x[X.ddelta3]


class DelaminationRootMidOnZ2(PhysicalEffect):
    """A delamination spanning sections 1 and 2: it opens when the inboard half of the beam bends down (its
    mid-span deflection z2 < 0, smooth over a width), and then both sections lose the same fraction of stiffness."""

    name = "blind2_delam_root_mid_z2"
    description = "Delamination over sections 1-2: k1 and k2 lower by crack_loss while z2 < 0 (smooth edge)"
    origin = "Interlaminar crack spanning the root and middle thirds; it opens with the bending of that whole span"
    parameters = (
        Parameter("crack_loss", "1", 0.0, 0.0, 0.9, "Fraction of k1 and k2 lost while open (z2 < 0)", neutral=0.0),
        Parameter("edge_width", "m", 1.0e-4, 1.0e-6, 1.0e-2, "Deflection z2 over which the faces close"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        gate = 0.5 * (1.0 - math.tanh(bus[B.z2] / p[P.edge_width]))
        w = p[P.crack_loss] * gate
        bus[B.s1] += w * p[P.k1] * x[X.delta1]
        bus[B.s2] += w * p[P.k2] * x[X.delta2]


# --- stiffness lost mid-record ----------------------------------------------------------------------------------------


class TipStepLoss(PhysicalEffect):
    """The tip section (3) loses a fraction of its stiffness at once at t_loss (a fibre bundle snaps) and stays so."""

    name = "blind2_tip_step_loss"
    description = "Section 3 stiffness lower by k_loss from t_loss on (step)"
    origin = "Sudden fibre or ply failure in the tip third (an overload or an impact during the test)"
    parameters = (
        Parameter("k_loss", "1", 0.0, 0.0, 0.9, "Fraction of k3 lost after t_loss", neutral=0.0),
        Parameter("t_loss", "s", 5.0, 0.0, 1.0e4, "Instant of the loss"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        if t >= p[P.t_loss]:
            bus[B.s3] += p[P.k_loss] * p[P.k3] * x[X.delta3]


class RootSCurveLoss(PhysicalEffect):
    """The root section (1) softens over a finite time: loss·½(1 + tanh((t − t_mid)/tau)) — a damage that grows
    slowly, runs away, and saturates (a delamination front crossing the section)."""

    name = "blind2_root_s_curve"
    description = "Section 1 stiffness lower by k_loss along an S-curve centred on t_mid, time scale tau"
    origin = "Delamination growth under the test's own cycling: slow start, fast growth, arrest at a ply drop"
    parameters = (
        Parameter("k_loss", "1", 0.0, 0.0, 0.9, "Fraction of k1 lost once the change is complete", neutral=0.0),
        Parameter("t_mid", "s", 5.0, 0.0, 1.0e4, "Instant of half the loss"),
        Parameter("tau", "s", 0.5, 1.0e-3, 1.0e3, "Time scale of the change (10-90 % in 2.2 tau)"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        frac = 0.5 * (1.0 + math.tanh((t - p[P.t_mid]) / p[P.tau]))
        bus[B.s1] += p[P.k_loss] * frac * p[P.k1] * x[X.delta1]


class MidDropThenRecover(PhysicalEffect):
    """The intermediate section (2) loses stiffness at t_drop, then recovers part of it exponentially with time
    constant tau_recover: loss(t) = k_loss·(1 − recovered·(1 − exp(−(t − t_drop)/tau_recover)))."""

    name = "blind2_mid_drop_recover"
    description = "Section 2 stiffness lower by k_loss at t_drop, a share 'recovered' of it back with tau_recover"
    origin = ("An overload opens matrix cracks in the middle third; as the load cycles, the crack faces re-seat and "
              "the resin relaxes, closing part of them again")
    parameters = (
        Parameter("k_loss", "1", 0.0, 0.0, 0.9, "Fraction of k2 lost right after t_drop", neutral=0.0),
        Parameter("t_drop", "s", 5.0, 0.0, 1.0e4, "Instant of the loss"),
        Parameter("tau_recover", "s", 1.0, 1.0e-3, 1.0e3, "Time constant of the partial recovery"),
        Parameter("recovered", "1", 0.5, 0.0, 1.0, "Share of the loss that comes back in the end"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        if t >= p[P.t_drop]:
            back = p[P.recovered] * (1.0 - math.exp(-(t - p[P.t_drop]) / p[P.tau_recover]))
            bus[B.s2] += p[P.k_loss] * (1.0 - back) * p[P.k2] * x[X.delta2]


class MidSqrtGrowth(PhysicalEffect):
    """A crack in the intermediate section (2) that starts at t_start and grows like the square root of the time
    since: loss(t) = k_loss·min(1, √((t − t_start)/t_grow)) (k_loss reached after t_grow)."""

    name = "blind2_mid_sqrt_growth"
    description = "Section 2 stiffness lower by k_loss·√((t − t_start)/t_grow), from t_start on"
    origin = "Crack initiated at t_start, growing under the test's cycling with a decelerating (√t) rate"
    parameters = (
        Parameter("k_loss", "1", 0.0, 0.0, 0.9, "Fraction of k2 lost t_grow after the start", neutral=0.0),
        Parameter("t_start", "s", 3.0, 0.0, 1.0e4, "Instant the crack starts"),
        Parameter("t_grow", "s", 10.0, 1.0e-3, 1.0e4, "Time for the loss to reach k_loss"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        if t > p[P.t_start]:
            frac = min(1.0, math.sqrt((t - p[P.t_start]) / p[P.t_grow]))
            bus[B.s2] += p[P.k_loss] * frac * p[P.k2] * x[X.delta2]


# --- weak polarity / patch damage -------------------------------------------------------------------------------------


class Side1DepolesOnNegativeChannel(PhysicalEffect):
    """The side-1 patches (channel 1) are partly depolarised: while their own channel voltage v_ch1 is negative
    (a field against the poling), they lose authority, and every couple's coupling drops by a fraction w (sharp).
    With the drive's +100 V common mode this happens for v_a below −100 V."""

    name = "blind2_side1_depoled"
    description = "All couples couple less by weak_loss while the channel-1 voltage is negative (sharp switch)"
    origin = ("MFC patches tolerate only −500 V against their poling; patches aged by reverse fields lose remanent "
              "polarisation and respond weakly to negative fields")
    parameters = (
        Parameter("weak_loss", "1", 0.0, 0.0, 0.9, "Fraction of every couple's coupling lost while v_ch1 < 0",
                  neutral=0.0),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        if bus[B.v_ch1] < 0.0:
            w = p[P.weak_loss]
            for i in range(3):
                theta = p[P_K + i] * p[P.d_ep]
                force = w * theta * bus[B_QH + i] / p[P.C_ep]
                bus[B_S + i] -= force
                bus[B.p_piezo] -= force * x[X_DDELTA + i]
                dx[X_Q + i] += w * theta * x[X_DDELTA + i]


class Patch2WeakAbovePositiveDrive(PhysicalEffect):
    """Couple 2's bond line is cracked so that it transfers less strain when the patches are driven hard one way:
    its coupling drops by w once the drive v_a exceeds +v_switch (smooth over edge_v)."""

    name = "blind2_patch2_weak_positive"
    description = "Couple 2 couples less by weak_loss for v_a above v_switch (smooth edge over edge_v)"
    origin = "Partial debond of patch 2 that slips when the patch pulls the laminate in one direction past a load"
    parameters = (
        Parameter("weak_loss", "1", 0.0, 0.0, 0.9, "Fraction of couple 2's coupling lost above v_switch",
                  neutral=0.0),
        Parameter("v_switch", "V", 80.0, -1.0e3, 1.0e3, "Drive v_a above which the couple is weak"),
        Parameter("edge_v", "V", 15.0, 1.0e-3, 1.0e3, "Width of the switch in v_a"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        gate = 0.5 * (1.0 + math.tanh((bus[B.va] - p[P.v_switch]) / p[P.edge_v]))
        w = p[P.weak_loss] * gate
        theta = p[P.k2] * p[P.d_ep]
        force = w * theta * bus[B.qh2] / p[P.C_ep]
        bus[B.s2] -= force
        bus[B.p_piezo] -= force * x[X.ddelta2]
        dx[X.q2] += w * theta * x[X.ddelta2]


class Patch1WeakOnNegativeCharge(PhysicalEffect):
    """Couple 1 (the root patches) responds weakly when its own effective charge q_h1 is negative (its polarisation
    partly switched back): coupling lower by w·½(1 − tanh(q_h1/q_edge)). The charge's sign lags the drive through the
    patch R-C pole and the hysteresis."""

    name = "blind2_patch1_weak_negative_charge"
    description = "Couple 1 couples less by weak_loss while its charge q_h1 < 0 (smooth over q_edge)"
    origin = "Root patches partly depolarised by an earlier over-voltage: weak response to charge of one sign"
    parameters = (
        Parameter("weak_loss", "1", 0.0, 0.0, 0.9, "Fraction of couple 1's coupling lost for q_h1 < 0", neutral=0.0),
        Parameter("q_edge", "C", 2.0e-5, 1.0e-9, 1.0e-2, "Width of the switch in q_h1"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        qh = bus[B.qh1]
        w = p[P.weak_loss] * 0.5 * (1.0 - math.tanh(qh / p[P.q_edge]))
        theta = p[P.k1] * p[P.d_ep]
        force = w * theta * qh / p[P.C_ep]
        bus[B.s1] -= force
        bus[B.p_piezo] -= force * x[X.ddelta1]
        dx[X.q1] += w * theta * x[X.ddelta1]


class PatchesSaturate(PhysicalEffect):
    """Every patch's authority saturates with the voltage across it (cracked fibres and a worn electrode give less
    strain per volt at high fields): the coupling of couple i is scaled by 1/(1 + sat·(v_ci/v_ref)²), v_ci = q_i/C_ep
    its own voltage, v_ref = 500 V (the patches' rated reverse limit)."""

    name = "blind2_patches_saturate"
    description = "All couples' coupling scaled by 1/(1 + sat (v_ci/v_ref)²) (saturation with each patch's voltage)"
    origin = "MFC fibres cracked by fatigue: the strain per volt falls at high field, both polarities alike"
    parameters = (
        Parameter("sat", "1", 0.0, 0.0, 10.0, "Saturation strength: coupling lost at v_ref is sat/(1 + sat)",
                  neutral=0.0),
        Parameter("v_ref", "V", 500.0, 1.0, 1.0e4, "Voltage scale of the saturation"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        for i in range(3):
            u = bus[B_VC + i] / p[P.v_ref]
            su = p[P.sat] * u * u
            w = su / (1.0 + su)
            theta = p[P_K + i] * p[P.d_ep]
            force = w * theta * bus[B_QH + i] / p[P.C_ep]
            bus[B_S + i] -= force
            bus[B.p_piezo] -= force * x[X_DDELTA + i]
            dx[X_Q + i] += w * theta * x[X_DDELTA + i]


# --- the set ----------------------------------------------------------------------------------------------------------

Words = tuple[tuple[str, ...], ...]
Timing = tuple[str, float] | None

CRACK: tuple[str, ...] = ("crack", "one-sided", "one side", "breathing", "bilinear", "only while", "only for",
                          "only when", "opens", "> 0", "< 0", "sign of")
STIFF: tuple[str, ...] = ("stiff", "softer", "k1", "k2", "k3")
PATCH: tuple[str, ...] = ("d_ep", "authority", "coupling", "piezo", "patch")
POLARITY: tuple[str, ...] = ("negative", "positive", "polarity", "'s sign", "sign of", "polaris")
SATURATION: tuple[str, ...] = ("saturat", "amplitude", "magnitude", "|v", "large drive", "high voltage", "high drive")


def section(i: int) -> tuple[str, ...]:
    return (f"section {i}", f"k{i}")


def patch_at(i: int) -> tuple[str, ...]:
    return (f"patch {i}", f"section {i}", f"couple {i}")


BLIND2: dict[str, tuple[type[PhysicalEffect], dict[str, float], Words, Timing]] = {
    # one-sided cracks
    "root_crack_down": (RootCrackOpensDown, {"crack_loss": 0.30}, (section(1), CRACK), None),
    "mid_crack_up_smooth": (MidCrackOpensUpSmooth, {"crack_loss": 0.30, "closure_width": 3.0e-4},
                            (section(2), CRACK), None),
    "tip_crack_gap_damped": (TipCrackPastGapDamped, {"crack_loss": 0.35, "gap": 6.0e-4, "c_open": 0.03},
                             (section(3), CRACK), None),
    "delam_root_mid_z2": (DelaminationRootMidOnZ2, {"crack_loss": 0.20, "edge_width": 1.0e-4},
                          (section(1) + section(2), CRACK), None),
    # stiffness lost mid-record
    "tip_step_loss": (TipStepLoss, {"k_loss": 0.25, "t_loss_frac": 0.45}, (section(3), STIFF), ("t_loss", 0.75)),
    "root_s_curve": (RootSCurveLoss, {"k_loss": 0.30, "t_mid_frac": 0.55, "tau_frac": 0.04},
                     (section(1), STIFF), ("t_mid", 1.5)),
    "mid_drop_recover": (MidDropThenRecover,
                         {"k_loss": 0.35, "t_drop_frac": 0.30, "tau_recover_frac": 0.12, "recovered": 0.5},
                         (section(2), STIFF), ("t_drop", 0.75)),
    "mid_sqrt_growth": (MidSqrtGrowth, {"k_loss": 0.30, "t_start_frac": 0.25, "t_grow_frac": 0.75},
                        (section(2), STIFF), ("t_start", 2.0)),
    # weak polarity / patch damage
    "side1_depoled": (Side1DepolesOnNegativeChannel, {"weak_loss": 0.25}, (PATCH, POLARITY), None),
    "patch2_weak_positive": (Patch2WeakAbovePositiveDrive, {"weak_loss": 0.30, "v_switch": 80.0, "edge_v": 15.0},
                             (patch_at(2), PATCH, POLARITY), None),
    "patch1_weak_negative_charge": (Patch1WeakOnNegativeCharge, {"weak_loss": 0.30, "q_edge": 2.0e-5},
                                    (patch_at(1), PATCH, POLARITY), None),
    "patches_saturate": (PatchesSaturate, {"sat": 0.4, "v_ref": 500.0}, (PATCH, SATURATION), None),
}


def truth_values(label: str, duration_s: float) -> dict[str, float]:
    """The truth values of ``label`` for a record of ``duration_s``: a ``*_frac`` value becomes frac × duration_s
    under the name without the suffix."""
    from workbench_unseen_damage import values_at

    return values_at(BLIND2[label][1], duration_s)


def run_blind2(label: str, *, kind: str = "sweep", duration_s: float = 15.0, noise_m: float = 2e-6, seed: int = 1,
               workdir: str | None = None) -> dict[str, object]:
    from workbench_unseen_damage import run_set_case

    return run_set_case(BLIND2, label, kind=kind, duration_s=duration_s, noise_m=noise_m, seed=seed, workdir=workdir)
