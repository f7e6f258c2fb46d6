"""Words for a damage term of ``shm discover``'s dictionary (:mod:`workbench.discover._gates`): one sentence in an
engineer's words for a core parameter's contribution switched by a gate (:func:`describe_damage`) and for a change
over a finite time (:func:`describe_finite_change`) — what the verdict and the emitted file say."""

from __future__ import annotations

import math

from workbench.discover._gates import (
    CONTRIBUTIONS,
    GROW_GATES,
    SAT_GATES,
    SIGN_GATES,
    SOFT_GATES,
    SQUARE_GATES,
    STEP_WIDTH_S,
)


def _switch_value(signal: str, g: float) -> str:
    """A switching point in the signal's unit, signed: '0.3 mm', '−12 µm', '+60 V', '4.2 mm/s'."""
    sign = "−" if g < 0 else ""
    if signal.startswith("ddelta"):
        return f"{sign}{abs(g) * 1e3:.3g} mm/s"
    if signal.startswith("delta") or _is_position(signal):
        return sign + (f"{abs(g) * 1e3:.3g} mm" if abs(g) >= 1e-4 else _length(abs(g)))
    if signal in ("va", "vc"):
        return f"{'−' if g < 0 else '+'}{abs(g):.3g} V"
    if signal == "ic":
        return f"{'−' if g < 0 else '+'}{abs(g) * 1e3:.3g} mA"
    return f"{g:.3g}"


def _is_position(signal: str) -> bool:
    """A mass's displacement (z1 … z3; not its velocity)."""
    return signal.startswith("z") and not signal.startswith("zd")


def _condition(form: str, signal: str, g: float = 0.0) -> str:
    """The gate's condition after 'for' or 'while': 'δ2 > 0', 'δ2 > 0.3 mm', 'negative drive', 'the drive is
    below +60 V' (``g``: the switching point, 0 unless it is named)."""
    positive = form.startswith("on_pos")
    op = ">" if positive else "<"
    at = "0" if g == 0.0 else _switch_value(signal, g)
    if signal.startswith("ddelta"):
        return f"δ̇{signal[-1]} {op} {at}"
    if signal.startswith("delta"):
        return f"δ{signal[-1]} {op} {at}"
    if _is_position(signal):
        where = "the tip" if signal == "z3" else f"mass {signal[-1]}"
        return f"{where} is {'above' if positive else 'below'} {at} ({signal} {op} {at})"
    if signal in ("va", "vc"):
        what = "drive" if signal == "va" else "patch voltage (charge)"
        if g == 0.0:
            return f"{'positive' if positive else 'negative'} {what}"
        return f"the {what} is {'above' if positive else 'below'} {at}"
    if signal == "ic":
        if g == 0.0:
            sense = "positive (the charge rising" if positive else "negative (the charge falling"
            return f"its charging current is {sense}, i_c {op} 0)"
        return f"its charging current is {'above' if positive else 'below'} {at} (i_c {op} {at})"
    return f"{signal} {op} {at}"


def named_switch(shape: float, shape_se: float | None) -> float:
    """The switching point to say in words: ``shape`` when it is away from 0 by more than twice its standard error
    (or has none), else 0 (the gate switches at the signal's sign)."""
    if shape == 0.0 or not math.isfinite(shape):
        return 0.0
    if shape_se is None or not math.isfinite(shape_se):
        return shape
    return shape if abs(shape) > 2.0 * shape_se else 0.0


