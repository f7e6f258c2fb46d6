"""Words and code for discovered terms: what a fitted term means physically (:func:`describe_term`), and the readable
:class:`~plant.PhysicalEffect` module ``shm discover --emit`` writes (:func:`emit_effect_source`).

The emitted module holds the chosen terms of :mod:`workbench.discover._dictionary` as one effect: a coefficient per
term (``c_<term>``, default 0 = the nominal model) and, for a term with a threshold, saturation level or delay, that
shape as a parameter too (``g_<term>``). Its docstring gives the formula with units; ``origin`` and ``signature``
say what was found on which records; ``guess`` starts a fit (``shm fit --add FILE.py``) at the discovered values;
each parameter's ``fit`` range says where to search (and a coefficient's ``neutral`` 0 switches its term off).
"""

from __future__ import annotations

import datetime as _dt
import math
import textwrap
from collections.abc import Callable, Mapping, Sequence

from workbench.discover._dictionary import ALL_FORMS, DELAY_FORMS, FORMS, SIGNALS, Term
from workbench.discover._dictionary_code import TermSlot, allocate_states, hooks_source
from workbench.discover._gate_words import describe_damage
from workbench.discover._gates import (
    SIGN_GATES,
    SWITCH_RANGE,
    TIME_GATES,
    class_stem,
    damage_formula,
    gate_width,
)


def _si(x: float, unit: str) -> str:
    """A readable quantity: mN/µN for forces, µm/mm for lengths, ms for seconds, mA/µA for currents."""
    a = abs(x)
    if unit == "N":
        return f"{x * 1e3:.3g} mN" if a >= 1e-4 else f"{x * 1e6:.3g} µN"
    if unit == "m":
        return f"{x * 1e3:.3g} mm" if a >= 1e-3 else f"{x * 1e6:.3g} µm"
    if unit == "s":
        return f"{x * 1e3:.3g} ms" if a < 1 else f"{x:.3g} s"
    if unit == "A":
        return f"{x * 1e3:.3g} mA" if a >= 1e-4 else f"{x * 1e6:.3g} µA"
    return f"{x:.3g} {unit}".strip()


def _mass(j: int) -> str:
    return f"mass {j + 1}" + (" (the tip)" if j == 2 else " (the root)" if j == 0 else "")


def _describe_force(term: Term, c: float, g: float, scale: float) -> str | None:
    """A force on a mass or in a section, by form (None: a form with no words of its own)."""
    j, p, f = term.index, term.placement, term.form
    u = SIGNALS[term.signal].unit
    where = _mass(j) if p == "force_mass" else f"section {j + 1}"
    what = "force on " + where if p == "force_mass" else "force in " + where
    rate_word = "velocity" if p == "force_mass" else "deformation rate"
    disp = f"z{j + 1}" if p == "force_mass" else f"δ{j + 1}"
    if f == "sign":
        tail = ": dry (Coulomb) friction" + (" at the tip" if (j == 2 and p == "force_mass") else
                                             f" at {where}")
        return (f"a {what} of {_si(abs(c), 'N')} {'opposing' if c < 0 else 'along'} its {rate_word}, independent "
                f"of speed{tail if c < 0 else ' (an energy source: suspicious)'}")
    if f == "absx":
        return (f"a {what} growing with the square of its {rate_word}, F = {c:.3g} N·s²/m² · |v|·v "
                f"({_si(abs(c) * scale ** 2, 'N')} at {scale:.3g} m/s)"
                + (": quadratic (air or squeeze-film) drag" if c < 0 else ": negative drag (suspicious)"))
    if f == "lin" and u == "m/s":
        return (f"a viscous {what} {'opposing' if c < 0 else 'along'} its {rate_word}, {abs(c):.3g} N·s/m: "
                + ("extra damping" if c < 0 else "less damping than modelled"))
    if f == "lin":
        return (f"a linear {what} of {abs(c):.3g} N/m × {disp}: "
                + ("a spring to the frame (stiffer than modelled)" if c < 0 else "softer than modelled"))
    if f == "cube":
        return (f"a cubic {what}, F = {c:.3g} N/m³ · {disp}³ ({_si(abs(c) * scale ** 3, 'N')} at "
                f"{_si(scale, 'm')}): " + ("hardening" if c < 0 else "softening") + " with deflection")
    if f == "square":
        return (f"a {what} growing with the square of its displacement, {c:.3g} N/m² · {disp}², the same sign on "
                f"both sides ({_si(c * scale ** 2, 'N')} at {_si(scale, 'm')}): a sign-asymmetric stiffness "
                f"(the response is {'smaller' if c < 0 else 'larger'} for positive than for negative deflection)")
    if f in ("pos", "neg"):
        side = f"{disp} > {_si(g, 'm')}" if f == "pos" else f"{disp} < {_si(-g, 'm')}"
        return (f"a one-sided {what} of {abs(c):.3g} N/m acting only when {side}: "
                + ("contact with a stop (one-sided stiffness)" if c < 0 else "a support that lets go"))
    if f == "dead":
        return (f"a {what} of {abs(c):.3g} N/m acting only beyond ±{_si(g, 'm')} of {disp} (a dead zone): "
                + ("a clearance that closes — stiffer at large deflection" if c < 0 else
                   "softer at large deflection"))
    if f == "clip":
        return (f"{where} is {'softer' if c > 0 else 'stiffer'} by {abs(c):.3g} N/m within ±{_si(g, 'm')} of "
                f"{disp} and as modelled beyond: "
                + ("a clearance / free play in its joint (dead zone of the stiffness)" if c > 0 else
                   "a preload or stiction band"))
    return None


