"""Damage forms of ``shm discover``'s dictionary: a core parameter's own contribution to the equations switched by
a *gate* — the conditions under which real damage acts.

A damage term is ``c × contribution(parameter) × gate``, where ``c`` is the parameter's relative change (1; for a
ramp, 1/s) while the gate is open. Contributions (what the parameter adds to the equations, :data:`CONTRIBUTIONS`):

=============  ==================================================================================================
``k`` (i)      the stiffness force of section i, −k_i·δ_i on the section force S_i
``c`` (i)      the damping force of section i, −c_i·δ̇_i on S_i
``m`` (j)      the inertia of mass j: its acceleration divided by (1 + c) (a mass m_j·(1 + c))
``d_ep``       the drive coupling θ_i = k_i·d_ep of every patch: the force θ_i·q_hi/C_ep and the current −θ_i·δ̇_i
``alpha_h``    the hysteresis share: q_hi += c·α_h·(q_i − h_qi)
``beta_h``     the Bouc-Wen β_h term of ḣ_qi
``R_ep``       the current through R_ep (a resistance R_ep·(1 + c))
``C_ep``       1/C_ep in the patch voltage and in the piezo force (a capacitance C_ep·(1 + c))
=============  ==================================================================================================

Gates (:data:`GATES`, code in ``S`` the gate's signal, ``G`` its shape, ``H`` a fixed smoothing width): open for a
signal above or below a switching point ``G`` (screened at 0, refitted within ±0.8 of the signal's scale: a breathing
crack δ_i > G — for the section's own stiffness the continuous hinge c·k·(δ − G)⁺ of a bilinear spring; direction-
dependent damping: δ̇_i > G; polarisation: a drive or patch voltage below G), open over a smooth edge of fitted
width ``G`` for the sign of a section's own deflection (a crack that opens gradually), beyond a gap
``(|S| − G)⁺/|S|`` (free play or contact: with the stiffness it is exactly k·(δ − clip(δ, ±G))), a step at an
instant ``G`` = t0 inside the record (a damage event), and a ramp from t0 (damage growing). A change may also grow
with its signal: on one side linearly or with the square up to a saturation ``G`` (a crack whose faces part
progressively), or linearly past a magnitude ``G`` of either sign, (|S| − G)⁺/G (a coupling lost by degrees past a
field). Which gates each
contribution meets is :data:`GATED_BY`; the dictionary crosses them (:func:`workbench.discover.build_dictionary`),
so a form nobody wrote a test for is still a member.

This module holds the pieces as data and text (no :class:`~workbench.discover._dictionary.Term`): the kernel lines
of a contribution (:func:`contribution_lines`), the gate's values on arrays (:func:`gate_values`), its formula and
words (:func:`describe_damage`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Gate:
    """A switching condition: numba ``code`` in S, G, H and t; ``shape`` names G ("" if unused); a ramp's value is in
    seconds (``per_second``: the coefficient is a rate)."""

    name: str
    code: str
    shape: str = ""
    per_second: bool = False
    formula: str = ""


GATES: dict[str, Gate] = {
    "on_pos": Gate("on_pos", "0.5 * (1.0 + math.tanh((S - G) / H))", "switching point", formula="[S > G]"),
    "on_neg": Gate("on_neg", "0.5 * (1.0 - math.tanh((S - G) / H))", "switching point", formula="[S < G]"),
    # the same switch at 0 with an edge of fitted width G: a crack that opens gradually (its faces meet over a range)
    "on_pos_soft": Gate("on_pos_soft", "0.5 * (1.0 + math.tanh(S / G))", "edge width",
                        formula="(1 + tanh(S / G)) / 2"),
    "on_neg_soft": Gate("on_neg_soft", "0.5 * (1.0 - math.tanh(S / G))", "edge width",
                        formula="(1 − tanh(S / G)) / 2"),
    # one side, the change growing with the distance past 0 up to a saturation G: a crack whose faces part
    # progressively (its lost stiffness grows with the opening: quadratic in δ, then linear beyond G)
    "on_pos_grow": Gate("on_pos_grow", "min(max(S, 0.0) / G, 1.0)", "saturation", formula="min(S⁺ / G, 1)"),
    "on_neg_grow": Gate("on_neg_grow", "min(max(-S, 0.0) / G, 1.0)", "saturation", formula="min(S⁻ / G, 1)"),
    # ... its share growing with the square of the opening up to G (a crack whose contact area falls off with the
    # opening: lost force cubic in δ, then linear beyond G; blind set 7's section-2 crack quadratic to −w_open left
    # 8.6 σ with the linear share)
    "on_pos_grow2": Gate("on_pos_grow2", "min(max(S, 0.0) / G, 1.0) ** 2", "saturation",
                         formula="min(S⁺ / G, 1)²"),
    "on_neg_grow2": Gate("on_neg_grow2", "min(max(-S, 0.0) / G, 1.0) ** 2", "saturation",
                         formula="min(S⁻ / G, 1)²"),
    # one side, the change saturating smoothly as the signal grows past 0 (63 % of it at G): a patch's coupling lost
    # with its charging current, none at rest and nearly all once the current is a few G (domain walls pinned by
    # degrees as the field's rate rises)
    "on_pos_sat": Gate("on_pos_sat", "math.tanh(max(S, 0.0) / G)", "saturation", formula="tanh(S⁺ / G)"),
    "on_neg_sat": Gate("on_neg_sat", "math.tanh(max(-S, 0.0) / G)", "saturation", formula="tanh(S⁻ / G)"),
    "on_gap": Gate("on_gap", "max(abs(S) - G, 0.0) / max(abs(S), G)", "gap", formula="(|S| − G)⁺ / |S|"),
    # past a magnitude G of either sign, the change growing linearly with the excess (the coefficient is the change
    # at |S| = 2G, its slope c/G): a coupling that falls progressively with the field past a corner (domains
    # back-switching by degrees) — the gap's (|S| − G)⁺/|S| levels off instead
    "on_excess": Gate("on_excess", "max(abs(S) - G, 0.0) / G", "corner", formula="(|S| − G)⁺ / G"),
    "on_step": Gate("on_step", "0.5 * (1.0 + math.tanh((t - G) / H))", "onset time", formula="[t > G]"),
    "on_ramp": Gate("on_ramp", "max(t - G, 0.0)", "onset time", per_second=True, formula="(t − G)⁺"),
}
#: the gates that switch on a signal's sign or a gap (the hard forms of the search), those with a smooth edge, and
#: those in time
SIGN_GATES = ("on_pos", "on_neg")
SOFT_GATES = ("on_pos_soft", "on_neg_soft")
GROW_GATES = ("on_pos_grow", "on_neg_grow")
#: ... the same share growing with the square of the opening (on a section's deflection only)
SQUARE_GATES = ("on_pos_grow2", "on_neg_grow2")
SAT_GATES = ("on_pos_sat", "on_neg_sat")
#: the gates that act on one side of their signal (a sharp or smooth switch, a linear rise or a smooth saturation)
SIDED_GATES = (*SIGN_GATES, *SOFT_GATES, *GROW_GATES, *SQUARE_GATES, *SAT_GATES)
TIME_GATES = ("on_step", "on_ramp")
#: the gates whose edge width H is a fitted parameter of the dictionary (``h_NN``, default the fixed width below): a
#: step whose change took time — a loss that ran and arrested along an S-curve — is the same step with a wide edge;
#: a switch off zero whose faces close progressively (a crack with rough faces, a patch that weakens over a range
#: of drive) is the same sign gate with a wide edge
WIDTH_GATES = ("on_step", "on_ramp", "on_pos", "on_neg")
#: a ramp's width is the time constant of its saturation: rate · H · (1 − exp(−(t − G)⁺ / H)), the plain ramp
#: rate · (t − G)⁺ as H → ∞ (its default, far beyond any record: 1e12 s); finite, a change that slows and settles
#: at rate · H (damage that grows and arrests; a loss that partly recovers, beside a step). A negative width −T is
#: the opposite curvature: rate · min((t − G)⁺, T)² / T, a change that starts with zero slope, grows faster and
#: faster for T and holds at rate · T (a fatigue crack whose growth rate rises with its length until it reaches a
#: stiffener: quadratic in time, then arrested)
RAMP_NEVER_S = 1e12
WIDTH_CODE = {"on_step": "0.5 * (1.0 + math.tanh((t - G) / H))",
              "on_ramp": "((-H * math.expm1(-max(t - G, 0.0) / H)) if H > 0.0 else "
                         "(min(max(t - G, 0.0), -H) ** 2 / -H))"}
#: smoothing width H of a sign gate by the unit of its signal (far below any signal's scale: a switch for the
#: record, smooth for the integrator), and of the time step (s: below a sample at the fits' 250 Hz — a 25 % loss of
#: k2 at 20 s of a sweep, switched over 10 ms, differed from the same loss switched at once by 2.5 σ RMS, 0.06 σ
#: over 1 ms)
SIGN_WIDTH = {"m": 1e-7, "m/s": 1e-5, "V": 1e-2, "A": 1e-7}
STEP_WIDTH_S = 1e-3
#: onset times a step is screened at (fractions of the record; the refit moves t0 by up to half the spacing either
#: way, so together they span the record), and those of a ramp
STEP_AT = (0.125, 0.375, 0.625, 0.875)
RAMP_AT = (0.25, 0.75)
#: a ramp begun before the record — a loss already under way when the record starts, a share of it lost and the rest
#: still growing, c·(t − G) with G < 0 — is screened at this fraction of the record before its start and its onset
#: refitted from :data:`RAMP_BEFORE_REACH` records before the start to the start (a root loss begun 7.5 s before a
#: 15 s sweep: the library's drifts and a constant loss with a ramp from 3.75 s left 16.5 σ; one term at G < 0 is it)
RAMP_BEFORE_AT = -0.5
RAMP_BEFORE_REACH = 2.0
#: a switched change that began during the record — a crack that appears at an instant and then breathes, a
#: polarity that goes weak mid-test (an electrode finger cracks; blind set 7: patch 3 weak for v_c3 > 0 from 6 s of
#: a 15 s sweep, 21.9 σ as a whole-record switch) — is its switched term times a step at the instant ``since``:
#: ½(1 + tanh((t − since)/STEP_WIDTH_S)). Every switched damage term of these parameters carries it as a fitted
#: parameter of the dictionary (``s_NN``), from :data:`SINCE_NEVER_S` (long before any record: the factor is exactly
#: 1, the term as before) until :mod:`workbench.discover._since_onset` places it
SINCE_PARAMS = ("k", "c", "d_ep", "d_ep_i")
SINCE_NEVER_S = -1e12
#: gaps, fractions of the section deflection's scale
GAP_AT = (0.3, 0.6)
#: edge widths a soft gate is screened at (fraction of its signal's scale; the refit moves it a factor of four)
SOFT_AT = 0.2
#: edge widths a soft gate on a section's rate is screened at (fractions of the rate's scale): a direction-dependent
#: stiffness switches close to the turning points, and its edge must be placed within a factor of about two (a
#: 25 % loss of k2 for δ̇2 > 0 over 1 mm/s, simulated with that edge at 1, 3 and 10 mm/s or switched at once: 0,
#: 32, 43 and 28 σ RMS apart on a 15 s sweep), so two widths a decade apart, each refitted a factor of four
SOFT_RATE_AT = (0.005, 0.05)
#: saturations a growing gate is screened at (fractions of its signal's scale; the refit moves it a factor of four:
#: from a quarter of the scale — nearly a sharp switch — to four times it, a loss quadratic over the whole motion)
GROW_AT = (1.0,)
#: ... and the saturation of a smoothly saturating gate on a patch's charging current (fraction of its scale): the
#: current's 99th percentile is set by the drive's fastest edges, far above the currents most of a record carries
#: (MBIT.a: a scale of 4 mA, a coupling lost over the first 0.2 mA), so it is screened low, where a factor of four
#: either way spans 0.05–0.8 mA there (a growing gate screened at the scale could not leave 83 σ on that case)
SAT_CHARGE_AT = 0.05
#: ... and on a patch's own voltage (a quarter of its scale; the refit spans 1/16 to the whole scale)
SAT_VOLT_AT = 0.25
#: a sign gate is screened switching at 0 and its switching point G refitted linearly within ± this fraction of
#: its signal's scale (the 99th percentile of |signal|): a crack or a depoled patch that switches off zero
SWITCH_RANGE = 0.8


@dataclass(frozen=True)
class Contribution:
    """A core parameter's own term: ``per`` section, mass or (every) patch; ``hooks``: kernel lines per hook with
    ``{A}`` the term's factor (coefficient × gate) and ``{i}`` the section/mass index (a patch's lines run in a loop
    over ``i``); ``formula``: the term in symbols; ``what``: words."""

    name: str
    per: str
    hooks: dict[str, tuple[str, ...]]
    formula: str
    what: str


def _mass_lines(j: int) -> tuple[str, ...]:
    acc = " + ".join(f"dx[X_DDELTA + {k}]" for k in range(j + 1)) + " + bus[B_Z0DD]"
    lines = ("f_m = {A}", "f_m = f_m / max(1.0 + f_m, 0.05)", f"a_m = {acc}", f"dx[X_DDELTA + {j}] -= a_m * f_m")
    return lines + ((f"dx[X_DDELTA + {j + 1}] += a_m * f_m",) if j < 2 else ())


#: the drive coupling of patch i (in the loop over the patches): its piezo force and the current its motion induces
_D_EP_HOOKS: dict[str, tuple[str, ...]] = {"rates": (
    "f_d = ({A}) * p[P_K + i] * p[P_D_EP]", "bus[B_S + i] += f_d * bus[B_QH + i] / p[P_C_EP]",
    "dx[X_Q + i] -= f_d * x[X_DDELTA + i]")}

CONTRIBUTIONS: dict[str, Contribution] = {
    "k": Contribution("k", "section", {"rates": ("bus[B_S + {i}] += -({A}) * p[P_K + {i}] * x[X_DELTA + {i}]",)},
                      "S_{n} += −c · k{n} · δ{n}", "stiffness k{n} of section {n}"),
    "c": Contribution("c", "section", {"rates": ("bus[B_S + {i}] += -({A}) * p[P_C + {i}] * x[X_DDELTA + {i}]",)},
                      "S_{n} += −c · c{n} · δ̇{n}", "damping c{n} of section {n}"),
    "m": Contribution("m", "mass", {}, "mass j: acceleration ÷ (1 + c)", "mass m{n}"),
    "d_ep": Contribution("d_ep", "patch", _D_EP_HOOKS,
                         "S_i += c · k_i d_ep q_hi / C_ep,  dq_i/dt −= c · k_i d_ep δ̇_i", "patch authority d_ep"),
    # one patch's own coupling (the patch bonded on section n): a single patch partly depolarised or debonded
    "d_ep_i": Contribution("d_ep_i", "each_patch", _D_EP_HOOKS,
                           "S_{n} += c · k{n} d_ep q_h{n} / C_ep,  dq_{n}/dt −= c · k{n} d_ep δ̇{n}",
                           "authority d_ep of patch {n}"),
    "alpha_h": Contribution("alpha_h", "patch", {"pre": (
        "bus[B_QH + i] += ({A}) * p[P_ALPHA_H] * (x[X_Q + i] - x[X_H + i])",)},
        "q_hi += c · α_h (q_i − h_qi)", "hysteresis share α_h of the patches"),
    "beta_h": Contribution("beta_h", "patch", {"post": (
        "h_b = x[X_H + i]",
        "dx[X_H + i] -= ({A}) * p[P_BETA_H] * abs(dx[X_Q + i]) * abs(h_b) ** (p[P_N_H] - 1.0) * h_b")},
        "dh_qi/dt −= c · β_h |q̇_i| |h_qi|^(n−1) h_qi", "hysteresis β_h of the patches"),
    "R_ep": Contribution("R_ep", "patch", {"rates": (
        "f_r = {A}", "i_r = -f_r / max(1.0 + f_r, 0.05) * (bus[B_VA] - bus[B_VC + i]) / p[P_R_EP]",
        "bus[B_IR + i] += i_r", "dx[X_Q + i] += i_r")},
        "R_ep → R_ep (1 + c)", "patch resistance R_ep"),
    "C_ep": Contribution("C_ep", "patch", {
        "pre": ("f_c = {A}", "bus[B_VC + i] -= f_c / max(1.0 + f_c, 0.05) * x[X_Q + i] / p[P_C_EP]"),
        "rates": ("f_c = {A}",
                  "bus[B_S + i] -= f_c / max(1.0 + f_c, 0.05) * p[P_K + i] * p[P_D_EP] * bus[B_QH + i] / p[P_C_EP]")},
        "C_ep → C_ep (1 + c) in q_i/C_ep and in the piezo force", "patch capacitance C_ep"),
}

#: the gate signals each contribution meets: "own_delta"/"own_ddelta" the section's own deflection/rate, "va" the
#: drive, "vc" the patch voltage (its charge), "time" the step and the ramp; "gap" the gap of the section's deflection,
#: "soft" its sign with a smooth edge (a crack that opens gradually), "soft_rate" the sign of its rate with a smooth
#: edge (a direction-dependent stiffness or damping whose faces part gradually), "grow" its sign with the change
#: growing with the opening (a crack whose faces part progressively); "tip"/"soft_tip" the sign of the tip's
#: displacement z3, sharp or with a smooth edge (a crack opened by the beam's swing, not by its own section's
#: bending); "soft_drive" the drive's sign with a smooth edge (the patch voltage's on an undriven record: a
#: polarisation that fades over a range of field); "grow_volt" the patch's own voltage with the change growing with
#: it up to a saturation (a coupling that fades progressively as the voltage rises on one polarity: electrode
#: fingers that lose contact one by one, domains that back-switch by degrees). A patch's own coupling meets its
#: section's deflection too (a patch whose bond opens while its section bends one way: partly debonded), and the sign
#: of its charging current "ic", (v_a − v_c)/R_ep, sharp or with a smooth edge ("soft_charge"): a coupling lost while
#: the patch charges, not while it discharges (domain walls pinned while the field rises in the poling sense), or
#: saturating smoothly as that current grows ("sat_charge", tanh(i⁺/G): none at rest, nearly all of it once the
#: current is a few G); the patch's own voltage meets the same smooth saturation ("sat_volt": a coupling lost on one
#: polarity the more the stronger the field, saturating — beside "grow_volt"'s linear rise to a corner) and a gap in
#: its magnitude ("gap_volt", (|v_c| − G)⁺/|v_c|: a coupling lost above a field magnitude in either polarity — fatigued
#: domains that saturate forward and back-switch in reverse; blind set 7's patch 2 weak above 150 V left 48 σ) and a
#: loss growing linearly past a magnitude ("excess_volt", (|v_c| − G)⁺/G: its slope and corner both free; the gap
#: form only approached that case's linear rise, 6.19 σ on the sweep, every patch standing in for patch 2)
GATED_BY: dict[str, tuple[str, ...]] = {
    "k": ("own_delta", "own_ddelta", "soft", "soft_rate", "grow", "tip", "soft_tip", "gap", "time"),
    "c": ("own_ddelta", "own_delta", "soft", "soft_rate", "grow", "gap", "time"),
    "m": ("time",),
    "d_ep": ("va", "vc", "soft_drive", "grow_volt", "sat_volt", "ic", "soft_charge", "sat_charge", "gap_volt",
             "excess_volt", "time"),
    "d_ep_i": ("va", "vc", "soft_drive", "grow_volt", "sat_volt", "ic", "soft_charge", "sat_charge", "gap_volt",
               "excess_volt", "own_delta", "soft", "time"),
    "alpha_h": ("va", "vc", "time"),
    "beta_h": ("va", "vc", "time"),
    "R_ep": ("va", "vc", "time"),
    "C_ep": ("va", "vc", "time"),
}


def param_label(param: str, index: int) -> str:
    """The parameter as named in a term's key: ``k2``, ``m3``, ``d_ep``."""
    if param == "d_ep_i":
        return f"d_ep{index + 1}"
    return f"{param}{index + 1}" if CONTRIBUTIONS[param].per != "patch" else param