def _describe_sign(param: str, index: int, form: str, signal: str, coef: float, g: float) -> str:
    """Words for a sign gate switching at ``g`` (0: at the signal's sign)."""
    n = index + 1
    what = CONTRIBUTIONS[param].what.format(n=n)
    pct = f"{100 * abs(coef):.3g} %"
    lower = coef < 0
    lh = "lower" if lower else "higher"
    cond = _condition(form, signal, g)
    when = "while" if (g != 0.0 and signal in ("va", "vc")) or signal == "ic" else "for"
    if param == "k" and signal.startswith("delta"):
        at = "" if g == 0.0 else f" switching at {_switch_value(signal, g)}"
        side = "on that side" if g == 0.0 else "beyond that deflection"
        at_rest = (form == "on_pos") == (g < 0.0) and g != 0.0  # the corner on the far side of rest
        if lower and at_rest:
            closes = _condition("on_neg" if form == "on_pos" else "on_pos", signal, g)
            return (f"a crack in section {n} open at rest that closes for {closes}: stiffness k{n} lower by {pct} "
                    f"for {cond}, whole again past that point (bilinear stiffness{at}: a crack propped open, no force "
                    "at rest)")
        if lower:
            return (f"a breathing crack in section {n} that opens for {cond}: stiffness k{n} lower by {pct} {side} "
                    f"(bilinear stiffness{at})")
        return (f"section {n} is stiffer by {pct} for {cond} (bilinear stiffness{at}: a contact or a crack that "
                "closes on that side)")
    if param == "k" and signal.startswith("ddelta"):
        return (f"stiffness k{n} of section {n} {pct} {lh} {when} {cond} (a stiffness that depends on the direction "
                "of motion: a crack whose faces separate or catch as the section moves one way)")
    if param == "k" and _is_position(signal):
        return _swing_crack(n, coef, cond, "")
    if param == "d_ep_i" and signal.startswith("delta"):
        return _debonded_patch(n, coef, cond, "")
    if param in ("d_ep", "d_ep_i") and signal == "ic":
        return _charging_patch(param, n, f"{pct} {lh} {when} {cond}")
    if param in ("d_ep", "d_ep_i"):
        return _depolarised(param, n, f"{pct} {lh} {when} {cond}")
    if param == "c" and signal.startswith("delta"):
        return f"damping c{n} of section {n} {pct} {lh} while {cond} (a crack whose faces rub when it is open)"
    return f"{what} {pct} {lh} {when} {cond} (a sign-dependent {what.split(' of ')[0]})"


def _instant(t0: float, se: float | None) -> str:
    """'t = 20.0 ± 0.1 s' (decimals from the standard error; '20 s' without one)."""
    if se is None or not math.isfinite(se) or se <= 0:
        return f"t = {t0:.4g} s"
    d = _decimals(se)
    if float(f"{se:.{d}f}") == 0.0:  # below the last decimal quoted: the instant alone
        return f"t = {t0:.{d}f} s"
    return f"t = {t0:.{d}f} ± {se:.{d}f} s"


def describe_damage(param: str, index: int, form: str, signal: str, coef: float, shape: float,
                    shape_se: float | None = None, width: float = 0.0, since: float | None = None,
                    since_se: float | None = None) -> str:
    """One sentence, in an engineer's words, for the damage term ``coef`` × contribution(``param``) × gate
    (``width``: a step's fitted edge time scale, s; 0 for a sharp step; ``since``: the instant, s, a switched change
    began at, with its standard error ``since_se``; None: it held through the record)."""
    words = _describe_gated(param, index, form, signal, coef, shape, shape_se, width)
    if since is None:
        return words
    began = "a crack that appeared" if param == "k" and coef < 0 else "damage that began"
    return f"{words}, from {_instant(since, since_se)} on ({began} during the record)"