def _describe_current(term: Term, c: float, g: float, scale: float) -> str | None:
    """A current into the patch charges: a leakage, linear or not."""
    f = term.form
    if f == "lin":
        return (f"a current {'out of' if c < 0 else 'into'} each patch of {abs(c):.3g} S × patch voltage: "
                + ("a leakage conductance" if c < 0 else "negative leakage (suspicious)"))
    return (f"a current into each patch growing with the {'square' if f == 'absx' else 'cube'} of the patch "
            f"voltage ({_si(c * scale ** FORMS[f].power, 'A')} at {scale:.3g} V): a nonlinear leakage")


def _describe_drive(term: Term, c: float, g: float, scale: float) -> str | None:
    """A change of the drive the patches see, by form (None: a form with no words of its own)."""
    f = term.form
    if f in DELAY_FORMS:
        return (f"a transport delay of {_si(c * g, 's')} on the drive: the patches see the commanded voltage "
                "late (amplifier/controller latency)")
    if f in ("pos", "neg"):
        side = "positive" if f == "pos" else "negative"
        return (f"a drive gain that depends on the drive's sign: {100 * c:+.3g} % more authority for {side} drive "
                f"(beyond {g:.3g} V) than for the other side (sign-asymmetric: polarisation-dependent piezo "
                "coefficient or a one-sided amplifier)")
    if f == "square":
        pct = 100 * c * 100.0
        return (f"a drive gain that depends on the drive's sign: {pct:+.3g} % per +100 V of drive, so the response "
                f"is larger for {'positive' if c > 0 else 'negative'} drive (sign-asymmetric: polarisation-"
                "dependent piezo coefficient or a one-sided amplifier)")
    if f == "cube":
        return (f"a drive gain changing with the drive amplitude: {100 * c * scale ** 2:+.3g} % at "
                f"{scale:.3g} V")
    if f == "sat":
        return (f"the drive saturates: the patches see at most about {g:.3g} V ({100 * c:.3g} % of the "
                "saturation applied; amplifier or depolarisation limit)")
    if f == "time":
        return (f"the drive gain drifts by {100 * c:+.3g} %/s during the test (a coupling that changes with time: "
                "temperature, amplifier gain)")
    return None


