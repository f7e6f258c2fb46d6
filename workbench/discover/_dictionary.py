"""The dictionary of candidate correction terms that ``shm discover`` searches: the forms, the signals, the terms.

A *term* is one physical correction, built from one of the model's own signals along the records and placed where
the physics allows it to act:

==================  ============================================================  ===============
placement           what the term adds                                             coefficient unit
==================  ============================================================  ===============
``force_mass``      a force on mass j (``bus[B_FM + j]``, N)                       N / signal^n
``force_section``   an internal force in section i (``bus[B_S + i]``, N)           N / signal^n
``current``         a current into every patch charge (``dx[X_Q + i]``, A)         A / signal^n
``drive``           a change of the voltage the patches see (``bus[B_VA]``, V)     V / signal^n
``measurement``     a change of what the tip laser reports (``y[Y_Z3_MEAS]``, m)   m / signal^n
``damage``          a core parameter's own term switched by a gate                 1 (relative)
==================  ============================================================  ===============

Each term is ``coefficient × form(signal)`` with one of the forms of :data:`FORMS` — linear, sign (dry friction,
smoothed by a width well below the signal's scale), |x|·x, x², x³, one-sided above/below a threshold, dead zone,
clipped (a clearance), saturating, time-weighted (a drifting gain) and delayed (a first-order Padé delay, one extra
state). Thresholds, widths and delays (the term's *shape*) are set from the signal's scale along the records, at a
few fractions each; the refit frees them.

*Damage terms* (placement ``damage``, :mod:`workbench.discover._gates`) are a family, not a list: every core
parameter's own contribution (k_i·δ_i, c_i·δ̇_i, the masses' inertia, d_ep's coupling, α_h, β_h, R_ep, C_ep) times
a switching gate (the sign of the section's deflection or rate, beyond a gap, the sign of the drive or the patch
voltage, a step at an instant t0 inside the record, a ramp from t0); the coefficient is the parameter's relative
change while the gate is open, the gate's signal is the term's ``signal`` and its switching point, gap or onset time
its ``shape`` (a section's stiffness switched by its own deflection is a bilinear spring: a hinge at the switching
point, continuous there).

:func:`build_dictionary` lists the terms for a model and records; :func:`form_values` evaluates a form on arrays
(NumPy) for scaling. The code a set of terms becomes (the hooks of a :class:`~plant.PhysicalEffect`: the whole
dictionary for the sensitivity batch, or the few chosen terms for the refit and the emitted file) is written by
:mod:`workbench.discover._dictionary_code`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace

import numpy as np

from workbench.discover._gates import (
    CONTRIBUTIONS,
    GAP_AT,
    GATED_BY,
    GATES,
    GROW_AT,
    GROW_GATES,
    RAMP_AT,
    SAT_CHARGE_AT,
    SAT_GATES,
    SAT_VOLT_AT,
    SOFT_AT,
    SOFT_GATES,
    SOFT_RATE_AT,
    SQUARE_GATES,
    STEP_AT,
    SWITCH_RANGE,
    gate_values,
    onset_before,
    onsets,
    param_label,
)

#: placements and the unit of what they add (a damage term's coefficient is a relative change)
PLACEMENT_UNIT = {"force_mass": "N", "force_section": "N", "current": "A", "drive": "V", "measurement": "m",
                  "damage": "1"}


@dataclass(frozen=True)
class Form:
    """A shape of a term: ``code`` is a numba expression in ``S`` (the signal) and ``G`` (the shape constant);
    ``power`` is the exponent of the signal's unit in the term; ``shape`` names what ``G`` is (or "" if unused)."""

    name: str
    code: str
    power: int
    shape: str = ""
    per_second: bool = False


FORMS: dict[str, Form] = {
    "lin": Form("lin", "S", 1),
    "sign": Form("sign", "math.tanh(S / G)", 0, "smoothing width"),
    "absx": Form("absx", "abs(S) * S", 2),
    "square": Form("square", "S * S", 2),
    "cube": Form("cube", "S * S * S", 3),
    "pos": Form("pos", "max(S - G, 0.0)", 1, "threshold"),
    "neg": Form("neg", "min(S + G, 0.0)", 1, "threshold"),
    "dead": Form("dead", "S - min(max(S, -G), G)", 1, "half-width"),
    "clip": Form("clip", "min(max(S, -G), G)", 1, "half-width"),
    "sat": Form("sat", "G * math.tanh(S / G) - S", 1, "saturation level"),
    "time": Form("time", "t * S", 1, "", per_second=True),
    "delay": Form("delay", "2.0 * (W - S)", 1, "delay"),
    # second-order Padé of a pure delay T: y = s − T·w2 with w1'' T²/12 + w1' T/2 + w1 = s, w2 = w1' (phase within
    # 2 % of e^{−iωT} up to ωT ≈ 2, where the first-order form is 20 % short)
    "delay2": Form("delay2", "-G * V", 1, "delay"),
}