def _describe_gated(param: str, index: int, form: str, signal: str, coef: float, shape: float,
                    shape_se: float | None, width: float) -> str:
    """The words of :func:`describe_damage` for a change that held through the record."""
    n = index + 1
    what = CONTRIBUTIONS[param].what.format(n=n)
    pct = f"{100 * abs(coef):.3g} %"
    lower = coef < 0
    lh = "lower" if lower else "higher"
    if form in SIGN_GATES and width > 0.0:  # a switch whose edge was fitted: where and over how much it switches
        span = _switch_value(signal, 2.2 * width).lstrip("+")
        return (_describe_sign(param, index, form, signal, coef, shape)
                + f" — a gradual switch: 10–90 % of it over {span} about that point")
    if form in SIGN_GATES:
        return _describe_sign(param, index, form, signal, coef, named_switch(shape, shape_se))
    if form in (*SOFT_GATES, *GROW_GATES, *SQUARE_GATES, *SAT_GATES):
        return _describe_edge(param, index, form, signal, coef, shape)
    if form in ("on_gap", "on_excess") and signal in ("va", "vc"):
        return _above_magnitude(param, n, form, signal, coef, shape)
    if form == "on_gap":
        if param == "k":
            return (f"section {n} is {'softer' if lower else 'stiffer'} by {pct} beyond ±{_length(shape)} of δ{n}"
                    + (": free play / contact — a clearance in its joint that closes at that gap" if not lower else
                       ": a joint that slips past that deflection"))
        if param == "c":
            return f"{what} {pct} {lh} beyond ±{_length(shape)} of δ{n} (contact damping: an impact past a clearance)"
        return f"{what} {pct} {lh} beyond ±{_length(shape)} of δ{n} (past a gap)"
    if form == "on_step" and width > 0.0:
        return _describe_s_curve(param, n, coef, shape, shape_se, width)
    if form == "on_step":  # no finer than the step's own width: the model cannot place it closer
        at = _instant(shape, None if shape_se is None else max(shape_se, STEP_WIDTH_S))
        if param == "k" and lower:
            return f"section {n} lost {pct} of its stiffness at {at} (a damage event inside the record)"
        if param == "m":
            return f"mass m{n} {'fell' if lower else 'grew'} by {pct} at {at} (a part lost or added during the record)"
        return f"{what} {'dropped' if lower else 'rose'} by {pct} at {at} (an event inside the record)"
    if form == "on_ramp" and width < 0.0:
        return _describe_accelerating(param, n, coef, shape, shape_se, -width)
    if form == "on_ramp" and width > 0.0:
        return _describe_settling(param, n, coef, shape, shape_se, width)
    if form == "on_ramp" and shape < 0.0:
        return _describe_under_way(param, n, coef, shape, shape_se)
    if form == "on_ramp":
        rate = f"{100 * abs(coef):.3g} %/s"
        return (f"{what} {'falling' if lower else 'rising'} by {rate} from {_instant(shape, shape_se)} on "
                "(damage growing during the record)")
    raise KeyError(form)


def _describe_under_way(param: str, n: int, coef: float, shape: float, shape_se: float | None) -> str:
    """A change growing at the rate ``coef`` (1/s) since ``shape`` < 0 s, before the record began: a share of it
    already there at t = 0 (−coef · shape), the rest growing through the record."""
    rate = f"{100 * abs(coef):.3g} %/s"
    at_start = f"{100 * abs(coef * shape):.3g} %"
    began = f"at that rate it began about {-shape:.3g} s before the record"
    if param == "k" and coef < 0:
        return (f"section {n} had already lost {at_start} of its stiffness when the record began and went on losing "
                f"{rate} through it (damage under way before the record: {began})")
    what = CONTRIBUTIONS[param].what.format(n=n)
    return (f"{what} already {at_start} {'lower' if coef < 0 else 'higher'} when the record began and "
            f"{'falling' if coef < 0 else 'rising'} by {rate} through it (a change under way before the record: "
            f"{began})")


def _depolarised(param: str, n: int, how: str) -> str:
    """A patch's coupling (every patch's ``d_ep``, or patch ``n``'s own ``d_ep_i``) changed ``how`` ('30 % lower
    for negative drive') on one polarity. The common ``d_ep`` is said as all three patches' (blind set 6: the three
    couples weak for negative voltage by 40, 30 and 20 % were found as one ``d_ep`` 35.5 % lower, 1.21 σ, and said as
    "a patch whose authority …" — read as one patch)."""
    if param == "d_ep_i":
        return (f"patch {n} (on section {n}) whose authority d_ep is {how}, the other patches as modelled "
                "(polarisation-dependent coupling: that patch partly depolarised)")
    return f"all three patches' authority d_ep is {how} (polarisation-dependent coupling: partly depolarised patches)"