def _describe_measurement_form(term: Term, c: float, g: float, scale: float) -> str | None:
    """A change of the laser reading alone, by signal and form, without the closing words."""
    f = term.form
    if term.signal == "one":
        if f == "time":
            return f"a laser zero drifting by {_si(c, 'm')}/s"
        return f"a laser offset of {_si(c, 'm')}"
    if term.signal == "zd3":
        return f"a laser lag of {_si(-c, 's')} (reading ≈ z3 − τ ż3)"
    if f in DELAY_FORMS:
        kind = ("a delay" if abs(c - 1.0) < 0.25 else
                "a first-order low-pass" if abs(c - 0.5) < 0.15 and f == "delay" else "a delay or low-pass")
        return (f"a laser lag of {_si(c * g, 's')}: the reading follows the tip late ({kind} in the sensor "
                f"chain: the laser's filter or the acquisition's timing; Padé time constant {_si(g, 's')}, "
                f"{100 * c:.3g} % applied)")
    if f == "lin":
        return f"a laser gain error of {100 * c:+.3g} %"
    if f == "square":
        return (f"a quadratic laser nonlinearity: reading += {c:.3g} 1/m · z3² ({_si(c * scale ** 2, 'm')} at "
                f"{_si(scale, 'm')})")
    if f == "cube":
        return (f"a cubic laser nonlinearity: reading += {c:.3g} 1/m² · z3³ ({_si(c * scale ** 3, 'm')} at "
                f"{_si(scale, 'm')})" + (": the reading falls short at large deflection, the onset of "
                                         "saturation" if c < 0 else ""))
    if f == "sat":
        return f"the laser reading saturates at about {_si(g, 'm')} ({100 * c:.3g} % of it applied)"
    if f == "time":
        return f"a laser gain drifting by {100 * c:+.3g} %/s"
    return None


def _describe_measurement(term: Term, c: float, g: float, scale: float) -> str | None:
    """A change of the laser reading alone (the physics unchanged)."""
    words = _describe_measurement_form(term, c, g, scale)
    return None if words is None else words + " (measurement only: the physics is unchanged)"


#: the words of a fitted term, one describer per placement (damage forms are described by
#: :func:`~workbench.discover._gates.describe_damage`)
_DESCRIBERS: dict[str, Callable[[Term, float, float, float], str | None]] = {
    "force_mass": _describe_force,
    "force_section": _describe_force,
    "current": _describe_current,
    "drive": _describe_drive,
    "measurement": _describe_measurement,
}


def describe_term(term: Term, coef: float, shape: float, scale: float, shape_se: float | None = None,
                  since_se: float | None = None) -> str:
    """One sentence: what the fitted term is, in words, numbers and units (``scale``: the signal's 99th percentile
    of |value| along the records, SI; ``shape_se``: the shape's standard error, said with an onset time;
    ``since_se``: that of the instant a switched change began at, ``term.since``)."""
    c, g = float(coef), float(shape)
    if term.placement == "damage":
        return describe_damage(term.param, term.index, term.form, term.signal, c, g, shape_se, term.width,
                               term.since, since_se)
    describer = _DESCRIBERS.get(term.placement)
    words = describer(term, c, g, scale) if describer is not None else None
    return words if words is not None else f"{c:.3g} {term.unit} × {term.form}({term.signal})"


def formula(term: Term, cname: str, gname: str | None) -> str:
    """The term as a formula in words-free notation (for the docstring)."""
    if term.placement == "damage":
        return damage_formula(term.param, term.index, term.form, term.signal, cname, gname, term.width,
                              term.since)
    s = {"one": "1"}.get(term.signal, term.signal)
    code = FORMS[term.form].code
    g = gname or "g"
    expr = (code.replace("math.tanh", "tanh").replace("G", g).replace("W", "w").replace("S", s)
            .replace("abs(", "|").replace(") * " + s, "|·" + s) if term.form == "absx" else
            code.replace("math.tanh", "tanh").replace("G", g).replace("W", "w").replace("S", s))
    target = {"force_mass": f"F_m{term.index + 1} (N, force on mass {term.index + 1})",
              "force_section": f"S_{term.index + 1} (N, force in section {term.index + 1})",
              "current": "dq_i/dt (A, every patch couple i)", "drive": "v_a (V, the voltage the patches see)",
              "measurement": "z3_meas (m, what the laser reports)"}[term.placement]
    extra = ""
    if term.form == "delay":
        extra = f"   with dw/dt = ({s} − w)/({g}/2)  (first-order Padé delay of {g})"
    elif term.form == "delay2":
        expr = f"−{g} · w2"
        extra = (f"   with dw1/dt = w2, dw2/dt = 12 ({s} − w1 − {g} w2 / 2) / {g}²  (second-order Padé delay of "
                 f"{g})")
    return f"{target} += {cname} · {expr}{extra}"