def is_hinge(param: str, form: str, signal: str) -> bool:
    """Whether the term is a section's stiffness gated by the sign of its own deflection: a bilinear spring, whose
    lost force c·k·(δ − G)⁺ (resp. (δ − G)⁻) is continuous at the switching point G (a hinge, not a step of k·δ)."""
    return param == "k" and form in SIGN_GATES and signal.startswith("delta")


#: the hinge's gate (code in S, G, H): (S − G) times the smoothed step at G, so the stiffness line drops its δ; at
#: G = 0 it is exactly δ·[δ > 0] (resp. δ·[δ < 0]), the step gate times k·δ — no division by δ anywhere. Less its
#: value at rest (S = 0): the section carries no force at rest, a corner on the far side of rest included — a crack
#: propped open at rest that closes for δ1 < −0.25 mm loses k1·(max(δ1, −0.25 mm)), not k1·(δ1 + 0.25 mm), which
#: would preload the section at rest (the sweep's fit with it, and a laser offset beside, left 15.5 σ; blind set 4)
HINGE_CODE = {form: f"(S - G) * {GATES[form].code} + G * {GATES[form].code.replace('S', '0.0')}"
              for form in SIGN_GATES}
#: the stiffness line of a hinge: the gate carries the deflection beyond the switching point
_HINGE_LINES = {"rates": ("bus[B_S + {i}] += -({A}) * p[P_K + {i}]",)}