def _above_magnitude(param: str, n: int, form: str, signal: str, coef: float, shape: float) -> str:
    """A patch's coupling (every patch's ``d_ep``, or patch ``n``'s own) changed past a voltage magnitude ``shape``
    (V) in either polarity: by ``coef`` × (|v| − shape)⁺/|v| (a gap, ``on_gap``), or growing linearly with the
    excess, ``coef`` × (|v| − shape)⁺/shape (``on_excess``: ``coef`` per ``shape`` volts past the corner)."""
    v = (f"v_c{n}" if param == "d_ep_i" else "v_c") if signal == "vc" else "v_a"
    lh = "lower" if coef < 0 else "higher"
    if form == "on_excess":
        per_100 = 100 * abs(coef) * 100.0 / max(shape, 1e-12)
        how = (f"{lh} above ±{shape:.3g} V of {v}, in either polarity, by {per_100:.3g} % per 100 V past that "
               f"magnitude ({100 * abs(coef):.3g} % × (|{v}| − {shape:.3g} V)⁺ / {shape:.3g} V: a loss growing "
               "linearly with the field's excess)")
    else:
        how = (f"{100 * abs(coef):.3g} % {lh} above ±{shape:.3g} V of {v}, in either polarity (growing as "
               f"(|{v}| − {shape:.3g} V)⁺/|{v}|)")
    why = ("coupling lost at high field: domains that saturate forward and back-switch in reverse" if coef < 0 else
           "a coupling that grows with the field")
    if param == "d_ep_i":
        return f"patch {n} (on section {n}) whose authority d_ep is {how}, the other patches as modelled ({why})"
    return f"all three patches' authority d_ep is {how} ({why})"


def _charging_patch(param: str, n: int, how: str) -> str:
    """A patch's coupling (every patch's ``d_ep``, or patch ``n``'s own) changed ``how`` ('40 % lower while its
    charging current is positive …') in one sense of its charging, not of its voltage."""
    why = ("a coupling lost in one sense of the charging, not of the voltage: domain walls pinned while the field "
           "changes that way")
    if param == "d_ep_i":
        return f"patch {n} (on section {n}) whose authority d_ep is {how}, the other patches as modelled ({why})"
    return f"all three patches' authority d_ep is {how} ({why})"


def _saturating_patch(param: str, n: int, form: str, signal: str, coef: float, shape: float) -> str:
    """A coupling (or another patch parameter) whose change on one polarity of the voltage saturates smoothly with
    it: 63 % of ``coef`` at ``shape`` (V), nearly all of it beyond three times that (tanh)."""
    positive = form.startswith("on_pos")
    whose = "drive" if signal == "va" else "voltage"
    sign = "positive" if positive else "negative"
    how = (f"{100 * abs(coef):.3g} % {'lower' if coef < 0 else 'higher'} for {sign} {whose}, the more the stronger "
           f"the {whose} (63 % of it at {_switch_value(signal, shape if positive else -shape)}, nearly all beyond "
           f"three times that: tanh)")
    why = (f"a coupling that fades with its {sign} polarity and saturates: electrode fingers that lose contact or "
           "domains that back-switch by degrees")
    if param == "d_ep_i":
        return f"patch {n} (on section {n}) whose authority d_ep is {how}, the other patches as modelled ({why})"
    if param == "d_ep":
        return f"all three patches' authority d_ep is {how} ({why})"
    what = CONTRIBUTIONS[param].what.format(n=n)
    return f"{what} {how} (a change that saturates with the {whose} on one polarity)"