def class_name_for(terms: Sequence[Term]) -> str:
    t = terms[0]
    if t.placement == "damage":
        return f"Discovered{class_stem(t.param, t.index, t.form, t.signal)}" + ("Plus" if len(terms) > 1 else "")
    base = {"force_mass": f"Mass{t.index + 1}", "force_section": f"Section{t.index + 1}", "current": "Patch",
            "drive": "Drive", "measurement": "Laser"}[t.placement]
    form = {"sign": "Friction", "absx": "Drag", "lin": "Linear", "cube": "Cubic", "square": "Quadratic",
            "pos": "ContactAbove", "neg": "ContactBelow", "dead": "DeadZone", "clip": "Clearance",
            "sat": "Saturation", "time": "Drift", "delay": "Delay", "delay2": "Delay"}[t.form]
    return f"Discovered{base}{form}" + ("Plus" if len(terms) > 1 else "")


def emit_effect_source(terms: Sequence[Term], values: Mapping[str, float], *, class_name: str | None = None,
                       effect_name: str = "discovered", words: Sequence[str] = (), records: Sequence[str] = (),
                       held_before: float | None = None, held_after: float | None = None,
                       free_shapes: bool = True) -> str:
    """The Python source of a readable effect holding ``terms`` with the fitted ``values`` (by parameter name,
    see :func:`parameter_names_for`)."""
    slots: list[TermSlot] = []
    params: list[str] = []  # source lines
    discovered: dict[str, float] = {}
    names: list[str] = []  # every parameter's name, in order
    state_specs: list[tuple[str, float]] = []  # (unit, scale) of each state
    formulas = []
    for term, (cname, gname) in zip(terms, parameter_names_for(terms, free_shapes)):
        k = len(params)
        c = _r(float(values.get(cname, 0.0)))
        span = abs(c) if c != 0.0 else 1.0  # a coefficient of 0 (a term switched off): a unit range around it
        lo, hi = _r(min(0.0, -20 * span if c < 0 else -span)), _r(max(0.0, 20 * span if c > 0 else span))
        names.append(cname)
        a, b = sorted((_r(c * 0.2), _r(c * 3.0))) if c != 0.0 else (-span, span)
        params.append(f"        Parameter({cname!r}, {term.unit!r}, 0.0, {lo!r}, {hi!r},\n"
                      f"                  {('coefficient of ' + term.key)!r},\n"
                      f"                  neutral=0.0, fit=FitRange({a!r}, {b!r})),")
        discovered[cname] = c
        shape_idx = None
        if gname is not None:
            g = float(values.get(gname, term.shape))
            # an onset to ten digits: a sharp step's timing is its fit (4.49876 s: a file's 1.518 σ, not 1.474)
            g = float(f"{g:.10g}") if term.form in TIME_GATES else _r(g)
            shape_idx = len(params)
            names.append(gname)
            params.append(_shape_parameter(term, gname, g))
            discovered[gname] = g
        slots.append(TermSlot(term, k, shape_idx, allocate_states(term, state_specs)))
        formulas.append(formula(term, cname, gname))
    cls = class_name or class_name_for(terms)
    what = "; ".join(words) if words else ", ".join(t.key for t in terms)
    score = ""
    if held_before is not None and held_after is not None:
        score = f"held-out error {held_before:.4g} σ → {held_after:.4g} σ"
    what_lines = textwrap.wrap(what[0].upper() + what[1:] + ".", 110)
    doc = ['"""' + "\n".join(what_lines), "",
           "Found by `shm discover` (mfc-shm) on " + (", ".join(records) or "the records") + f" ({score})."
           if score else "Found by `shm discover` (mfc-shm).", "",
           "Formula (SI units; signals as in docs/model.md: z_j displacement of mass j relative to the base, m; "
           "δ_i deformation of section i, m; v_a drive voltage, V; t time from the record's start, s):", ""]
    doc = [*doc[:4], *textwrap.wrap(doc[4], 110), *doc[5:]]
    doc += [f"    {f}" for f in formulas]
    doc += ["", "Coefficients default to 0 (the nominal model); `guess` starts a fit at the discovered values.",
            f"Written {_dt.datetime.now(_dt.UTC).strftime('%Y-%m-%d %H:%M UTC')}. Edit freely: it is an "
            "ordinary effect (docs/effects.md).", '"""']
    states = "".join(f"        StateSpec('w_delay_{k}', {u!r}, {sc!r}),\n" for k, (u, sc) in enumerate(state_specs))
    hooks = hooks_source(slots, parameter_names=names, state_names=[f"w_delay_{k}" for k in range(len(state_specs))])
    effect_names = "Parameter, PhysicalEffect" + (", StateSpec" if state_specs else "")
    imports = (("import math\n\n" if "math." in hooks else "")
               + f"from plant.effect import {effect_names}\n"
               "from plant.effects.library_support import FitRange\n")
    body = (
        "\n".join(doc) + "\n\nfrom __future__ import annotations\n\n"
        + imports + "\n\n"
        f"class {cls}(PhysicalEffect):\n"
        '    """' + "\n    ".join(textwrap.wrap(what[0].upper() + what[1:] + ".", 110)) + '"""\n\n'
        f"    name = {effect_name!r}\n"
        f"    description = {('Discovered: ' + what)!r}\n"
        f"    origin = {('shm discover on ' + (', '.join(records) or 'records') + (': ' + score if score else ''))!r}\n"
        f"    signature = {('its absence leaves: ' + what)!r}\n"
        "    parameters = (\n" + "\n".join(params) + "\n    )\n"
        + ("    states = (\n" + states + "    )\n" if state_specs else "")
        + f"    DISCOVERED = {discovered!r}\n\n"
        "    @classmethod\n"
        "    def guess(cls, data=None):\n"
        '        """Start a fit at the values shm discover found."""\n'
        "        return dict(cls.DISCOVERED)\n\n"
        + hooks
    )
    return body


