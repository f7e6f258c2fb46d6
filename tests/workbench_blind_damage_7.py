"""A seventh blind set of damage effects: twelve damages an outside SHM / aerospace-maintenance engineer would write to
check a monitor, written from the plant's effect seam and the seed paper alone, by someone who has not seen how the
workbench discovers damage (nor the earlier sets' discovery runs); sets 2–6 and the unseen set were read only for
the API and so as not to repeat their exact forms.

Three families of four, varied in section, sign, size, edge, switching variable and timing across the set:

* cracks that open on one side: a root crack held shut by the clamp's preload that opens only once the root bends
  up past an offset (δ1 > d_pre, the lost stiffness on the part beyond, with a smooth softplus corner over the faces'
  roughness), an intermediate crack opened by its *outboard* neighbour's bending (section 2 softer while the tip
  section bends down, δ3 < 0), a tip crack open for δ3 > 0 (sharp) that loses stiffness *and* dissipates while open
  (a damping written as a share of the tip section's critical damping), an intermediate crack open for δ2 < 0 whose
  lost share grows with the square of the opening (quadratic edge, full at δ2 = −w_open);
* stiffness (or damping) lost inside the record: the root cracking in two unequal steps at two instants, the
  intermediate section losing stiffness along an exponential approach to a final loss (time constant 0.6 s), the tip
  section starting to lose stiffness at an instant and going on losing it at a steady rate until the record ends
  (never held), a delamination opening in the intermediate section at an instant whose faces then rub by dry
  (Coulomb) friction. Instants are fractions of the record (``*_frac`` values, scaled by :func:`truth_values` as
  sets 5 and 6 do); time constants are in seconds;
* patches weak in one polarity: the root couple weak while its own section bends down (the sign of the strain δ1,
  not of a voltage), the intermediate couple losing coupling above a voltage magnitude in both polarities (growing
  linearly past v_on: depolarisation and saturation at high field), the tip couple weak for positive voltage only
  from an instant mid-record (a polarity that goes weak during the test), the intermediate couple weak while its
  charge falls (the sign of its own current through R_ep, the opposite sense of set 5's charging case).

Section forces follow ``plant/effects/laminate.py``: ``bus[B.s_i]`` carries −k_i δ_i − c_i δ̇_i + θ_i q_hi/C_ep, so a
section that softens by Δk *adds* +Δk δ_i and extra damping adds −Δc δ̇_i (a friction force F adds −F·sign δ̇_i). The
piezo force of couple i is θ_i q_hi / C_ep with θ_i = k_i d_ep (``plant/effects/piezo_coupling.py``), its
back-coupling current −θ_i δ̇_i: a couple that couples less by a fraction w takes back w of both (and of their power
in ``bus[B.p_piezo]``). A patch's own voltage is v_ci = q_i/C_ep and the current into it through R_ep is
i_i = (v_a − v_ci)/R_ep (``plant/effects/patch_rc.py``); v_a is the amplifier's drive at its terminals.

Every damage has one size parameter with ``neutral=0.0`` (healthy at 0). :data:`BLIND7` maps each label to (class,
truth values, word groups the verdict's first sentence must match, timing); :func:`run_blind7` runs one through the
one-command walk of ``workbench_unseen_damage.run_walk``. The sizes quoted on each case are ``size_sigma`` of
``workbench.challenges.discovery.case_record`` at the truth values, 2 µm noise, seed 1, on the 15 s sweep, MBIT.a and
MBIT.b (measured 2026-11-29 while writing the set).
"""

from __future__ import annotations

import math

from workbench_blind_damage_3 import (
    CRACK,
    DAMPING,
    PATCH,
    POLARITY,
    STIFF,
    THRESHOLD,
    Timing,
    Words,
    patch_at,
    section,
)
from workbench_blind_damage_4 import OFFSET_CRACK
from workbench_blind_damage_5 import RATE_POLARITY

from plant.effect import Parameter, PhysicalEffect

# --- cracks that open on one side -------------------------------------------------------------------------------------


