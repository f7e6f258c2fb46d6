"""A third blind set of damage effects: twelve damages written from the plant's effect seam and the seed paper alone,
by someone who has not seen how the workbench discovers damage (nor the first two sets' discovery runs).

Three families of four, each varied in section, sign, sharpness, switching variable and time profile, none of them
a form of the first two sets:

* state-dependent stiffness or damping: a crack whose faces rub only while it is open (one-sided damping, no
  stiffness change), a root crack opened by the *neighbouring* section's bending, a tip crack whose closed side is
  stiffer than healthy (debris wedged in it), dry (Coulomb) friction of a delamination at the root;
* change mid-record: a damping rise at an instant, a patch couple that debonds at an instant, a linear ramp loss
  that stops, a fatigue loss that grows with the accumulated motion of the section (a history carried in the
  effect's own state). Instants are fractions of the record (``*_frac`` values, scaled by :func:`truth_values`);
* polarity / patch damage: a patch that couples *more* for one polarity of its own voltage, a patch depolarising
  progressively while it is driven against its poling (the reverse volt-seconds carried in a state), a patch that
  goes dead above a voltage magnitude, a patch whose charge leaks through a breakdown path in one polarity.

Section forces follow ``plant/effects/laminate.py``: ``bus[B.s_i]`` carries −k_i δ_i − c_i δ̇_i + θ_i q_hi/C_ep, so a
section that softens by Δk *adds* +Δk δ_i, one that stiffens adds −Δk δ_i, and extra damping adds −Δc δ̇_i. The
piezo force of couple i is θ_i q_hi / C_ep with θ_i = k_i d_ep (``plant/effects/piezo_coupling.py``), its
back-coupling current −θ_i δ̇_i: a couple that couples less by a fraction w takes back w of both (and of their power
in ``bus[B.p_piezo]``); one that couples more has w < 0. A patch's charge q_i is fed by R_ep from v_a
(``plant/effects/patch_rc.py``); a leak takes current out of q̇_i.

Every damage has one size parameter with ``neutral=0.0`` (healthy at 0). :data:`BLIND3` maps each label to (class,
truth values, word groups the verdict's first sentence must match, timing); :func:`run_blind3` runs one through the
one-command walk of ``workbench_unseen_damage.run_walk``.
"""

from __future__ import annotations

import math

from plant.effect import Parameter, PhysicalEffect, StateSpec

# --- state-dependent stiffness or damping -----------------------------------------------------------------------------