def _r(x: float) -> float:
    """Six significant digits: readable, and far below what the data determine."""
    return float(f"{x:.6g}")


def _switch_range(term: Term, g: float) -> tuple[float, float]:
    """Where a sign gate's switching point ``g`` may lie: its term's refit range (± the signal's scale × 0.8 around
    0), else a range from the gate's width (10⁴ widths: 1 mm, 0.1 m/s, 100 V) — either way reaching ``g``."""
    if term.shape_range is not None:
        lo, hi = term.shape_range
    else:
        half = 1e4 * gate_width(term.form, SIGNALS[term.signal].unit) / SWITCH_RANGE
        lo, hi = -half, half
    return min(lo, g), max(hi, g)


def _shape_parameter(term: Term, gname: str, g: float) -> str:
    """The source line of a term's shape parameter: bounds a factor of 20 either way, an onset time from 0 (a ramp's
    onset placed before the record: from ten times its refit range before it) to ten times its refit range past it, a
    switching point its refit range widened by its width either way.

    An onset time is fitted only when asked (``fit_by_default=False``; ``shm fit --free g_…``): ``shm discover``
    placed it on the whole record, held-out blocks too, and half the instants an event can happen at lie in a
    held-out block, where the training error cannot see it — section 1 lost 20 % at 10.0 s of MBIT.a (20 s, a
    held-out block from 10 to 12 s): discovered at 10.01 s, 1.04 σ held out; the file's refit on the training blocks
    moved it to 10.55 s (training 0.98 σ) and left 11.5 σ held out."""
    if term.form in TIME_GATES:
        lo, hi = term.shape_range or (0.0, max(g, 1.0))
        early = min(g, lo)  # an onset placed before the record (a ramp begun before it) may move further back
        bounds = (0.0 if early >= 0.0 else _r(early - 10 * (hi - lo)), _r(max(g, hi) + 10 * (hi - lo)))
        unit = "s"
    elif term.form in SIGN_GATES:
        lo, hi = _switch_range(term, g)
        bounds = (_r(lo - (hi - lo)), _r(hi + (hi - lo)))
        unit = SIGNALS[term.signal].unit
    else:
        bounds = (_r(g / 20), _r(g * 20))
        unit = "s" if term.form in DELAY_FORMS else SIGNALS[term.signal].unit
    what = ALL_FORMS[term.form].shape + " of " + term.key
    on_request = ""
    if term.form in TIME_GATES:  # placed on the whole record: a refit on the training blocks alone cannot see it
        what += f" (placed by shm discover on the whole record; --free {gname} refits it)"
        on_request = ", fit_by_default=False"
    return (f"        Parameter({gname!r}, {unit!r}, {g!r}, {bounds[0]!r}, {bounds[1]!r},\n"
            f"                  {what!r},\n"
            f"                  fit={_shape_fit_range(term, g)}{on_request}),")