def gate_code(form: str, param: str, signal: str) -> str:
    """Numba code (in S, G, H, t) of the gate of a damage term: the hinge for a bilinear spring, else the gate's."""
    return HINGE_CODE[form] if is_hinge(param, form, signal) else GATES[form].code


def contribution_lines(param: str, index: int, factor: str, hinge: bool = False) -> dict[str, list[str]]:
    """Kernel lines (unindented) of ``param``'s contribution scaled by ``factor`` (numba code), per hook; ``hinge``:
    the stiffness line without its deflection (the factor is the hinge, :data:`HINGE_CODE`)."""
    con = CONTRIBUTIONS[param]
    hooks = {"post": _mass_lines(index)} if param == "m" else _HINGE_LINES if hinge else con.hooks
    out: dict[str, list[str]] = {}
    for hook, lines in hooks.items():
        body = [ln.replace("{A}", factor).replace("{i}", str(index)) for ln in lines]
        if con.per == "each_patch":  # the loop keeps ``i`` for the patch signals (bus[B_VC + i])
            out[hook] = ["for i in range(3):", f"    if i == {index}:", *("        " + ln for ln in body)]
        else:
            out[hook] = ["for i in range(3):", *("    " + ln for ln in body)] if con.per == "patch" else body
    return out


def has_since(param: str, form: str) -> bool:
    """Whether a damage term of ``param`` gated by ``form`` may begin at an instant of the record (a switched change
    of :data:`SINCE_PARAMS`; not a step or a ramp, which have their own onset)."""
    return param in SINCE_PARAMS and form not in TIME_GATES