#: the gates of the damage terms as forms (code in S, G and the fixed width H; no power of the signal)
GATE_FORMS: dict[str, Form] = {g.name: Form(g.name, g.code, 0, g.shape, g.per_second) for g in GATES.values()}
#: every form a term may have
ALL_FORMS: dict[str, Form] = {**FORMS, **GATE_FORMS}

#: forms that carry states of their own (how many): the delay lines, first- and second-order Padé
STATE_FORMS = {"delay": 1, "delay2": 2}
DELAY_FORMS = tuple(STATE_FORMS)


def n_form_states(form: str) -> int:
    """How many states a term of ``form`` carries (its delay line)."""
    return STATE_FORMS.get(form, 0)


@dataclass(frozen=True)
class Signal:
    """A model signal: numba code reading it inside a hook, SI unit, words."""

    name: str
    code: str
    unit: str
    words: str


def _signals() -> dict[str, Signal]:
    out = {}
    for j in range(3):
        out[f"z{j + 1}"] = Signal(f"z{j + 1}", f"bus[B_Z + {j}]", "m", f"displacement of mass {j + 1}")
        out[f"zd{j + 1}"] = Signal(f"zd{j + 1}", f"bus[B_ZD + {j}]", "m/s", f"velocity of mass {j + 1}")
        out[f"delta{j + 1}"] = Signal(f"delta{j + 1}", f"x[X_DELTA + {j}]", "m", f"deformation of section {j + 1}")
        out[f"ddelta{j + 1}"] = Signal(f"ddelta{j + 1}", f"x[X_DDELTA + {j}]", "m/s",
                                       f"deformation rate of section {j + 1}")
    out["vc"] = Signal("vc", "bus[B_VC + i]", "V", "patch voltage")
    out["va"] = Signal("va", "bus[B_VA_DEMAND]", "V", "drive voltage")
    # the current charging the patch through R_ep (its own; the rate of its charge less the piezo share)
    out["ic"] = Signal("ic", "((bus[B_VA] - bus[B_VC + i]) / p[P_R_EP])", "A", "patch charging current")
    out["one"] = Signal("one", "1.0", "1", "constant (a time gate's signal)")
    return out


SIGNALS = _signals()


@dataclass(frozen=True)
class Term:
    """One candidate correction: ``coefficient × form(signal)`` added at ``placement`` (mass/section ``index``,
    0-based; -1 when it does not apply). ``shape`` is the form's constant (SI, the signal's unit; for a delay, s).
    A damage term (placement ``damage``) is ``coefficient × contribution(param) × gate(signal)``, the gate being
    its form; ``shape_range`` is where the refit may move its shape (an onset time or a switching point: linear),
    None for a factor of four either way. ``width``: a fitted edge time scale (s) of a step whose change took time
    (an S-shaped loss: ½(1 + tanh((t − t0)/width))); 0 for the gate's own fixed, sharp edge. ``since``: the instant
    (s) a switched change began at, found (:mod:`workbench.discover._since_onset`); None for the whole record."""

    placement: str
    index: int
    signal: str
    form: str
    shape: float = 0.0
    param: str = ""
    shape_range: tuple[float, float] | None = None
    width: float = 0.0
    since: float | None = None

    @property
    def key(self) -> str:
        if self.placement == "damage":
            gate = "t" if self.signal == "one" else self.signal
            return f"{param_label(self.param, self.index)}_{self.form[3:]}_{gate}"
        where = {"force_mass": f"m{self.index + 1}", "force_section": f"s{self.index + 1}", "current": "q",
                 "drive": "va", "measurement": "z3m"}[self.placement]
        return f"{where}_{self.form}_{self.signal}"

    @property
    def shape_unit(self) -> str:
        """SI unit of the shape: s for a delay or an onset, else the signal's unit (a gap, a smoothing width)."""
        if self.form in DELAY_FORMS or self.form in ("on_step", "on_ramp"):
            return "s"
        return SIGNALS[self.signal].unit

    @property
    def unit(self) -> str:
        """Unit of the coefficient."""
        if self.placement == "damage":
            return "1/s" if ALL_FORMS[self.form].per_second else "1"
        sig = SIGNALS[self.signal].unit
        f = FORMS[self.form]
        base = PLACEMENT_UNIT[self.placement]
        if sig == "1" or f.power == 0:
            den = ""
        elif f.power == 1:
            den = sig
        else:
            den = f"({sig})^{f.power}"
        if f.per_second:
            den = f"{den}*s" if den else "s"
        if not den:
            return base
        return "1" if den == base else f"{base}/{den}"

    @property
    def before_record(self) -> bool:
        """Whether this is a ramp begun before the record (its onset's refit range ends at the record's start)."""
        return self.shape_range is not None and self.shape_range[1] <= 0.0 and self.form == "on_ramp"

    def with_shape(self, shape: float) -> Term:
        return replace(self, shape=float(shape))