def _fading_patch(param: str, n: int, form: str, signal: str, coef: float, shape: float) -> str:
    """A coupling (or another patch parameter) whose change grows in proportion to the patch voltage on one
    polarity, reaching ``coef`` at ``shape`` (V) and holding beyond."""
    positive = form.startswith("on_pos")
    reach = f"{'+' if positive else '−'}{abs(shape):.3g} V"
    whose = "drive" if signal == "va" else "voltage"
    how = (f"{100 * abs(coef):.3g} % {'lower' if coef < 0 else 'higher'} once its {whose} reaches {reach}, in "
           f"proportion to the {whose} from 0 V up to there and not at all for {'negative' if positive else 'positive'}"
           f" {whose}")
    if param == "d_ep_i":
        return (f"patch {n} (on section {n}) whose authority d_ep is {how}, the other patches as modelled (a "
                f"coupling that fades with its own {'positive' if positive else 'negative'} polarity: electrode "
                "fingers that lose contact or domains that back-switch by degrees)")
    if param == "d_ep":
        return (f"all three patches' authority d_ep is {how} (a coupling that fades on one polarity: patches "
                "partly depolarised by degrees)")
    what = CONTRIBUTIONS[param].what.format(n=n)
    return f"{what} {how} (a change that grows with the {whose} on one polarity)"


def _swing_crack(n: int, coef: float, cond: str, edge: str) -> str:
    """A section's stiffness switched by a mass's displacement (the tip's swing), ``edge``: its smooth edge's words."""
    pct = f"{100 * abs(coef):.3g} %"
    if coef < 0:
        return (f"a crack in section {n} opened by the beam's swing: stiffness k{n} lower by {pct} while {cond}"
                f"{edge} (a crack that opens on one side of the motion)")
    return f"section {n} is stiffer by {pct} while {cond}{edge} (a contact that closes on one side of the motion)"


def _debonded_patch(n: int, coef: float, cond: str, edge: str) -> str:
    """A patch's own coupling switched by its section's bending (``edge``: its smooth edge's words)."""
    pct = f"{100 * abs(coef):.3g} %"
    return (f"patch {n} (on section {n}) whose authority d_ep is {pct} {'lower' if coef < 0 else 'higher'} for "
            f"{cond}{edge}, the other patches as modelled (a patch whose bond opens while its section bends that "
            "way: partly debonded)")


def _describe_edge(param: str, index: int, form: str, signal: str, coef: float, shape: float) -> str:
    """Words for a gate with a smooth edge (of width ``shape``) or a change growing with the opening (saturating at
    ``shape``), on a section's deflection or rate, the tip's displacement or the drive."""
    n = index + 1
    what = CONTRIBUTIONS[param].what.format(n=n)
    pct = f"{100 * abs(coef):.3g} %"
    lower = coef < 0
    lh = "lower" if lower else "higher"
    op = ">" if form.startswith("on_pos") else "<"
    if form in GROW_GATES and signal in ("va", "vc"):
        return _fading_patch(param, n, form, signal, coef, shape)
    if form in SAT_GATES and signal == "ic":
        reach = _switch_value(signal, shape if op == ">" else -shape)
        how = (f"{pct} {lh} while it {'charges' if op == '>' else 'discharges'}, the more the stronger the current "
               f"(63 % of it at {reach}, nearly all beyond three times that: tanh) and not at all while it "
               f"{'discharges' if op == '>' else 'charges'}")
        return _charging_patch(param, n, how) if param in ("d_ep", "d_ep_i") else f"{what} {how}"
    if form in SAT_GATES and signal in ("va", "vc"):
        return _saturating_patch(param, n, form, signal, coef, shape)
    if form in (*GROW_GATES, *SQUARE_GATES):
        side = f"δ{n} {op} 0"
        reach = f"{'−' if op == '<' else ''}{_length(shape)}"
        how = "with the square of the opening" if form in SQUARE_GATES else "with the opening"
        if param == "k" and lower:
            return (f"a breathing crack in section {n} that opens for {side}, its lost stiffness growing {how}: "
                    f"k{n} lower by {pct} once δ{n} reaches {reach}, less before (a crack whose faces part "
                    "progressively)")
        by = f"the square of δ{n}" if form in SQUARE_GATES else f"δ{n}"
        return f"{what} {pct} {lh} for {side}, growing with {by} up to {reach} (a change that grows with the opening)"
    if signal.startswith("ddelta"):
        edge = f"switching over about ±{1e3 * abs(shape):.3g} mm/s of δ̇{n}"
        if param == "k":
            return (f"stiffness k{n} of section {n} {pct} {lh} for δ̇{n} {op} 0 ({edge}: a stiffness that depends on "
                    "the direction of motion — a crack whose faces separate or catch as the section moves one way)")
        return f"{what} {pct} {lh} for δ̇{n} {op} 0 ({edge}: direction-dependent)"
    cond = _condition("on_pos" if op == ">" else "on_neg", signal)
    if signal == "ic":
        edge = f", switching over about ±{1e3 * abs(shape):.3g} mA"
        if param in ("d_ep", "d_ep_i"):
            return _charging_patch(param, n, f"{pct} {lh} while {cond}{edge}")
        return f"{what} {pct} {lh} while {cond}{edge} (a change with the sense of the patch's charging)"
    if signal in ("va", "vc"):
        edge = f", switching over about ±{abs(shape):.3g} V"
        if param in ("d_ep", "d_ep_i"):
            return _depolarised(param, n, f"{pct} {lh} for {cond}{edge}")
        return f"{what} {pct} {lh} for {cond}{edge} (a sign-dependent {what.split(' of ')[0]})"
    if _is_position(signal):
        edge = f", switching over about ±{_length(shape)} of {signal}"
        return _swing_crack(n, coef, cond, edge) if param == "k" else f"{what} {pct} {lh} while {cond}{edge}"
    edge = f"its faces parting over about ±{_length(shape)} of δ{n}"
    if param == "d_ep_i":
        return _debonded_patch(n, coef, f"δ{n} {op} 0", f", switching over about ±{_length(shape)}")
    if param == "k" and lower:
        return (f"a breathing crack in section {n} that opens gradually for δ{n} {op} 0 ({edge}): stiffness k{n} "
                f"lower by {pct} when open (bilinear stiffness with a smooth edge)")
    return f"{what} {pct} {lh} for δ{n} {op} 0, switching gradually ({edge})"