def since_factor(since: str) -> str:
    """Numba code (in t) of the step at the instant ``since`` (code or a literal, s) a switched change begins at."""
    return f"0.5 * (1.0 + math.tanh((t - {since}) / {STEP_WIDTH_S!r}))"


def default_width(form: str, unit: str = "s") -> float:
    """The edge width a fitted-width gate on a signal of ``unit`` starts from (SI): the sharp step's, a ramp that
    never saturates, a sign gate's sharp switch."""
    if form in SIGN_GATES:
        return gate_width(form, unit)
    return STEP_WIDTH_S if form == "on_step" else RAMP_NEVER_S


def gate_width(form: str, unit: str) -> float:
    """The fixed smoothing width H of a gate on a signal of ``unit`` (s for the time step; 0 when unused)."""
    if form == "on_step":
        return STEP_WIDTH_S
    return SIGN_WIDTH.get(unit, 1e-6) if form in SIGN_GATES else 0.0


def gate_values(form: str, s: np.ndarray, g: float, t: np.ndarray, unit: str, hinge: bool = False) -> np.ndarray:
    """The gate evaluated on arrays (NumPy): signal ``s`` (of ``unit``), shape ``g``, time ``t`` (s); ``hinge``: a
    sign gate as the bilinear spring's hinge (s − g)·[s ≷ g] (of the signal's unit)."""
    h = gate_width(form, unit)
    s = np.broadcast_to(np.asarray(s, float), np.shape(t)) if np.ndim(s) == 0 else np.asarray(s, float)
    if form in SIGN_GATES:
        sign = 1.0 if form == "on_pos" else -1.0
        step = 0.5 * (1.0 + sign * np.tanh((s - g) / h))
        return (s - g) * step + g * 0.5 * (1.0 + sign * np.tanh(-g / h)) if hinge else step
    if form in SOFT_GATES:
        return 0.5 * (1.0 + np.tanh(s / g)) if form == "on_pos_soft" else 0.5 * (1.0 - np.tanh(s / g))
    if form in GROW_GATES:
        return np.minimum(np.maximum(s if form == "on_pos_grow" else -s, 0.0) / g, 1.0)
    if form in SQUARE_GATES:
        return np.minimum(np.maximum(s if form == "on_pos_grow2" else -s, 0.0) / g, 1.0) ** 2
    if form in SAT_GATES:
        return np.tanh(np.maximum(s if form == "on_pos_sat" else -s, 0.0) / g)
    if form == "on_gap":
        return np.maximum(np.abs(s) - g, 0.0) / np.maximum(np.abs(s), g)
    if form == "on_excess":
        return np.maximum(np.abs(s) - g, 0.0) / g
    if form == "on_step":
        return 0.5 * (1.0 + np.tanh((np.asarray(t, float) - g) / h))
    if form == "on_ramp":
        return np.maximum(np.asarray(t, float) - g, 0.0)
    raise KeyError(form)