# ----------------------------------------------------------------------------------------------------------------
# the dictionary for a model and records


def form_values(form: str, s: np.ndarray, g: float, t: np.ndarray, dt: float) -> np.ndarray:
    """The form evaluated on the signal ``s`` (NumPy; for the delay, the first-order Padé delay's correction
    2·(lag(s) − s) ≈ −g·ds/dt)."""
    s = np.asarray(s, float)
    if form == "lin":
        return s
    if form == "sign":
        return np.tanh(s / g)
    if form == "absx":
        return np.abs(s) * s
    if form == "square":
        return s * s
    if form == "cube":
        return s ** 3
    if form == "pos":
        return np.maximum(s - g, 0.0)
    if form == "neg":
        return np.minimum(s + g, 0.0)
    if form == "dead":
        return s - np.clip(s, -g, g)
    if form == "clip":
        return np.clip(s, -g, g)
    if form == "sat":
        return g * np.tanh(s / g) - s
    if form == "time":
        return t * s
    if form in DELAY_FORMS:
        return -g * np.gradient(s, dt) if s.size > 2 else np.zeros_like(s)
    if form in GATE_FORMS:
        return gate_values(form, s, g, t, "m")  # a sign gate's width (by unit) does not change its RMS
    raise KeyError(form)


#: fractions of a signal's scale (99th percentile of |signal| along the records) used as thresholds/widths
THRESHOLDS = (0.2, 0.35, 0.5, 0.65, 0.8)
DEAD_ZONES = (0.15, 0.4)
SAT_LEVEL = 0.6
SIGN_WIDTH = 1e-3
DELAYS_S = (0.002, 0.008)


def build_dictionary(scales: Mapping[str, float], *, driven: bool = True) -> list[Term]:
    """The candidate terms for signals of the given scales (99th percentile of |signal|, SI). ``driven``: the
    patches are driven by the amplifier (drive terms apply); an open-circuit record has no drive to correct."""
    terms: list[Term] = []

    def ok(sig: str) -> bool:
        return scales.get(sig, 0.0) > 0.0

    for j in range(3):
        z, zd = f"z{j + 1}", f"zd{j + 1}"
        if ok(zd):
            terms += [Term("force_mass", j, zd, "lin"), Term("force_mass", j, zd, "absx"),
                      Term("force_mass", j, zd, "sign", SIGN_WIDTH * scales[zd])]
        if ok(z):
            terms += [Term("force_mass", j, z, "lin"), Term("force_mass", j, z, "cube"),
                      Term("force_mass", j, z, "square")]
            for f in THRESHOLDS:
                terms += [Term("force_mass", j, z, "pos", f * scales[z]),
                          Term("force_mass", j, z, "neg", f * scales[z])]
    for i in range(3):
        d, dd = f"delta{i + 1}", f"ddelta{i + 1}"
        if ok(d):
            for f in DEAD_ZONES:
                terms += [Term("force_section", i, d, "dead", f * scales[d]),
                          Term("force_section", i, d, "clip", f * scales[d])]
        if ok(dd):
            terms.append(Term("force_section", i, dd, "sign", SIGN_WIDTH * scales[dd]))
    if ok("vc"):
        terms += [Term("current", -1, "vc", "lin"), Term("current", -1, "vc", "absx"),
                  Term("current", -1, "vc", "cube")]
    if driven and ok("va"):
        terms += [Term("drive", -1, "va", f, tau) for f in DELAY_FORMS for tau in DELAYS_S]
        terms += [Term("drive", -1, "va", "pos", 0.01 * scales["va"]),
                  Term("drive", -1, "va", "neg", 0.01 * scales["va"])]
        terms += [Term("drive", -1, "va", "square"), Term("drive", -1, "va", "cube"),
                  Term("drive", -1, "va", "sat", SAT_LEVEL * scales["va"]), Term("drive", -1, "va", "time")]
    if ok("z3"):
        terms += [Term("measurement", -1, "z3", f) for f in ("lin", "square", "cube", "time")]
        terms.append(Term("measurement", -1, "z3", "sat", SAT_LEVEL * scales["z3"]))
        # the reading late or low-passed (sensor filter, DAQ skew): a Padé delay of z3 in the measurement
        terms += [Term("measurement", -1, "z3", f, tau) for f in DELAY_FORMS for tau in DELAYS_S]
    if ok("zd3"):
        terms.append(Term("measurement", -1, "zd3", "lin"))
    terms += [Term("measurement", -1, "one", "lin"), Term("measurement", -1, "one", "time")]
    return terms + damage_terms(scales, driven=driven)