class MidCrackRubsWhileOpen(PhysicalEffect):
    """A crack in the intermediate section (2) whose rough faces rub on each other only while it is open (δ2 > 0):
    friction of the faces adds viscous-like damping c_rub on that side; the crack is short, so the stiffness is
    unchanged. Sharp switch at δ2 = 0."""

    name = "blind3_mid_crack_rubs"
    description = "Section 2 damping higher by c_rub only while δ2 > 0 (one-sided damping, stiffness unchanged)"
    origin = "Short crack with rough, mismatched faces: fretting dissipates energy while it is open, none when shut"
    parameters = (
        Parameter("c_rub", "N*s/m", 0.0, 0.0, 1.0, "Extra damping of section 2 while δ2 > 0", neutral=0.0),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        if x[X.delta2] > 0.0:
            bus[B.s2] -= p[P.c_rub] * x[X.ddelta2]


class RootCrackOpenedByMidBend(PhysicalEffect):
    """A crack at the junction of the root and intermediate sections (the end of the root patches, a ply drop)
    that lies in the root section but is opened by the bending of its neighbour: while section 2 bends down
    (δ2 < 0, smooth over a width) the root section loses a fraction of its stiffness."""

    name = "blind3_root_crack_on_mid_bend"
    description = "Section 1 stiffness lower by crack_loss while δ2 < 0 (switched by the neighbour, smooth edge)"
    origin = ("Crack at the stress concentration where the root patches end: its opening follows the curvature of "
              "the section outboard of it, not the root's own deflection")
    parameters = (
        Parameter("crack_loss", "1", 0.0, 0.0, 0.9, "Fraction of k1 lost while δ2 < 0", neutral=0.0),
        Parameter("edge_width", "m", 2.0e-4, 1.0e-6, 1.0e-2, "Deformation δ2 over which the crack closes"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        gate = 0.5 * (1.0 - math.tanh(x[X.delta2] / p[P.edge_width]))
        bus[B.s1] += p[P.crack_loss] * gate * p[P.k1] * x[X.delta1]


class TipCrackWedgedStiffer(PhysicalEffect):
    """A crack in the tip section (3) with fretting debris lodged between its faces: once the crack has closed by
    more than a gap (δ3 < −gap) the faces bear on the wedge and the section is *stiffer* than healthy, k3 higher by
    gain on the part beyond the gap (force continuous there); on the other side it is healthy."""

    name = "blind3_tip_crack_wedged"
    description = "Section 3 stiffer by contact_gain·k3 for δ3 < −gap (contact stiffening on the closed side)"
    origin = "Debris (fretting product, a resin chip) wedged in a closing crack: contact stiffening, a bilinear spring"
    parameters = (
        Parameter("contact_gain", "1", 0.0, 0.0, 5.0, "Stiffness added beyond the gap, as a fraction of k3",
                  neutral=0.0),
        Parameter("gap", "m", 3.0e-4, 0.0, 1.0e-2, "Closing δ3 at which the faces meet the debris"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        over = x[X.delta3] + p[P.gap]
        if over < 0.0:
            bus[B.s3] -= p[P.contact_gain] * p[P.k3] * over


class RootDelaminationDryFriction(PhysicalEffect):
    """A delamination at the root (section 1) whose faces slide on each other: dry (Coulomb) friction, a force of
    constant size f_fric opposing the section's deformation rate, −f_fric·tanh(δ̇1/v_edge) (regularised stick)."""

    name = "blind3_root_dry_friction"
    description = "Coulomb friction in section 1: force −f_fric·tanh(δ̇1/v_edge) (amplitude-dependent damping)"
    origin = ("Interlaminar crack near the clamp under the root patches: the laminae slide and rub under the "
              "shear of bending; the friction force does not grow with speed (dry friction)")
    parameters = (
        Parameter("f_fric", "N", 0.0, 0.0, 1.0, "Size of the friction force", neutral=0.0),
        Parameter("v_edge", "m/s", 2.0e-3, 1.0e-6, 1.0, "Rate δ̇1 over which the friction reverses"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        bus[B.s1] -= p[P.f_fric] * math.tanh(x[X.ddelta1] / p[P.v_edge])


# --- change mid-record ------------------------------------------------------------------------------------------------


class TipDampingRiseAtEvent(PhysicalEffect):
    """At t_event a delamination opens in the tip section (3) and its faces start rubbing: section 3's damping rises
    by dc at once and stays so (stiffness unchanged)."""

    name = "blind3_tip_damping_rise"
    description = "Section 3 damping higher by dc from t_event on (step)"
    origin = "Impact or overload during the test: a tip delamination whose faces dissipate energy by friction"
    parameters = (
        Parameter("dc", "N*s/m", 0.0, 0.0, 1.0, "Damping added to section 3 after t_event", neutral=0.0),
        Parameter("t_event", "s", 5.0, 0.0, 1.0e4, "Instant of the change"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        if t >= p[P.t_event]:
            bus[B.s3] -= p[P.dc] * x[X.ddelta3]


class RootPatchDebondAtEvent(PhysicalEffect):
    """The root patches (couple 1) partly debond at t_debond (the adhesive layer cracks under the high strain at
    the root): from then on the couple transfers a fraction debond_loss less strain — its force and its
    back-coupling current both drop (step)."""

    name = "blind3_patch1_debond"
    description = "Couple 1 couples less by debond_loss from t_debond on (sudden partial debond of patch 1)"
    origin = "Adhesive failure under the root patches: shear lag grows, the effective d_ep of the couple falls at once"
    parameters = (
        Parameter("debond_loss", "1", 0.0, 0.0, 0.9, "Fraction of couple 1's coupling lost after t_debond",
                  neutral=0.0),
        Parameter("t_debond", "s", 5.0, 0.0, 1.0e4, "Instant of the debond"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        if t >= p[P.t_debond]:
            w = p[P.debond_loss]
            theta = p[P.k1] * p[P.d_ep]
            force = w * theta * bus[B.qh1] / p[P.C_ep]
            bus[B.s1] -= force
            bus[B.p_piezo] -= force * x[X.ddelta1]
            dx[X.q1] += w * theta * x[X.ddelta1]


class MidRampLoss(PhysicalEffect):
    """The intermediate section (2) loses stiffness along a straight ramp of length t_span centred on t_mid and
    then stops: loss(t) = k_loss·clip((t − t_mid + t_span/2)/t_span, 0, 1) (a crack that grows steadily until it
    reaches a stiffener or a ply drop and arrests)."""

    name = "blind3_mid_ramp_loss"
    description = "Section 2 stiffness lower by k_loss along a linear ramp over t_span centred on t_mid, then constant"
    origin = "Matrix crack growing at a constant rate under the test's load, arrested at a ply drop"
    parameters = (
        Parameter("k_loss", "1", 0.0, 0.0, 0.9, "Fraction of k2 lost at the end of the ramp", neutral=0.0),
        Parameter("t_mid", "s", 5.0, 0.0, 1.0e4, "Instant of half the loss"),
        Parameter("t_span", "s", 3.0, 1.0e-3, 1.0e4, "Duration of the ramp"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        frac = min(1.0, max(0.0, (t - p[P.t_mid]) / p[P.t_span] + 0.5))
        bus[B.s2] += p[P.k_loss] * frac * p[P.k2] * x[X.delta2]


class RootFatigueWithTravel(PhysicalEffect):
    """Fatigue of the root section (1): its stiffness loss grows with the motion it has been through, the
    accumulated travel D = ∫|δ̇1| dt (a measure of the cycles times their amplitude), saturating:
    loss = k_loss·(1 − exp(−D/travel_ref)). The damage is history-dependent: large motion (a resonance) ages the
    section, slow small motion barely does."""

    name = "blind3_root_fatigue_travel"
    description = "Section 1 stiffness lower by k_loss·(1 − exp(−∫|δ̇1|dt / travel_ref)) (loss grows with motion)"
    origin = "Fatigue damage (matrix micro-cracking) accumulating with the cycles of bending at the root"
    parameters = (
        Parameter("k_loss", "1", 0.0, 0.0, 0.9, "Fraction of k1 lost once the fatigue saturates", neutral=0.0),
        Parameter("travel_ref", "m", 0.2, 1.0e-4, 1.0e3, "Accumulated travel of δ1 for 63 % of the loss"),
    )
    states = (StateSpec("travel1", "m", 0.1, 0.0),)

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        dx[X.travel1] = abs(x[X.ddelta1])
        loss = p[P.k_loss] * (1.0 - math.exp(-x[X.travel1] / p[P.travel_ref]))
        bus[B.s1] += loss * p[P.k1] * x[X.delta1]


# --- polarity / patch damage ------------------------------------------------------------------------------------------


class Patch1StrongerNegative(PhysicalEffect):
    """Couple 1 was partly re-poled the wrong way by an over-voltage event: its butterfly curve is now lopsided and
    it gives *more* strain per volt than healthy while its own voltage v_c1 is negative — coupling higher by gain
    there, ½(1 − tanh(v_c1/edge_v)), healthy for positive voltage."""

    name = "blind3_patch1_stronger_negative"
    description = "Couple 1 couples more by gain while its voltage v_c1 < 0 (smooth edge over edge_v)"
    origin = "Partial domain switching of the root MFCs after a reverse over-voltage: asymmetric strain per volt"
    parameters = (
        Parameter("gain", "1", 0.0, 0.0, 2.0, "Fraction of couple 1's coupling added for v_c1 < 0", neutral=0.0),
        Parameter("edge_v", "V", 20.0, 1.0e-3, 1.0e3, "Width of the switch in v_c1"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        g = p[P.gain] * 0.5 * (1.0 - math.tanh(bus[B.vc1] / p[P.edge_v]))
        theta = p[P.k1] * p[P.d_ep]
        force = g * theta * bus[B.qh1] / p[P.C_ep]
        bus[B.s1] += force
        bus[B.p_piezo] += force * x[X.ddelta1]
        dx[X.q1] -= g * theta * x[X.ddelta1]


class Patch2DepolesUnderReverseField(PhysicalEffect):
    """Couple 2 depolarises progressively while it is driven against its poling: the reverse volt-seconds beyond a
    threshold, A = ∫max(0, −v_c2 − v_th) dt, are carried in a state, and the couple's coupling falls by
    w_max·(1 − exp(−A/a_ref)) — for both polarities, once lost."""

    name = "blind3_patch2_depoling"
    description = "Couple 2 couples less by w_max·(1 − exp(−A/a_ref)), A the reverse volt-seconds beyond v_th"
    origin = ("MFC patches tolerate a limited field against their poling (−500 V); repeated reverse fields switch "
              "domains back and the remanent polarisation, and with it d_ep, decays")
    parameters = (
        Parameter("w_max", "1", 0.0, 0.0, 0.9, "Fraction of couple 2's coupling lost when fully depoled",
                  neutral=0.0),
        Parameter("v_th", "V", 100.0, 0.0, 1.0e3, "Reverse voltage below which nothing is lost"),
        Parameter("a_ref", "V*s", 500.0, 1.0e-3, 1.0e6, "Reverse volt-seconds for 63 % of the loss"),
    )
    states = (StateSpec("reverse_vs2", "V*s", 100.0, 0.0),)

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        dx[X.reverse_vs2] = max(0.0, -bus[B.vc2] - p[P.v_th])
        w = p[P.w_max] * (1.0 - math.exp(-x[X.reverse_vs2] / p[P.a_ref]))
        theta = p[P.k2] * p[P.d_ep]
        force = w * theta * bus[B.qh2] / p[P.C_ep]
        bus[B.s2] -= force
        bus[B.p_piezo] -= force * x[X.ddelta2]
        dx[X.q2] += w * theta * x[X.ddelta2]


class Patch3DeadAboveVoltage(PhysicalEffect):
    """Couple 3 (the tip patches) has cracked electrode fingers that arc over and lose contact when the field is
    high: above a voltage magnitude |v_c3| > v_dead (either polarity, sharp edge over edge_v) the couple loses most
    of its authority; below it it is healthy."""

    name = "blind3_patch3_dead_above_v"
    description = "Couple 3 couples less by dead_loss while |v_c3| > v_dead (threshold in magnitude, both polarities)"
    origin = "Electrode fingers cracked by fatigue of the tip MFCs: contact lost at high field, kept at low field"
    parameters = (
        Parameter("dead_loss", "1", 0.0, 0.0, 1.0, "Fraction of couple 3's coupling lost above v_dead", neutral=0.0),
        Parameter("v_dead", "V", 200.0, 0.0, 1.0e3, "Voltage magnitude above which the couple is dead"),
        Parameter("edge_v", "V", 10.0, 1.0e-3, 1.0e3, "Width of the switch in |v_c3|"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        gate = 0.5 * (1.0 + math.tanh((abs(bus[B.vc3]) - p[P.v_dead]) / p[P.edge_v]))
        w = p[P.dead_loss] * gate
        theta = p[P.k3] * p[P.d_ep]
        force = w * theta * bus[B.qh3] / p[P.C_ep]
        bus[B.s3] -= force
        bus[B.p_piezo] -= force * x[X.ddelta3]
        dx[X.q3] += w * theta * x[X.ddelta3]


class Patch2BreakdownLeakPositive(PhysicalEffect):
    """Couple 2 has a partial dielectric breakdown: a carbonised track across its electrodes with a rectifying
    contact conducts once the patch voltage exceeds +v_bd, draining its charge through a conductance g_leak — the
    patch voltage (and with it its force) is clipped for positive drive; negative drive is untouched."""

    name = "blind3_patch2_leak_positive"
    description = "Couple 2's charge leaks by g_leak·(v_c2 − v_bd) while v_c2 > v_bd (one-polarity breakdown path)"
    origin = "Arc tracking between interdigitated electrodes of an MFC after an over-voltage: a one-way leakage path"
    parameters = (
        Parameter("g_leak", "S", 0.0, 0.0, 1.0, "Conductance of the breakdown path once it conducts", neutral=0.0),
        Parameter("v_bd", "V", 150.0, 0.0, 1.5e3, "Patch voltage above which the path conducts"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        over = bus[B.vc2] - p[P.v_bd]
        if over > 0.0:
            dx[X.q2] -= p[P.g_leak] * over


# --- the set ----------------------------------------------------------------------------------------------------------

Words = tuple[tuple[str, ...], ...]
Timing = tuple[str, float] | None

CRACK: tuple[str, ...] = ("crack", "one-sided", "one side", "breathing", "bilinear", "only while", "only for",
                          "only when", "opens", "> 0", "< 0", "sign of")
#: a one-sided stiffness that can also be a stiffening (contact on the closed side)
CONTACT: tuple[str, ...] = (*CRACK, "contact", "stiffen", "stiffer", "gap", "closed", "closes", "closing", "< −",
                             "< -", "wedge")
STIFF: tuple[str, ...] = ("stiff", "softer", "k1", "k2", "k3")
DAMPING: tuple[str, ...] = ("damp", "c1", "c2", "c3", "friction", "dissipat", "rub")
PATCH: tuple[str, ...] = ("d_ep", "authority", "coupling", "piezo", "patch", "debond")
POLARITY: tuple[str, ...] = ("negative", "positive", "polarity", "'s sign", "sign of", "polaris", "> 0", "< 0",
                             "reverse", "forward")
THRESHOLD: tuple[str, ...] = ("saturat", "amplitude", "magnitude", "|v", "large drive", "high voltage",
                              "high drive", "above", "threshold", "exceed", "beyond")


def section(i: int) -> tuple[str, ...]:
    return (f"section {i}", f"k{i}", f"c{i}")


def patch_at(i: int) -> tuple[str, ...]:
    return (f"patch {i}", f"section {i}", f"couple {i}")


BLIND3: dict[str, tuple[type[PhysicalEffect], dict[str, float], Words, Timing]] = {
    # state-dependent stiffness or damping
    "mid_crack_rubs": (MidCrackRubsWhileOpen, {"c_rub": 0.03}, (section(2), DAMPING), None),
    "root_crack_on_mid_bend": (RootCrackOpenedByMidBend, {"crack_loss": 0.30, "edge_width": 2.0e-4},
                               (section(1), CRACK), None),
    "tip_crack_wedged": (TipCrackWedgedStiffer, {"contact_gain": 0.40, "gap": 3.0e-4}, (section(3), CONTACT), None),
    "root_dry_friction": (RootDelaminationDryFriction, {"f_fric": 0.01, "v_edge": 2.0e-3},
                          (section(1), DAMPING), None),
    # change mid-record
    "tip_damping_rise": (TipDampingRiseAtEvent, {"dc": 0.0125, "t_event_frac": 0.55}, (section(3), DAMPING),
                         ("t_event", 1.0)),
    "patch1_debond": (RootPatchDebondAtEvent, {"debond_loss": 0.35, "t_debond_frac": 0.40}, (patch_at(1), PATCH),
                      ("t_debond", 0.75)),
    "mid_ramp_loss": (MidRampLoss, {"k_loss": 0.30, "t_mid_frac": 0.50, "t_span_frac": 0.20},
                      (section(2), STIFF), ("t_mid", 1.5)),
    "root_fatigue_travel": (RootFatigueWithTravel, {"k_loss": 0.30, "travel_ref": 0.2}, (section(1), STIFF), None),
    # polarity / patch damage
    "patch1_stronger_negative": (Patch1StrongerNegative, {"gain": 0.30, "edge_v": 20.0},
                                 (patch_at(1), PATCH, POLARITY), None),
    "patch2_depoling": (Patch2DepolesUnderReverseField, {"w_max": 0.40, "v_th": 100.0, "a_ref": 500.0},
                        (patch_at(2), PATCH), None),
    "patch3_dead_above_v": (Patch3DeadAboveVoltage, {"dead_loss": 0.60, "v_dead": 200.0, "edge_v": 10.0},
                            (patch_at(3), PATCH, THRESHOLD), None),
    "patch2_leak_positive": (Patch2BreakdownLeakPositive, {"g_leak": 1.0e-3, "v_bd": 150.0},
                             (patch_at(2), PATCH, POLARITY), None),
}


def truth_values(label: str, duration_s: float) -> dict[str, float]:
    """The truth values of ``label`` for a record of ``duration_s``: a ``*_frac`` value becomes frac × duration_s
    under the name without the suffix."""
    from workbench_unseen_damage import values_at

    return values_at(BLIND3[label][1], duration_s)


def run_blind3(label: str, *, kind: str = "sweep", duration_s: float = 15.0, noise_m: float = 2e-6, seed: int = 1,
               workdir: str | None = None) -> dict[str, object]:
    from workbench_unseen_damage import run_set_case

    return run_set_case(BLIND3, label, kind=kind, duration_s=duration_s, noise_m=noise_m, seed=seed, workdir=workdir)
