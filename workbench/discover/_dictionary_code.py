"""The code each dictionary term becomes: the hook lines of a generated :class:`~plant.PhysicalEffect` for a set of
terms (:func:`hook_bodies`, :func:`hooks_source`), the states their delay lines carry (:func:`allocate_states`), and
the source of the one effect holding the whole dictionary (:func:`dictionary_source`) that the sensitivity batch
compiles once per machine. What the terms are (forms, signals, :class:`~workbench.discover._dictionary.Term`) lives in
:mod:`workbench.discover._dictionary`; the readable emitted file in :mod:`workbench.discover._effect_writer`.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from workbench.discover._dictionary import ALL_FORMS, GATE_FORMS, SIGNALS, Term, n_form_states
from workbench.discover._gates import (
    SIGN_GATES,
    SINCE_NEVER_S,
    WIDTH_CODE,
    WIDTH_GATES,
    contribution_lines,
    default_width,
    gate_code,
    gate_width,
    has_since,
    is_hinge,
    since_factor,
)


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
class TermSlot:
    """Where a term's numbers live in the generated effect: its coefficient at ``p[po + coef]``, its shape either
    a literal or ``p[po + shape_param]``, its delay state (if any) at ``x[so + state]``, a gate's width (a step's
    or a switch's edge, a ramp's settling time) either a literal (the term's fitted ``width``, else the gate's fixed
    one) or ``p[po + width_param]``, the instant a switched change began at (if any) either a literal (the term's
    found ``since``) or ``p[po + since_param]``."""

    term: Term
    coef: int
    shape_param: int | None = None
    state: int | None = None
    width_param: int | None = None
    since_param: int | None = None


def _lit(v: float) -> str:
    return repr(float(v))


def _value_code(slot: TermSlot) -> str:
    term = slot.term
    form = ALL_FORMS[term.form]
    g = f"p[po + {slot.shape_param}]" if slot.shape_param is not None else _lit(term.shape)
    s = SIGNALS[term.signal].code
    w = f"x[so + {slot.state}]" if slot.state is not None else "0.0"
    v = f"x[so + {slot.state + 1}]" if slot.state is not None and n_form_states(term.form) > 1 else "0.0"
    if slot.width_param is not None:
        h = f"p[po + {slot.width_param}]"
    elif term.form in GATE_FORMS:
        h = _lit(term.width if term.width != 0.0 else gate_width(term.form, SIGNALS[term.signal].unit))
    else:
        h = "0.0"
    code = gate_code(term.form, term.param, term.signal) if term.placement == "damage" else form.code
    if term.form in WIDTH_CODE and (slot.width_param is not None or term.width != 0.0):
        code = WIDTH_CODE[term.form]  # the edge (a step) or the saturation (a ramp) at a fitted width
    expr = code.replace("G", g).replace("W", w).replace("V", v).replace("H", h)
    expr = expr.replace("S", f"({s})")
    if slot.since_param is not None:
        expr = f"({expr}) * {since_factor(f'p[po + {slot.since_param}]')}"
    elif term.since is not None:
        expr = f"({expr}) * {since_factor(repr(float(f'{term.since:.10g}')))}"
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
            hinge = is_hinge(term.param, term.form, term.signal)
            for hook, lines in contribution_lines(term.param, term.index, value, hinge).items():
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


def width_name(k: int) -> str:
    """The dictionary effect's parameter for the edge width of term ``k`` (a form of
    :data:`~workbench.discover._gates.WIDTH_GATES`)."""
    return f"h_{k:02d}"


def width_unit(term: Term) -> str:
    """SI unit of ``term``'s width: its signal's for a switch, s for a step or a ramp."""
    return SIGNALS[term.signal].unit if term.form in SIGN_GATES else "s"


def term_default_width(term: Term) -> float:
    """The width ``term`` starts from in the dictionary (:func:`~workbench.discover._gates.default_width`)."""
    return default_width(term.form, width_unit(term))


def dictionary_width_names(terms: Sequence[Term]) -> dict[int, str]:
    """The edge-width parameter of every term whose width is fitted (dictionary index → name)."""
    return {k: width_name(k) for k, t in enumerate(terms) if t.form in WIDTH_GATES}


def since_name(k: int) -> str:
    """The dictionary effect's parameter for the instant term ``k``'s switched change began at (s)."""
    return f"s_{k:02d}"


def carries_since(term: Term) -> bool:
    """Whether ``term`` is a switched damage term that may begin at an instant of the record (its ``s_NN``)."""
    return term.placement == "damage" and has_since(term.param, term.form)


def since_placed(values: Mapping[str, float], k: int) -> bool:
    """Whether term ``k``'s switched change has been given an instant inside the record (not the default before any
    record)."""
    name = since_name(k)
    return name in values and values[name] > 0.5 * SINCE_NEVER_S


def dictionary_since_names(terms: Sequence[Term]) -> dict[int, str]:
    """The since-instant parameter of every term that may begin during the record (dictionary index → name)."""
    return {k: since_name(k) for k, t in enumerate(terms) if carries_since(t)}


def dictionary_source(terms: Sequence[Term], class_name: str = "DiscoveryDictionary",
                      effect_name: str = "discovery_dictionary") -> str:
    """Source of one effect holding every term: a coefficient per term (default 0 = neutral) and, for a shaped form,
    its shape as a parameter (placeholder default 1, a switching point's 0 and unbounded below; the workbench sets
    it per record). The source depends only on
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
            signed = term.form in SIGN_GATES  # a switching point: either side of zero
            early = term.form == "on_ramp"  # a ramp's onset may lie before the record (a loss under way at t = 0)
            params.append(f"        Parameter({gname!r}, {term.shape_unit!r}, {0.0 if signed else 1.0}, "
                          f"{'-math.inf' if signed or early else '0.0'}, math.inf, "
                          f"'shape of {term.key}'),")
        hi = None
        if term.form in WIDTH_GATES:
            hi = len(params)
            params.append(f"        Parameter({width_name(len(slots))!r}, {width_unit(term)!r}, "
                          f"{term_default_width(term)!r}, {'-math.inf' if term.form == 'on_ramp' else '1e-12'}, "
                          "math.inf, "
                          f"'edge width or saturation time of {term.key}'),")
        si = None
        if carries_since(term):
            si = len(params)
            params.append(f"        Parameter({since_name(len(slots))!r}, 's', {SINCE_NEVER_S!r}, -math.inf, "
                          f"math.inf, 'instant the switched change of {term.key} began'),")
        slots.append(TermSlot(term, ci, gi, allocate_states(term, specs), hi, si))
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