def damage_terms(scales: Mapping[str, float], *, driven: bool = True) -> list[Term]:
    """Every core parameter's contribution crossed with the gates it meets (:data:`~workbench.discover._gates.
    GATED_BY`): sign gates on the section's own deflection or rate, on the drive (when ``driven``) or the patch
    voltage (switching at 0, refitted within ± :data:`~workbench.discover._gates.SWITCH_RANGE` of the signal's
    scale); gaps at :data:`~workbench.discover._gates.GAP_AT` of the deflection's scale; steps and ramps at onsets
    spanning the record (``scales["t"]``, the longest record's duration; no time gates without it)."""
    terms: list[Term] = []

    def ok(sig: str) -> bool:
        return scales.get(sig, 0.0) > 0.0

    duration = scales.get("t", 0.0)
    for param, con in CONTRIBUTIONS.items():
        for index in (range(3) if con.per != "patch" else (-1,)):
            for what in GATED_BY[param]:
                sig = {"own_delta": f"delta{index + 1}", "own_ddelta": f"ddelta{index + 1}",
                       "gap": f"delta{index + 1}", "tip": "z3"}.get(what, what)
                if what == "time":
                    if duration > 0:
                        terms += [Term("damage", index, "one", "on_step", t0, param, rng)
                                  for t0, rng in onsets(duration, STEP_AT)]
                        terms += [Term("damage", index, "one", "on_ramp", t0, param, rng)
                                  for t0, rng in (onset_before(duration), *onsets(duration, RAMP_AT))]
                elif what in ("soft", "soft_rate", "soft_tip", "soft_drive", "soft_charge"):
                    sig = {"soft": f"delta{index + 1}", "soft_rate": f"ddelta{index + 1}", "soft_tip": "z3",
                           "soft_drive": "va" if driven else "vc", "soft_charge": "ic"}[what]
                    if ok(sig):
                        widths = SOFT_RATE_AT if what == "soft_rate" else (SOFT_AT,)
                        terms += [Term("damage", index, sig, g, w * scales[sig], param) for g in SOFT_GATES
                                  for w in widths]
                elif what in ("grow", "grow_volt"):
                    if ok(sig := "vc" if what == "grow_volt" else f"delta{index + 1}"):
                        gates = GROW_GATES if what == "grow_volt" else (*GROW_GATES, *SQUARE_GATES)
                        terms += [Term("damage", index, sig, g, f * scales[sig], param) for g in gates
                                  for f in GROW_AT]
                elif what in ("sat_charge", "sat_volt"):
                    if ok(sig := "ic" if what == "sat_charge" else "vc"):
                        at = SAT_CHARGE_AT if sig == "ic" else SAT_VOLT_AT
                        terms += [Term("damage", index, sig, g, at * scales[sig], param) for g in SAT_GATES]
                elif what in ("gap", "gap_volt", "excess_volt"):
                    if ok(sig := "vc" if what.endswith("_volt") else sig):
                        form = "on_excess" if what == "excess_volt" else "on_gap"
                        terms += [Term("damage", index, sig, form, f * scales[sig], param) for f in GAP_AT]
                elif ok(sig) and (driven or sig != "va"):
                    rng = (-SWITCH_RANGE * scales[sig], SWITCH_RANGE * scales[sig])
                    terms += [Term("damage", index, sig, g, 0.0, param, rng) for g in ("on_pos", "on_neg")]
    return terms