def _shape_fit_range(term: Term, g: float) -> str:
    """The ``FitRange`` a refit of the emitted file searches a shape over: around the discovered value, an onset time
    linearly (a quarter of its term's refit range either way, within the record), a switching point linearly (a
    quarter of its range either way), a gap or delay in log."""
    if term.form in TIME_GATES:
        lo, hi = term.shape_range or (0.0, max(2 * g, 1.0))
        half = max(0.25 * (hi - lo), 1e-3)  # within the record, or before it for an onset placed there
        return f"FitRange({_r(max(g - half, min(lo, 0.0)))!r}, {_r(g + half)!r})"
    if term.form in SIGN_GATES:  # a switching point, either sign: linearly, a quarter of its range either way
        lo, hi = _switch_range(term, g)
        half = 0.25 * (hi - lo)
        return f"FitRange({_r(g - half)!r}, {_r(g + half)!r})"
    lo_g, hi_g = (_r(g / 10), _r(g * 2)) if term.form == "sign" else (_r(g / 4), _r(g * 4))
    return f"FitRange({lo_g!r}, {hi_g!r}, log=True)"


def parameter_names(term: Term, free_shapes: bool = True, suffix: str = "") -> tuple[str, str | None]:
    """(coefficient name, shape name or None) of ``term`` in a refit/emitted effect."""
    g = None
    if free_shapes and ALL_FORMS[term.form].shape:
        g = f"g_{term.key}{suffix}"
    return f"c_{term.key}{suffix}", g


def parameter_names_for(terms: Sequence[Term], free_shapes: bool = True) -> list[tuple[str, str | None]]:
    """(coefficient name, shape name or None) of each of ``terms`` in one emitted effect: unique also when two terms
    share a key (the same form at two thresholds — a stop found twice on MBIT.a gave two ``c_m3_neg_z3`` and a file
    ``shm fit --add`` refused: "parameter declared twice"); the second of a key is ``c_<key>_2``, and so on."""
    seen: dict[str, int] = {}
    out = []
    for term in terms:
        seen[term.key] = seen.get(term.key, 0) + 1
        out.append(parameter_names(term, free_shapes, "" if seen[term.key] == 1 else f"_{seen[term.key]}"))
    return out


def typical_force(term: Term, coef: float, scale: float) -> float:
    """|coefficient × form| at the signal's scale (SI of the placement), for ranking words by size."""
    f = ALL_FORMS[term.form]
    return abs(coef) * (scale ** f.power if f.power else 1.0) if math.isfinite(coef) else float("nan")
