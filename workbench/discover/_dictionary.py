"""The dictionary of candidate correction terms that ``shm discover`` searches, and the code each term becomes.

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
change while the gate is open, the gate's signal is the term's ``signal`` and its gap or onset time its ``shape``.

:func:`build_dictionary` lists the terms for a model and records; :func:`effect_source` writes the Python source of
a :class:`~plant.PhysicalEffect` holding a given set of terms (the whole dictionary for the sensitivity batch, or
the few chosen terms for the refit and the emitted file). :func:`form_values` evaluates a form on arrays (NumPy) for
scaling.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np

from workbench.discover._gates import (
    CONTRIBUTIONS,
    GAP_AT,
    GATED_BY,
    GATES,
    RAMP_AT,
    STEP_AT,
    contribution_lines,
    gate_values,
    gate_width,
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


def allocate_states(term: Term, specs: list[tuple[str, float]]) -> int | None:
    """Append the (unit, scale) of ``term``'s own states to ``specs`` (the effect's states so far) and return the
    index of its first state, or None when the term carries none."""
    n = n_form_states(term.form)
    if not n:
        return None
    first = len(specs)
    specs += [state_spec_args(term.signal)] * n
    return first


def state_spec_args(signal: str) -> tuple[str, float]:
    """(unit, typical magnitude) of a delay state following ``signal`` (the integrator's error scale)."""
    unit = SIGNALS[signal].unit
    return unit, {"m": 1e-4, "m/s": 1e-2, "V": 1.0}.get(unit, 1.0)


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
    out["one"] = Signal("one", "1.0", "1", "constant (a time gate's signal)")
    return out


SIGNALS = _signals()


@dataclass(frozen=True)
class Term:
    """One candidate correction: ``coefficient × form(signal)`` added at ``placement`` (mass/section ``index``,
    0-based; -1 when it does not apply). ``shape`` is the form's constant (SI, the signal's unit; for a delay, s).
    A damage term (placement ``damage``) is ``coefficient × contribution(param) × gate(signal)``, the gate being
    its form; ``shape_range`` is where the refit may move its shape (an onset time: linear), None for a factor
    of four either way."""

    placement: str
    index: int
    signal: str
    form: str
    shape: float = 0.0
    param: str = ""
    shape_range: tuple[float, float] | None = None

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
    voltage; gaps at :data:`~workbench.discover._gates.GAP_AT` of the deflection's scale; steps and ramps at onsets
    spanning the record (``scales["t"]``, the longest record's duration; no time gates without it)."""
    terms: list[Term] = []

    def ok(sig: str) -> bool:
        return scales.get(sig, 0.0) > 0.0

    duration = scales.get("t", 0.0)
    for param, con in CONTRIBUTIONS.items():
        for index in (range(3) if con.per != "patch" else (-1,)):
            for what in GATED_BY[param]:
                sig = {"own_delta": f"delta{index + 1}", "own_ddelta": f"ddelta{index + 1}",
                       "gap": f"delta{index + 1}"}.get(what, what)
                if what == "time":
                    if duration > 0:
                        terms += [Term("damage", index, "one", "on_step", t0, param, rng)
                                  for t0, rng in onsets(duration, STEP_AT)]
                        terms += [Term("damage", index, "one", "on_ramp", t0, param, rng)
                                  for t0, rng in onsets(duration, RAMP_AT)]
                elif what == "gap":
                    if ok(sig):
                        terms += [Term("damage", index, sig, "on_gap", f * scales[sig], param) for f in GAP_AT]
                elif ok(sig) and (driven or sig != "va"):
                    terms += [Term("damage", index, sig, g, 0.0, param) for g in ("on_pos", "on_neg")]
    return terms


# ----------------------------------------------------------------------------------------------------------------
# code generation


@dataclass(frozen=True)
class TermSlot:
    """Where a term's numbers live in the generated effect: its coefficient at ``p[po + coef]``, its shape either
    a literal or ``p[po + shape_param]``, its delay state (if any) at ``x[so + state]``."""

    term: Term
    coef: int
    shape_param: int | None = None
    state: int | None = None


def _lit(v: float) -> str:
    return repr(float(v))


def _value_code(slot: TermSlot) -> str:
    term = slot.term
    form = ALL_FORMS[term.form]
    g = f"p[po + {slot.shape_param}]" if slot.shape_param is not None else _lit(term.shape)
    s = SIGNALS[term.signal].code
    w = f"x[so + {slot.state}]" if slot.state is not None else "0.0"
    v = f"x[so + {slot.state + 1}]" if slot.state is not None and n_form_states(term.form) > 1 else "0.0"
    h = _lit(gate_width(term.form, SIGNALS[term.signal].unit)) if term.form in GATE_FORMS else "0.0"
    expr = form.code.replace("G", g).replace("W", w).replace("V", v).replace("H", h)
    expr = expr.replace("S", f"({s})")
    return f"p[po + {slot.coef}] * ({expr})"


def hook_bodies(slots: Sequence[TermSlot], guard: bool = False) -> dict[str, list[str]]:
    """Body lines (8-space indented) of the ``pre``, ``rates`` and ``output`` hooks for ``slots`` (``guard``: skip a
    term whose coefficient is 0 — its delay states too: they stay at 0, so the dictionary's many fast delay lines
    (poles up to ~1 700 rad/s) do not limit the step of every simulation where they are off; switched on, a state
    starts from 0 at t = 0 exactly as in the emitted effect)."""
    bodies: dict[str, list[str]] = {"pre": [], "rates": [], "post": [], "output": []}
    for slot in slots:
        term = slot.term
        value = _value_code(slot)
        state_lines = []
        if slot.state is not None and term.form == "delay2":  # w1' = w2, w2' = 12 (s − w1 − T w2 / 2) / T²
            g = (f"max(p[po + {slot.shape_param}], 1e-4)" if slot.shape_param is not None
                 else _lit(max(term.shape, 1e-4)))
            s = SIGNALS[term.signal].code
            w1, w2 = f"x[so + {slot.state}]", f"x[so + {slot.state + 1}]"
            state_lines = [f"dx[so + {slot.state}] += {w2}",
                           f"dx[so + {slot.state + 1}] += 12.0 * (({s}) - {w1} - 0.5 * {g} * {w2}) / ({g} * {g})"]
        elif slot.state is not None:  # the first-order Padé delay's state: dw/dt = (s − w)/(τ/2)
            g = f"p[po + {slot.shape_param}]" if slot.shape_param is not None else _lit(term.shape)
            s = SIGNALS[term.signal].code
            state_lines = [f"dx[so + {slot.state}] += (({s}) - x[so + {slot.state}]) / (0.5 * max({g}, 1e-4))"]
        if state_lines:
            if guard:
                bodies["rates"].append(f"        if p[po + {slot.coef}] != 0.0:")
                bodies["rates"].extend("            " + ln for ln in state_lines)
            else:
                bodies["rates"].extend("        " + ln for ln in state_lines)
        if term.placement == "damage":
            for hook, lines in contribution_lines(term.param, term.index, value).items():
                if guard:
                    bodies[hook].append(f"        if p[po + {slot.coef}] != 0.0:")
                    bodies[hook].extend("            " + ln for ln in lines)
                else:
                    bodies[hook].extend("        " + ln for ln in lines)
            continue
        if term.placement == "force_mass":
            hook, lines = "rates", [f"bus[B_FM + {term.index}] += {value}"]
        elif term.placement == "force_section":
            hook, lines = "rates", [f"bus[B_S + {term.index}] += {value}"]
        elif term.placement == "current":
            hook, lines = "rates", ["for i in range(3):", f"    dx[X_Q + i] += {value}"]
        elif term.placement == "drive":
            hook, lines = "pre", [f"bus[B_VA] += {value}"]
        elif term.placement == "measurement":
            hook, lines = "output", [f"y[Y_Z3_MEAS] += {value}"]
        else:
            raise KeyError(term.placement)
        if guard:
            bodies[hook].append(f"        if p[po + {slot.coef}] != 0.0:")
            bodies[hook].extend("            " + ln for ln in lines)
        else:
            bodies[hook].extend("        " + ln for ln in lines)
    return bodies


HEADER_IMPORTS = (
    "import math\n\n"
    "from plant.effect import Parameter, PhysicalEffect, StateSpec\n"
    "from plant.layout import (\n"
    "    B_FM, B_IR, B_QH, B_S, B_VA, B_VA_DEMAND, B_VC, B_Z, B_Z0DD, B_ZD, P_ALPHA_H, P_BETA_H, P_C, P_C_EP, P_D_EP,\n"
    "    P_K, P_N_H, P_R_EP, X_DDELTA, X_DELTA, X_H, X_Q, Y_Z3_MEAS,\n"
    ")\n"
)


#: core slots of plant.layout as the generated code names them -> the slot-table name of the documented seam
_LAYOUT_TO_TABLE = {"B_Z": ("B", "z"), "B_ZD": ("B", "zd"), "B_FM": ("B", "fm"), "B_S": ("B", "s"),
                    "B_VC": ("B", "vc"), "X_DELTA": ("X", "delta"), "X_DDELTA": ("X", "ddelta"), "X_Q": ("X", "q"),
                    "B_QH": ("B", "qh"), "B_IR": ("B", "ir"), "X_H": ("X", "hq"), "P_K": ("P", "k"),
                    "P_C": ("P", "c")}
_LAYOUT_SCALARS = {"B_VA_DEMAND": "B.va_demand", "B_VA": "B.va", "Y_Z3_MEAS": "Y.z3_meas", "B_Z0DD": "B.z0dd",
                   "P_D_EP": "P.d_ep", "P_C_EP": "P.C_ep", "P_R_EP": "P.R_ep", "P_ALPHA_H": "P.alpha_h",
                   "P_BETA_H": "P.beta_h", "P_N_H": "P.n_h"}


def _named(code: str, parameter_names: Sequence[str], state_names: Sequence[str]) -> str:
    """``code`` written against plant.layout and the offsets (``p[po + k]``, ``x[so + k]``) rewritten in the slot
    tables of the documented seam: ``p[P.name]``, ``x[X.name]``, ``bus[B.z3]``, ``dx[X.q1 + i]``, ``y[Y.z3_meas]``."""
    code = re.sub(r"p\[po \+ (\d+)\]", lambda m: f"p[P.{parameter_names[int(m.group(1))]}]", code)
    code = re.sub(r"x\[so \+ (\d+)\]", lambda m: f"x[X.{state_names[int(m.group(1))]}]", code)

    def block(m: re.Match[str]) -> str:
        table, stem = _LAYOUT_TO_TABLE[m.group(1)]
        index = m.group(2)
        return f"{table}.{stem}{int(index) + 1}" if index.isdigit() else f"{table}.{stem}1 + {index}"

    code = re.sub(r"\b(" + "|".join(_LAYOUT_TO_TABLE) + r") \+ (\w+)", block, code)
    return re.sub(r"\b(" + "|".join(_LAYOUT_SCALARS) + r")\b", lambda m: _LAYOUT_SCALARS[m.group(1)], code)


def hooks_source(slots: Sequence[TermSlot], guard: bool = False, *, parameter_names: Sequence[str] | None = None,
                 state_names: Sequence[str] = ()) -> str:
    """The hook methods (class-body indentation) for ``slots``: with ``parameter_names`` (every parameter of the
    effect, in order) in the documented named seam (``rates(t, x, p, bus, dx, X, P, B)``, ``p[P.name]``,
    ``bus[B.z3]``), else in the offsets form the compiled dictionary uses (``p[po + k]``)."""
    bodies = hook_bodies(slots, guard)
    parts = []
    for name, lines in bodies.items():
        if not lines:
            continue
        if parameter_names is None:
            sig = "t, x, p, bus, y, so, po, yo" if name == "output" else "t, x, p, bus, dx, so, po"
            code = "\n".join(lines)
        else:
            sig = "t, x, p, bus, y, X, P, B, Y" if name == "output" else "t, x, p, bus, dx, X, P, B"
            code = _named("\n".join(lines), parameter_names, state_names)
        parts.append(f"    @staticmethod\n    def {name}({sig}):\n" + code + "\n")
    return "\n".join(parts)


def dictionary_parameter_names(terms: Sequence[Term]) -> list[tuple[str, str | None]]:
    """(coefficient name, shape name or None) of every term in the dictionary effect, in order."""
    return [(f"a_{k:02d}", f"g_{k:02d}" if ALL_FORMS[t.form].shape else None) for k, t in enumerate(terms)]


def dictionary_source(terms: Sequence[Term], class_name: str = "DiscoveryDictionary",
                      effect_name: str = "discovery_dictionary") -> str:
    """Source of one effect holding every term: a coefficient per term (default 0 = neutral) and, for a shaped form,
    its shape as a parameter (placeholder default 1; the workbench sets it per record). The source depends only on
    the terms' structure (placement, index, signal, form), so the compiled kernel is cached across records and
    runs; a term whose coefficient is 0 is skipped at run time."""
    slots: list[TermSlot] = []
    params: list[str] = []  # source lines
    specs: list[tuple[str, float]] = []  # (unit, scale) of each state
    for term, (cname, gname) in zip(terms, dictionary_parameter_names(terms)):
        ci = len(params)
        params.append(f"        Parameter({cname!r}, {term.unit!r}, 0.0, -math.inf, math.inf, {term.key!r}),")
        gi = None
        if gname is not None:
            gi = len(params)
            params.append(f"        Parameter({gname!r}, {term.shape_unit!r}, 1.0, 0.0, math.inf, "
                          f"'shape of {term.key}'),")
        slots.append(TermSlot(term, ci, gi, allocate_states(term, specs)))
    states = "\n".join(f"        StateSpec('w_{k}', {u!r}, {sc!r})," for k, (u, sc) in enumerate(specs))
    return (
        '"""Generated by workbench.discover._dictionary: every candidate term of shm discover (not for editing)."""\n\n'
        + HEADER_IMPORTS + "\n\n"
        f"class {class_name}(PhysicalEffect):\n"
        f"    name = {effect_name!r}\n"
        "    description = 'shm discover: the candidate correction terms'\n"
        "    parameters = (\n" + "\n".join(params) + "\n    )\n"
        + ("    states = (\n" + states + "\n    )\n" if specs else "")
        + "\n" + hooks_source(slots, guard=True)
    )