def damage_formula(param: str, index: int, form: str, signal: str, cname: str, gname: str | None,
                   width: float = 0.0, since: float | None = None) -> str:
    """The term as a formula (for the emitted file's docstring); ``width``: a fitted width (a step's edge, a ramp's
    settling time, s; a switch's edge, SI of its signal); ``since``: the instant (s) a switched change began at."""
    out = _gated_formula(param, index, form, signal, cname, gname, width)
    if since is None:
        return out
    return f"{out}   × (1 + tanh((t − {since:.10g} s) / {STEP_WIDTH_S * 1e3:g} ms)) / 2   (from t = {since:.4g} s on)"


def _gated_formula(param: str, index: int, form: str, signal: str, cname: str, gname: str | None,
                   width: float) -> str:
    """The formula of :func:`damage_formula` for a change that held through the record."""
    g = gname or "g"
    if form in TIME_GATES and width != 0.0:
        con = CONTRIBUTIONS[param].formula.format(n=index + 1)
        if form == "on_ramp" and width < 0.0:  # accelerating, then held
            return f"{con}   with c = {cname} · min((t − {g})⁺, {-width:.4g} s)² / {-width:.4g} s"
        if form == "on_ramp":
            return f"{con}   with c = {cname} · {width:.4g} s · (1 − exp(−(t − {g})⁺ / {width:.4g} s))"
        return f"{con}   with c = {cname} · (1 + tanh((t − {g}) / {width:.4g} s)) / 2"
    if form in SIGN_GATES and width > 0.0:  # the switch's edge: ½(1 ± tanh((S − G)/H)) at the fitted H
        return (_gated_formula(param, index, form, signal, cname, gname, 0.0)
                + f"   (its edge ½(1 {'+' if form == 'on_pos' else '−'} tanh(({signal} − {g}) / {width:.4g})), SI)")
    if is_hinge(param, form, signal):  # the bilinear spring: the lost force beyond the switching point
        n = index + 1
        side = "⁺" if form == "on_pos" else "⁻"
        return f"S_{n} += −{cname} · k{n} · ((δ{n} − {g}){side} − (−{g}){side})   (no force at rest)"
    gate = GATES[form].formula.replace("S", {"one": "1"}.get(signal, signal)).replace("G", g)
    con = CONTRIBUTIONS[param].formula.format(n=index + 1)
    return f"{con}   with c = {cname} · {gate}"