def describe_finite_change(param: str, index: int, rate: float, t0: float, se0: float | None, end_rate: float,
                           t1: float, se1: float | None, holds_share: float) -> tuple[str, str]:
    """Words for two ramps of one parameter — ``rate`` (1/s) from ``t0`` and ``end_rate`` from ``t1`` (s, with their
    standard errors) — as one change over a finite time: the rise's words and the end's. It *holds* after ``t1``
    when the rate left, ``rate + end_rate``, is below ``holds_share`` of ``rate``."""
    n = index + 1
    what = CONTRIBUTIONS[param].what.format(n=n)
    total = rate * (t1 - t0)
    pct = f"{100 * abs(total):.3g} %"
    left = rate + end_rate
    holds = abs(left) <= holds_share * abs(rate)
    span = f"between {_instant(t0, se0)} and {_instant(t1, se1)}"
    then = ("then held" if holds else f"then kept {'falling' if left < 0 else 'rising'} by "
            f"{100 * abs(left):.3g} %/s")
    # the middle too: where half of the change was reached (a loss over 6–9 s is a loss around 7.5 s)
    mid = 0.5 * (t0 + t1)
    why = f"damage that grew over {t1 - t0:.3g} s, half of it by t = {mid:.{_decimals(se0, se1)}f} s, {then}"
    if param == "k" and total < 0:
        rise = f"section {n} lost {pct} of its stiffness {span} ({why})"
    elif param == "m":
        rise = f"mass m{n} {'fell' if total < 0 else 'grew'} by {pct} {span} ({why})"
    else:
        rise = f"{what} {'fell' if total < 0 else 'rose'} by {pct} {span} ({why})"
    end = (f"its end at {_instant(t1, se1)} (a ramp of {100 * end_rate:+.3g} %/s from then on "
           + ("cancels the change's rate)" if holds else f"leaves it changing by {100 * left:+.3g} %/s)"))
    return rise, end