class RootCrackPastPreloadUp(PhysicalEffect):
    """A crack at the root (section 1) held shut by the clamp's preload: it starts to open only once the root bends
    up past d_pre (δ1 > d_pre > 0), and its rough faces part over w_edge. The section carries (1 − crack_loss)·k1 for
    the part of δ1 beyond d_pre — a continuous bilinear spring with a smooth (softplus) corner: the added force is
    crack_loss·k1·w_edge·ln(1 + exp((δ1 − d_pre)/w_edge)), ≈ crack_loss·k1·(δ1 − d_pre) well past the offset, ≈ 0 at
    and below rest."""

    name = "blind7_root_crack_past_preload_up"
    description = "Section 1 softer by crack_loss·k1 for the part of δ1 beyond +d_pre (offset opening, smooth corner)"
    origin = ("Fatigue crack at the clamp edge kept closed by the clamp plate's preload (a compressive stress on its "
              "face) until the root's upward bending overcomes it")
    parameters = (
        Parameter("crack_loss", "1", 0.0, 0.0, 0.9, "Fraction of k1 lost beyond the opening point", neutral=0.0),
        Parameter("d_pre", "m", 3.0e-4, 0.0, 1.0e-2, "Upward deflection δ1 at which the crack starts to open"),
        Parameter("w_edge", "m", 3.0e-5, 1.0e-8, 1.0e-3, "Deflection δ1 over which the faces part (the corner)"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        s = (x[X.delta1] - p[P.d_pre]) / p[P.w_edge]
        soft = s + math.log1p(math.exp(-s)) if s > 0.0 else math.log1p(math.exp(s))
        bus[B.s1] += p[P.crack_loss] * p[P.k1] * p[P.w_edge] * soft


class MidCrackOnTipBendDown(PhysicalEffect):
    """A crack at the outboard end of the intermediate section (2), at the ply drop where the tip patches begin,
    opened by the bending of its *outboard* neighbour: while the tip section bends down (δ3 < 0; tanh edge over
    edge of δ3) section 2 carries (1 − crack_loss)·k2. Section 2's own sign does not decide."""

    name = "blind7_mid_crack_on_tip_bend_down"
    description = "Section 2 softer by crack_loss·k2 while δ3 < 0 (switched by the outboard neighbour, tanh edge)"
    origin = ("Crack at the stress concentration where the tip patches start: its opening follows the rotation of "
              "the tip section hanging off it, not the intermediate section's own deflection")
    parameters = (
        Parameter("crack_loss", "1", 0.0, 0.0, 0.9, "Fraction of k2 lost while δ3 < 0", neutral=0.0),
        Parameter("edge", "m", 2.0e-5, 1.0e-8, 1.0e-3, "Deflection δ3 over which the crack switches"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        gate = 0.5 * (1.0 - math.tanh(x[X.delta3] / p[P.edge]))
        bus[B.s2] += gate * p[P.crack_loss] * p[P.k2] * x[X.delta2]


class TipCrackOpenUpLosesAndDamps(PhysicalEffect):
    """A crack in the tip section (3) open while it bends up (δ3 > 0, sharp switch): open, the section loses
    crack_loss·k3 of its spring, and its faces, sliding on each other, dissipate through a damping
    crack_loss·zeta_open·2√(k3 m3) — zeta_open of the tip section's critical damping per unit of loss. Shut
    (δ3 ≤ 0) the section is healthy: stiffness and damping switch together."""

    name = "blind7_tip_crack_open_up_damps"
    description = ("Section 3 softer by crack_loss·k3 and damping higher by crack_loss·zeta_open·2√(k3 m3) while "
                   "δ3 > 0 (open crack that loses and dissipates)")
    origin = ("Crack in the outer third under a peel ply: open, it carries no load across and its fibre-bridged faces "
              "rub; shut, the faces bear and stick")
    parameters = (
        Parameter("crack_loss", "1", 0.0, 0.0, 0.9, "Fraction of k3 lost while δ3 > 0", neutral=0.0),
        Parameter("zeta_open", "1", 0.3, 0.0, 5.0, "Damping of the open crack per unit loss, share of 2√(k3 m3)"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        if x[X.delta3] > 0.0:
            a = p[P.crack_loss]
            c_open = p[P.zeta_open] * 2.0 * math.sqrt(p[P.k3] * p[P.m3])
            bus[B.s3] += a * (p[P.k3] * x[X.delta3] - c_open * x[X.ddelta3])


class MidCrackOpensDownQuadratic(PhysicalEffect):
    """A crack in the intermediate section (2) open for δ2 < 0 whose faces separate progressively: the lost share of
    k2 grows with the square of the opening, crack_loss·min(1, (δ2/w_open)²) for δ2 < 0 — none at rest, the full
    crack_loss from δ2 = −w_open on; healthy for δ2 ≥ 0 (a quadratic, not a tanh, edge)."""

    name = "blind7_mid_crack_down_quadratic"
    description = "Section 2 softer by crack_loss·min(1, (δ2/w_open)²)·k2 while δ2 < 0 (quadratic opening edge)"
    origin = ("Crack with wavy, interlocking faces (fibre bridging): the load they carry falls off progressively as "
              "the downward bending pulls them apart, until they no longer touch")
    parameters = (
        Parameter("crack_loss", "1", 0.0, 0.0, 0.9, "Fraction of k2 lost with the crack fully open", neutral=0.0),
        Parameter("w_open", "m", 5.0e-4, 1.0e-7, 1.0e-2, "Downward deflection δ2 at which the crack is fully open"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        d = x[X.delta2]
        if d < 0.0:
            u = d / p[P.w_open]
            bus[B.s2] += min(1.0, u * u) * p[P.crack_loss] * p[P.k2] * d


# --- stiffness (or damping) lost inside the record --------------------------------------------------------------------


class RootLossInTwoSteps(PhysicalEffect):
    """The root section (1) cracks in two steps: at t_first it loses first_share·k_loss of k1 (the crack starts
    across part of the width), at the later t_second the crack runs on and the loss reaches k_loss (two unequal steps
    of one sign in one section)."""

    name = "blind7_root_loss_two_steps"
    description = "Section 1 stiffness lower by first_share·k_loss·k1 from t_first, by k_loss·k1 from t_second"
    origin = ("An overload starts a crack at the clamp edge; a later overload of the same test drives it on "
              "across the rest of the laminate's width")
    parameters = (
        Parameter("k_loss", "1", 0.0, 0.0, 0.9, "Fraction of k1 lost after t_second", neutral=0.0),
        Parameter("t_first", "s", 4.5, 0.0, 1.0e4, "Instant of the first step"),
        Parameter("t_second", "s", 10.0, 0.0, 1.0e4, "Instant of the second step"),
        Parameter("first_share", "1", 0.4, 0.0, 1.0, "Share of k_loss lost at the first step"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        if t >= p[P.t_first]:
            share = 1.0 if t >= p[P.t_second] else p[P.first_share]
            bus[B.s1] += share * p[P.k_loss] * p[P.k1] * x[X.delta1]


class MidLossExponentialApproach(PhysicalEffect):
    """The intermediate section (2) starts losing stiffness at t_on and approaches a final loss exponentially:
    loss(t) = k_loss·(1 − exp(−(t − t_on)/tau)), tau of a few tenths of a second — the steepest change at the onset,
    63 % of the loss after tau, settled after a few tau."""

    name = "blind7_mid_loss_exponential"
    description = "Section 2 stiffness lower by k_loss·(1 − exp(−(t − t_on)/tau))·k2 from t_on (exponential approach)"
    origin = ("A delamination released at t_on by an overload, spreading under the vibration between two "
              "stiffeners at a speed that falls as its front nears them")
    parameters = (
        Parameter("k_loss", "1", 0.0, 0.0, 0.9, "Fraction of k2 lost once the loss has settled", neutral=0.0),
        Parameter("t_on", "s", 6.0, 0.0, 1.0e4, "Instant the loss starts"),
        Parameter("tau", "s", 0.6, 1.0e-3, 1.0e3, "Time constant of the approach"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        if t > p[P.t_on]:
            s = 1.0 - math.exp(-(t - p[P.t_on]) / p[P.tau])
            bus[B.s2] += s * p[P.k_loss] * p[P.k2] * x[X.delta2]


class TipLossGrowsToEnd(PhysicalEffect):
    """The tip section (3) starts losing stiffness at t_start and goes on losing it at a steady rate until the record
    ends: loss(t) = min(0.9, loss_rate·(t − t_start)) for t > t_start — a straight growth that is never held inside
    the record (the crack is still running when the test stops)."""

    name = "blind7_tip_loss_grows_to_end"
    description = "Section 3 stiffness lower by loss_rate·(t − t_start)·k3 from t_start to the end (steady growth)"
    origin = ("A fatigue crack initiated in the outer third at t_start and growing at a constant rate under the "
              "test's own cycling (a Paris-law growth at a steady stress intensity)")
    parameters = (
        Parameter("loss_rate", "1/s", 0.0, 0.0, 1.0, "Fraction of k3 lost per second after t_start", neutral=0.0),
        Parameter("t_start", "s", 8.0, 0.0, 1.0e4, "Instant the loss starts"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        if t > p[P.t_start]:
            loss = min(0.9, p[P.loss_rate] * (t - p[P.t_start]))
            bus[B.s3] += loss * p[P.k3] * x[X.delta3]


class MidFrictionFromInstant(PhysicalEffect):
    """At t_delam a delamination opens in the intermediate section (2) and its faces start to slide on each other:
    from then on dry (Coulomb) friction, a force of constant size f_fric opposing the section's rate,
    −f_fric·tanh(δ̇2/v_edge) (regularised stick). Stiffness unchanged: only the damping rises, and it does not grow
    with speed."""

    name = "blind7_mid_friction_from_instant"
    description = "Section 2 dry friction −f_fric·tanh(δ̇2/v_edge) from t_delam on (delamination faces rubbing)"
    origin = ("Interlaminar crack in the intermediate section opened by an impact during the test: its faces are "
              "pressed together by the through-thickness stress and rub under the shear of bending")
    parameters = (
        Parameter("f_fric", "N", 0.0, 0.0, 1.0, "Size of the friction force after t_delam", neutral=0.0),
        Parameter("t_delam", "s", 11.0, 0.0, 1.0e4, "Instant the delamination opens"),
        Parameter("v_edge", "m/s", 2.0e-3, 1.0e-6, 1.0, "Rate δ̇2 over which the friction reverses"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        if t >= p[P.t_delam]:
            bus[B.s2] -= p[P.f_fric] * math.tanh(x[X.ddelta2] / p[P.v_edge])


# --- patches weak in one polarity -------------------------------------------------------------------------------------


class Patch1WeakWhileRootBendsDown(PhysicalEffect):
    """The root couple (1) couples less by weak_loss while its own section bends down (δ1 < 0; tanh edge over edge
    of δ1): a weakness in one polarity of the *strain*, not of a voltage. Force and back-coupling current both lower;
    healthy while the root bends up."""

    name = "blind7_patch1_weak_root_down"
    description = "Couple 1 couples less by weak_loss while δ1 < 0 (switched by the section's strain sign, tanh edge)"
    origin = ("Root MFCs debonded along their clamp-side edge: the root's downward bending peels the loose edge "
              "off the laminate and the patch transfers strain over a shorter length; upward bending presses it back")
    parameters = (
        Parameter("weak_loss", "1", 0.0, 0.0, 0.9, "Fraction of couple 1's coupling lost while δ1 < 0", neutral=0.0),
        Parameter("edge", "m", 2.0e-5, 1.0e-8, 1.0e-3, "Deflection δ1 over which the weakness switches"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        w = p[P.weak_loss] * 0.5 * (1.0 - math.tanh(x[X.delta1] / p[P.edge]))
        lost_theta = w * p[P.k1] * p[P.d_ep]
        f = lost_theta * bus[B.qh1] / p[P.C_ep]
        bus[B.s1] -= f
        bus[B.p_piezo] -= f * x[X.ddelta1]
        dx[X.q1] += lost_theta * x[X.ddelta1]


class Patch2WeakAboveMagnitude(PhysicalEffect):
    """The intermediate couple (2) loses coupling above a voltage magnitude, in both polarities: none while
    |v_c2| ≤ v_on, then a share growing linearly with the excess, weak_loss·min(1, (|v_c2| − v_on)/v_span) — the
    whole weak_loss from |v_c2| = v_on + v_span on."""

    name = "blind7_patch2_weak_above_magnitude"
    description = "Couple 2 couples less by weak_loss·clip((|v_c2| − v_on)/v_span, 0, 1) (high field, both signs)"
    origin = ("Fatigued intermediate MFCs: at high field of either sign their domains saturate (forward) or start "
              "to back-switch (reverse), and the strain per volt falls beyond a field magnitude")
    parameters = (
        Parameter("weak_loss", "1", 0.0, 0.0, 0.9, "Fraction of couple 2's coupling lost from v_on + v_span on",
                  neutral=0.0),
        Parameter("v_on", "V", 150.0, 0.0, 1.5e3, "Voltage magnitude above which coupling is lost"),
        Parameter("v_span", "V", 300.0, 1.0e-3, 1.5e3, "Voltage past v_on over which the whole loss is reached"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        excess = (abs(bus[B.vc2]) - p[P.v_on]) / p[P.v_span]
        w = p[P.weak_loss] * min(1.0, max(0.0, excess))
        lost_theta = w * p[P.k2] * p[P.d_ep]
        f = lost_theta * bus[B.qh2] / p[P.C_ep]
        bus[B.s2] -= f
        bus[B.p_piezo] -= f * x[X.ddelta2]
        dx[X.q2] += lost_theta * x[X.ddelta2]


class Patch3WeakPositiveFromInstant(PhysicalEffect):
    """The tip couple (3) is healthy until t_weak; from then on it couples less by weak_loss while its own voltage
    is positive (tanh edge over v_edge), healthy for negative voltage — a polarity that goes weak during the test."""

    name = "blind7_patch3_weak_positive_from_instant"
    description = "Couple 3 couples less by weak_loss while v_c3 > 0, from t_weak on (a polarity weak mid-record)"
    origin = ("An electrode finger of the tip MFCs cracks during the test; from then on the field of one polarity "
              "pulls the cracked finger off the fibres and a part of the patch is no longer driven")
    parameters = (
        Parameter("weak_loss", "1", 0.0, 0.0, 0.9, "Fraction of couple 3's coupling lost for v_c3 > 0 after t_weak",
                  neutral=0.0),
        Parameter("t_weak", "s", 6.0, 0.0, 1.0e4, "Instant the polarity goes weak"),
        Parameter("v_edge", "V", 10.0, 1.0e-3, 1.0e3, "Voltage over which the weakness switches"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        if t >= p[P.t_weak]:
            w = p[P.weak_loss] * 0.5 * (1.0 + math.tanh(bus[B.vc3] / p[P.v_edge]))
            lost_theta = w * p[P.k3] * p[P.d_ep]
            f = lost_theta * bus[B.qh3] / p[P.C_ep]
            bus[B.s3] -= f
            bus[B.p_piezo] -= f * x[X.ddelta3]
            dx[X.q3] += lost_theta * x[X.ddelta3]


class Patch2WeakWhileChargeFalls(PhysicalEffect):
    """The intermediate couple (2) couples less by weak_loss while its charge falls: while the current into it
    through R_ep, i_2 = (v_a − v_c2)/R_ep, is negative (gate ½(1 − tanh(i_2/i_edge))), healthy while it is positive.
    A weakness in one polarity of the patch's own current."""

    name = "blind7_patch2_weak_charge_falls"
    description = ("Couple 2 couples less by weak_loss while i_2 = (v_a − v_c2)/R_ep < 0 (its charge falling; "
                   "tanh edge over i_edge)")
    origin = ("Fatigued intermediate MFCs whose domain walls are pinned on the way back: the walls' share of the "
              "strain follows a rising charge but is lost while the charge falls")
    parameters = (
        Parameter("weak_loss", "1", 0.0, 0.0, 0.9, "Fraction of couple 2's coupling lost while i_2 < 0", neutral=0.0),
        Parameter("i_edge", "A", 5.0e-4, 1.0e-9, 1.0, "Current over which the weakness switches"),
    )

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        i2 = (bus[B.va] - bus[B.vc2]) / p[P.R_ep]
        w = p[P.weak_loss] * 0.5 * (1.0 - math.tanh(i2 / p[P.i_edge]))
        lost_theta = w * p[P.k2] * p[P.d_ep]
        f = lost_theta * bus[B.qh2] / p[P.C_ep]
        bus[B.s2] -= f
        bus[B.p_piezo] -= f * x[X.ddelta2]
        dx[X.q2] += lost_theta * x[X.ddelta2]


# --- the set ----------------------------------------------------------------------------------------------------------

#: label → (class, truth values, word groups, timing). Above each case: its size_sigma (case_record, 2 µm, seed 1)
#: on the 15 s sweep, MBIT.a (20 s) and MBIT.b (3 s), measured 2026-11-29 14:30–14:45 UTC; a 0.0 (or near it) on
#: MBIT.b is a damage its one-way positive step never reaches (the other sign), or one that starts after the step's
#: ringing has died out, so that record cannot show it.
BLIND7: dict[str, tuple[type[PhysicalEffect], dict[str, float], Words, Timing]] = {
    # cracks that open on one side
    # size_sigma sweep 112, MBIT.a 121, MBIT.b 93
    "root_crack_past_preload_up": (RootCrackPastPreloadUp, {"crack_loss": 0.25, "d_pre": 3.0e-4, "w_edge": 3.0e-5},
                                   (section(1), OFFSET_CRACK), None),
    # size_sigma sweep 267, MBIT.a 103, MBIT.b 10.5 (the step bends δ3 down only in its first overshoots)
    "mid_crack_on_tip_bend_down": (MidCrackOnTipBendDown, {"crack_loss": 0.20, "edge": 2.0e-5},
                                   (section(2), CRACK), None),
    # size_sigma sweep 323, MBIT.a 62, MBIT.b 73
    "tip_crack_open_up_damps": (TipCrackOpenUpLosesAndDamps, {"crack_loss": 0.12, "zeta_open": 0.3},
                                (section(3), CRACK), None),
    # size_sigma sweep 441, MBIT.a 176, MBIT.b 0.0 (δ2 ≥ −23 µm on the step: (δ2/w_open)² < 0.3 %)
    "mid_crack_down_quadratic": (MidCrackOpensDownQuadratic, {"crack_loss": 0.30, "w_open": 5.0e-4},
                                 (section(2), CRACK), None),
    # stiffness (or damping) lost inside the record
    # size_sigma sweep 247, MBIT.a 94, MBIT.b 71
    "root_loss_two_steps": (RootLossInTwoSteps,
                            {"k_loss": 0.20, "t_first_frac": 0.30, "t_second_frac": 0.65, "first_share": 0.4},
                            (section(1), STIFF), ("t_first", 0.5)),
    # size_sigma sweep 374, MBIT.a 78, MBIT.b 43
    "mid_loss_exponential": (MidLossExponentialApproach, {"k_loss": 0.15, "t_on_frac": 0.40, "tau": 0.6},
                             (section(2), STIFF), ("t_on", 0.5)),
    # size_sigma sweep 357, MBIT.a 47, MBIT.b 4.7 (only 1.35 s of growth, 2.7 % of k3 at the end, after the ringing)
    "tip_loss_grows_to_end": (TipLossGrowsToEnd, {"loss_rate": 0.02, "t_start_frac": 0.55},
                              (section(3), STIFF), ("t_start", 1.5)),
    # size_sigma sweep 57, MBIT.a 4.3 (0.1 Hz: a hysteresis of 6 mN on a slow bend, in the last 5 s only), MBIT.b
    # 0.01 (the step's ringing has died out by t_delam = 2.25 s: no motion left to rub)
    "mid_friction_from_instant": (MidFrictionFromInstant, {"f_fric": 0.006, "t_delam_frac": 0.75, "v_edge": 2.0e-3},
                                  (section(2), DAMPING), ("t_delam", 0.5)),
    # patches weak in one polarity
    # size_sigma sweep 106, MBIT.a 144, MBIT.b 0.2 (δ1 ≥ 0 on the step but for the tanh edge)
    "patch1_weak_root_down": (Patch1WeakWhileRootBendsDown, {"weak_loss": 0.35, "edge": 2.0e-5},
                              (patch_at(1), PATCH, POLARITY), None),
    # size_sigma sweep 58 (300 V reaches only half of the loss), MBIT.a 290, MBIT.b 100
    "patch2_weak_above_magnitude": (Patch2WeakAboveMagnitude, {"weak_loss": 0.50, "v_on": 150.0, "v_span": 300.0},
                                    (patch_at(2), PATCH, THRESHOLD), None),
    # size_sigma sweep 58, MBIT.a 96, MBIT.b 104
    "patch3_weak_positive_from_instant": (Patch3WeakPositiveFromInstant,
                                          {"weak_loss": 0.30, "t_weak_frac": 0.40, "v_edge": 10.0},
                                          (patch_at(3), PATCH, POLARITY), ("t_weak", 0.75)),
    # size_sigma sweep 118, MBIT.a 125, MBIT.b 59
    "patch2_weak_charge_falls": (Patch2WeakWhileChargeFalls, {"weak_loss": 0.30, "i_edge": 5.0e-4},
                                 (patch_at(2), PATCH, RATE_POLARITY), None),
}


def truth_values(label: str, duration_s: float) -> dict[str, float]:
    """The truth values of ``label`` for a record of ``duration_s``: a ``*_frac`` value becomes frac × duration_s
    under the name without the suffix."""
    from workbench_unseen_damage import values_at

    return values_at(BLIND7[label][1], duration_s)


def run_blind7(label: str, *, kind: str = "sweep", duration_s: float = 15.0, noise_m: float = 2e-6, seed: int = 1,
               workdir: str | None = None) -> dict[str, object]:
    from workbench_unseen_damage import run_set_case

    return run_set_case(BLIND7, label, kind=kind, duration_s=duration_s, noise_m=noise_m, seed=seed, workdir=workdir)