def class_stem(param: str, index: int, form: str, signal: str = "") -> str:
    """CamelCase words for an emitted class: 'Section2StiffnessEvent' ('Section2StiffnessRatePositive' for a gate
    on the section's rate, apart from the gate on its deflection)."""
    base = {"k": f"Section{index + 1}Stiffness", "c": f"Section{index + 1}Damping", "m": f"Mass{index + 1}",
            "d_ep": "PatchCoupling", "d_ep_i": f"Patch{index + 1}Coupling",
            "alpha_h": "PatchHysteresisShare", "beta_h": "PatchHysteresis",
            "R_ep": "PatchResistance", "C_ep": "PatchCapacitance"}[param]
    on = ("Rate" if signal.startswith("ddelta") else "Tip" if signal == "z3" else "Charging" if signal == "ic"
          else "Drive" if signal in ("va", "vc")
          and form in SOFT_GATES else "Bend" if signal.startswith("delta") and param == "d_ep_i" else "")
    return base + {"on_pos": f"{on}Positive", "on_neg": f"{on}Negative", "on_pos_soft": f"{on}OpeningPositive",
                   "on_neg_soft": f"{on}OpeningNegative",
                   "on_pos_grow": "GrowingPositive", "on_neg_grow": "GrowingNegative",
                   "on_pos_grow2": "GrowingSquarePositive", "on_neg_grow2": "GrowingSquareNegative",
                   "on_pos_sat": f"{on}SaturatingPositive", "on_neg_sat": f"{on}SaturatingNegative",
                   "on_gap": "AboveMagnitude" if signal in ("va", "vc") else "BeyondGap",
                   "on_excess": "GrowingAboveMagnitude", "on_step": "Event",
                   "on_ramp": "Growth"}[form]