def describe_recovery(param: str, index: int, first: float, second: float, t1: float, se1: float | None) -> str:
    """Words for the later of two steps of one parameter when it gives part of the earlier one's change back:
    ``first``, ``second`` their relative changes, ``t1`` (s, standard error ``se1``) the later one's instant."""
    n = index + 1
    what = CONTRIBUTIONS[param].what.format(n=n)
    back = f"{100 * abs(second):.3g} %"
    share = abs(second / first) if first else math.inf
    at = _instant(t1, None if se1 is None else max(se1, STEP_WIDTH_S))
    undone = "all of the change undone" if share >= 1.0 else f"{100 * share:.3g} % of the change undone, " \
        f"{100 * abs(first + second):.3g} % stays"
    if param == "k" and first < 0:
        return (f"then section {n} regained {back} of its stiffness at {at} ({undone}: a partial recovery — "
                "faces that re-seated and carry part of the load again)")
    return f"then {what} {'rose' if second > 0 else 'fell'} back by {back} at {at} ({undone}: a partial recovery)"


def _decimals(*ses: float | None) -> int:
    """Decimals of a time quoted as precisely as the least precise of the standard errors ``ses`` (3 without one;
    at most 6)."""
    known = [se for se in ses if se is not None and math.isfinite(se) and se > 0.0]
    return min(max(0, -math.floor(math.log10(max(known)))), 6) if known else 3


def _describe_s_curve(param: str, n: int, coef: float, centre: float, se: float | None, width: float) -> str:
    """Words for a step with a fitted edge: half the change at ``centre`` (s), 10–90 % of it over 2.2 × ``width``."""
    what = CONTRIBUTIONS[param].what.format(n=n)
    pct = f"{100 * abs(coef):.3g} %"
    span = f"{2.2 * width:.3g} s"
    at = _instant(centre, se)
    why = "damage that ran and arrested: an S-shaped change, half of it at that instant"
    if param == "k" and coef < 0:
        return f"section {n} lost {pct} of its stiffness around {at}, over {span} (10–90 %; {why})"
    if param == "m":
        return f"mass m{n} {'fell' if coef < 0 else 'grew'} by {pct} around {at}, over {span} (10–90 %; {why})"
    return f"{what} {'dropped' if coef < 0 else 'rose'} by {pct} around {at}, over {span} (10–90 %; {why})"


def _describe_settling(param: str, n: int, rate: float, t0: float, se: float | None, tau: float) -> str:
    """Words for a ramp that saturates: ``rate`` (1/s) from ``t0`` (s), settling at rate × ``tau`` (s)."""
    what = CONTRIBUTIONS[param].what.format(n=n)
    total = rate * tau
    pct = f"{100 * abs(total):.3g} %"
    how = f"from {_instant(t0, se)} on, settling exponentially with time constant {tau:.3g} s"
    if param == "k":
        if total < 0:
            return f"section {n} lost {pct} of its stiffness {how} (damage that grew and arrested)"
        return (f"section {n} regained {pct} of its stiffness {how} (a loss that partly recovered: crack faces "
                "re-seating, resin relaxing — or a stiffening)")
    return f"{what} {'fell' if total < 0 else 'rose'} by {pct} {how} (a change that settled)"


def _describe_accelerating(param: str, n: int, rate: float, t0: float, se: float | None, span: float) -> str:
    """Words for a ramp that accelerates: ``rate`` × min((t − ``t0``)⁺, ``span``)² / ``span`` (t0 and span in s),
    held at rate × span from t0 + span on."""
    what = CONTRIBUTIONS[param].what.format(n=n)
    total = rate * span
    pct = f"{100 * abs(total):.3g} %"
    how = (f"between {_instant(t0, se)} and t = {t0 + span:.4g} s, faster and faster (quadratic in time: a quarter of "
           f"it by t = {t0 + 0.5 * span:.4g} s), then held")
    if param == "k" and total < 0:
        return (f"section {n} lost {pct} of its stiffness {how} (damage that accelerated and arrested: a fatigue "
                "crack growing faster as it lengthens, until it reached a stiffener)")
    return f"{what} {'fell' if total < 0 else 'rose'} by {pct} {how} (a change that accelerated, then held)"


def _length(x: float) -> str:
    return f"{x * 1e3:.3g} mm" if abs(x) >= 1e-3 else f"{x * 1e6:.3g} µm"