def onset_floor(onset: float, half: float) -> float:
    """The lower end (s) of a refit window ``half`` wide below an ``onset``: kept inside the record (≥ 0) for an
    onset inside it, free below one placed before it (a ramp begun before the record)."""
    return onset - half if onset < 0.0 else max(onset - half, 0.0)


def onset_before(duration_s: float) -> tuple[float, tuple[float, float]]:
    """(t0, refit range of t0) of the ramp begun before a record of ``duration_s``: :data:`RAMP_BEFORE_AT` of it
    before the start, refitted between :data:`RAMP_BEFORE_REACH` records before the start and the start."""
    return RAMP_BEFORE_AT * duration_s, (-RAMP_BEFORE_REACH * duration_s, 0.0)


def onsets(duration_s: float, fractions: Sequence[float]) -> list[tuple[float, tuple[float, float]]]:
    """(t0, refit range of t0) for onsets at ``fractions`` of a record of ``duration_s``: each range reaches half way
    to its neighbours, the first from 0 and the last to the end."""
    out = []
    for k, f in enumerate(fractions):
        lo = 0.0 if k == 0 else 0.5 * (fractions[k - 1] + f)
        hi = 1.0 if k == len(fractions) - 1 else 0.5 * (f + fractions[k + 1])
        out.append((f * duration_s, (lo * duration_s, hi * duration_s)))
    return out
