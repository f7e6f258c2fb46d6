"""The verdict of ``shm diagnose`` in words: what is missing or wrong, by how much, the command to fix it, what the
records cannot tell apart, and — when the candidates do not suffice — the ``shm discover`` command to run next."""

from __future__ import annotations

import math
import shlex
from collections.abc import Mapping, Sequence
from typing import Any

from board_config import ParameterSet
from workbench.compare import ResidualTests
from workbench.diagnose._one_sided import one_sided_twin
from workbench.diagnose._rules import CURE_AT_MOST_SIGMA, excess_share, head_kind
from workbench.fit import AT_NOISE_FLOOR, CandidateResult

#: how parameter values are shown: SI unit -> (factor, shown unit)
_SHOW = {"kg": (1e3, "g"), "F": (1e6, "µF"), "m/V": (1e6, "µm/V"), "ohm": (1.0, "Ω")}


def show(value: float, unit: str) -> str:
    f, u = _SHOW.get(unit, (1.0, "" if unit == "1" else unit))
    return f"{value * f:.4g} {u}".strip()


def percent_change(rel: float) -> str:
    """'+50 %', '-5 %', '+0.38 %' (a change below 1 % keeps two digits: never a '+0 %' that hides it)."""
    return f"{100 * rel:+.2g} %" if abs(rel) < 0.01 else f"{100 * rel:+.0f} %"


def records_arg(d: Any) -> str:
    """The diagnosed records as shell arguments."""
    return _records_arg(d)


def _failed_names(tests: Sequence[ResidualTests]) -> list[str]:
    names: list[str] = []
    for t in tests:
        for x in t.failed:
            if x.title not in names:
                names.append(x.title)
    return names


def _records_arg(d: Any) -> str:
    return " ".join(shlex.quote(str(tg.record.path)) if tg.record.path else tg.name for tg in d.targets)


def fit_command(d: Any, cand: CandidateResult, params_label: str) -> str:
    """The ``shm fit`` command that refits ``cand`` on the same records."""
    spec = cand.spec
    parts = ["shm fit", _records_arg(d), "--params", shlex.quote(params_label)]
    if spec is not None:
        for cls in spec.effects:
            parts += ["--add", cls.name]
            parts += [f"--free {n}" for n in spec.extra_for(cls)]
        for pc in spec.params:
            parts += [f"--free {n}" for n in pc.members]
    parts += ["--save", "refit.toml", "--out", "fit"]
    return " ".join(parts)


def discover_command(d: Any, params_label: str) -> str:
    return f"shm discover {_records_arg(d)} --params {shlex.quote(params_label)} --emit my_effect.py --out discover"


def parameter_words(cand: CandidateResult, base: ParameterSet, wrong: bool = True,
                    twins: Mapping[str, str] | None = None) -> str:
    """'m3 is wrong: 2.09 g instead of 1.39 g (+50 %)' (or a group scaled together, or a pair); with ``wrong``
    False, 'm3 re-estimated: 2.09 g instead of 1.39 g (+50 %)' (a part of the story, not its cure). ``twins``:
    parameter → its one-sided reading (:func:`~workbench.diagnose._one_sided.one_sided_twin`), said after it."""
    o = cand.outcome
    spec = cand.spec
    assert o is not None and spec is not None
    est = {e.name: e for e in o.estimates}
    phrases = []
    for pc in spec.params:
        if pc.tied:
            s = est[pc.scale_name].value
            changes = ", ".join(f"{n} {show(base.values[n], _unit(n))} → {show(base.values[n] * s, _unit(n))}"
                                for n in pc.members)
            phrases.append(f"{pc.description} are off by the same factor: ×{s:.3g} ({percent_change(s - 1)}; "
                           f"{changes})")
            continue
        bits = []
        for n in pc.members:
            e = est[n]
            old = float(base.values[n])
            rel = f" ({percent_change(e.value / old - 1)})" if old != 0 else ""
            twin = (twins or {}).get(n)
            bits.append(f"{n} {'is wrong' if wrong else 're-estimated'}: {show(e.value, e.unit)} instead of "
                        f"{show(old, e.unit)}{rel}" + (f" — {twin}" if twin else ""))
        phrases.append("; ".join(bits))
    return "; ".join(phrases)


def _unit(name: str) -> str:
    from board_config import CORE_SCHEMA

    return CORE_SCHEMA[name].unit


def _effect_words(cand: CandidateResult, missing: bool = True) -> str:
    if cand.spec is None or not cand.spec.effects or cand.outcome is None:
        return cand.effect
    est = {e.name: e for e in cand.outcome.estimates}
    out = []
    for cls in cand.spec.effects:
        vals = ", ".join(est[p.name].describe() for p in cls.own_parameters() if p.name in est)
        out.append(f"{cls.name} {'is missing' if missing else 'added'} ({cls.description}; {vals})")
    return "; ".join(out)


def term_shares_words(d: Any, cand: CandidateResult) -> str:
    """'without piezo_creep the rest leaves 8.2 σ (it carries 96 % of what the set removes), …' for a combination."""
    shares = getattr(d, "term_shares", {}) or {}
    without = getattr(d, "without_sigma", {}) or {}
    bits = []
    for m in cand.members:
        if m in shares and m in without:
            bits.append(f"without {m} the rest leaves {without[m]:.3g} σ ({m} carries {100 * shares[m]:.3g} % of "
                        "what the set removes)")
    if not bits:
        return ""
    total = sum(shares.get(m, 0.0) for m in cand.members)
    tail = (" — the terms overlap: part of what they remove either could" if total < 0.9 else "")
    return "; ".join(bits) + tail


def identifiability_lines(d: Any, cand: CandidateResult, base: ParameterSet) -> list[str]:
    """What the records cannot tell apart about ``cand`` (the confusions the naming rule measured are reused)."""
    from workbench.diagnose._identifiability import confusions

    lines = []
    o = cand.outcome
    if o is not None and len(o.estimates) > 1:
        names = [e.name for e in o.estimates]
        for i in range(len(names)):
            for j in range(i + 1, len(names)):
                r = float(o.correlation[i, j])
                if math.isfinite(r) and abs(r) >= 0.95:
                    lines.append(f"{names[i]} and {names[j]} are strongly correlated in this fit (ρ = {r:+.2f}): the "
                                 "records constrain a combination of the two better than each")
    if cand.spec is None or not cand.spec.params or o is None:
        return lines
    fitted: dict[str, float] = {}
    est = {e.name: e.value for e in o.estimates}
    about = []
    for pc in cand.spec.params:
        for n in pc.members:
            about.append(n)
            fitted[n] = float(base.values[n]) * est[pc.scale_name] if pc.tied else est[n]
    judged = getattr(d, "judgement", None)
    if judged is not None and all(a in judged.closest for a in about):
        conf = [c for c in judged.confusions if c.a in about and c.b not in about]
        closest = judged.closest
    else:
        try:
            conf, closest = confusions(d.targets, base, fitted, about)
        except (ValueError, KeyError) as exc:  # a short or odd record: say so rather than fail the diagnosis
            return [*lines, f"identifiability not assessed ({exc})"]
    for c in conf:
        best_kind, best_rho, best_se = c.separating[0]
        tail = (f"a {best_kind} test separates them ({c.a} to ±{100 * best_se:.2g} % with both free, ρ = "
                f"{best_rho:.2f})" if best_se < 0.5 * c.rel_se else "none of the standard tests separates them well")
        lines.append(f"{c.a} cannot be told apart from {c.b} on these records (their effects on the measurement "
                     f"correlate at ρ = {c.rho:+.2f}; with both free {c.a} is known only to ±{100 * c.rel_se:.2g} %): "
                     + tail)
    for a in about:
        if not any(c.a == a for c in conf) and a in closest and closest[a][0]:
            b, rho, se = closest[a]
            lines.append(f"{a} is identifiable on these records: even with the most similar parameter, {b} "
                         f"(ρ = {rho:+.3f}), free too, {a} is pinned to ±{100 * se:.2g} %")
    return lines


def verdict_kind(winner_kind: str | None, explained_by_winner: bool, base_held_sigma: float) -> str:
    """The verdict's kind (docs/workbench.md, "Verdicts") from the kind of the set the verdict may name and whether
    it reaches the noise floor: :func:`workbench.diagnose._rules.head_kind`."""
    kinds = ([] if winner_kind is None else ["parameter", "effect"] if winner_kind == "combination"
             else [winner_kind])
    return head_kind(kinds, 1.0 if explained_by_winner else math.inf, base_held_sigma, AT_NOISE_FLOOR)


def member_kinds(cand: CandidateResult | None) -> list[str]:
    """The kinds of ``cand``'s members, in order ("parameter" or "effect")."""
    if cand is None or cand.spec is None:
        return [] if cand is None else [cand.kind]
    return ["effect"] * len(cand.spec.effects) + ["parameter"] * len(cand.spec.params)


def percent_share(share: float) -> str:
    """'62 %', '99.9 %' (never rounded up to a whole 100 % that was not reached)."""
    if share >= 0.995 and share < 1.0:
        return f"{math.floor(share * 1000) / 10:.1f} %"
    return f"{100 * share:.0f} %"


def part_words(cand: CandidateResult, base: ParameterSet) -> str:
    """What a set changes, as a part of the story: 'k1 re-estimated: … (−5 %); geometric_stiffening added (…)'."""
    parts = []
    spec = cand.spec
    if spec is not None and spec.params:
        from workbench.fit import CandidateSpec

        sub = CandidateResult(cand.effect, "", "", "", cand.free, cand.outcome, spec=CandidateSpec(params=spec.params))
        parts.append(parameter_words(sub, base, wrong=False))
    if spec is not None and spec.effects:
        parts.append(_effect_words(cand, missing=False))
    return "; ".join(parts) or cand.effect


def _nothing_missing(d: Any, failed_before: Sequence[str]) -> str:
    base_held = d.baseline_held_rms_sigma
    best = next((c for c in d.ranking if c.stable and c.outcome is not None), None)
    msg = (f"Nothing missing: the nominal model already explains the held-out data to the noise floor "
           f"({base_held:.3g} σ RMS), and no candidate reduces the held-out error by the required margin")
    if best is not None and best.held_reduction > 0 and best.delta_bic_held > 10:
        msg += (f". Note: the best candidate is significant on the held-out data (ΔBIC {best.delta_bic_held:.3g}) "
                "but changes too little to matter here; a longer record or less noise would tell")
    if failed_before:
        msg += f". Residual tests that still fail: {', '.join(failed_before)}"
    return msg + "."


def _unexplained(d: Any, failed_before: Sequence[str]) -> str:
    msg = (f"Not explained by the library and the core parameters: the nominal model misses the held-out data by "
           f"{d.baseline_held_rms_sigma:.3g} σ RMS, and no "
           "candidate effect or parameter re-estimation removes enough of it on held-out data while being "
           "identifiable, away from its bounds, changing the prediction by more than the noise and costing more "
           "than the noise when removed")
    msg += ". Where it fails: " + " | ".join(d.where_it_fails)
    if failed_before:
        msg += f". Failed residual tests: {', '.join(failed_before)}"
    return msg + "."


def _one_sided(d: Any, winner: CandidateResult) -> str | None:
    """:func:`~workbench.diagnose._one_sided.one_sided_twin` of a single re-estimated parameter, on the nominal
    model's simulated outputs (None when there are none)."""
    spec = winner.spec
    if spec is None or spec.effects or len(spec.params) != 1:
        return None
    return one_sided_twins(d, winner).get(spec.params[0].members[0])


def one_sided_twins(d: Any, cand: CandidateResult) -> dict[str, str]:
    """Each parameter re-estimated alone in ``cand`` (not scaled with others) whose switching signal stays on one
    side over every record → its one-sided reading, on the nominal model's simulated outputs. A pair is read member
    by member: on MBIT.b (a step bending every section one way) a tip crack opened by the mid section's bend was
    "Two things at once: k3 is wrong (−10 %); d_ep is wrong (+4 %)" — each as good as a section 3 that lost
    stiffness on one side, and a patch weaker for one polarity."""
    spec = cand.spec
    sim = getattr(d, "baseline_sim", None)
    if spec is None or sim is None or not sim.full:
        return {}
    traces = [{n: full[0, :, j] for j, n in enumerate(tg.model.output_names)} for tg, full in zip(d.targets, sim.full)]
    out = {}
    for pc in spec.params:
        twin = None if pc.tied or len(pc.members) != 1 else one_sided_twin(pc.members[0], traces)
        if twin:
            out[pc.members[0]] = twin
    return out


def _cure_head(d: Any, winner: CandidateResult, base: ParameterSet, kind: str, cut: str) -> str:
    if kind == "wrong_parameter":
        twin = _one_sided(d, winner)
        return (f"{parameter_words(winner, base)} — re-estimate it{'; ' + twin if twin else ''}. "
                f"Re-estimating {winner.effect} {cut}")
    if kind == "missing":
        return f"Missing effect: {winner.effect} — {winner.description}. Adding it {cut}"
    words = [f"{step.effect} alone: {step.held_rms_sigma:.3g} σ" for step in d.steps]
    parts = []
    spec = winner.spec
    if spec is not None and spec.params:
        from workbench.fit import CandidateSpec

        sub = CandidateResult(winner.effect, "", "", "", winner.free, winner.outcome,
                              spec=CandidateSpec(params=spec.params))
        parts.append(parameter_words(sub, base, twins=one_sided_twins(d, winner)))
    if spec is not None and spec.effects:
        parts.append(_effect_words(winner))
    head = (f"{'Two' if len(winner.members) == 2 else 'Several'} things at once: {'; and '.join(parts)}. "
            f"Together they {cut.replace('cuts', 'cut', 1)}")
    if words:
        head += f"; found step by step ({', '.join(words)})"
    shares = term_shares_words(d, winner)
    if shares:
        head += f". What each explains: {shares}"
    return head


def verdict_for(d: Any, base: ParameterSet, params_label: str) -> None:
    """Fill ``d.verdict``, ``d.message``, ``d.fit_command``, ``d.next_command``, ``d.identifiability``.

    ``d.winner`` is what the verdict may name (the members of the best set that pass the naming rule, fitted
    together: :mod:`workbench.diagnose._evidence`); its first sentence follows
    :func:`workbench.diagnose._rules.head_kind`: a cure only when the named set reaches
    :data:`~workbench.diagnose._rules.CURE_AT_MOST_SIGMA` held out, otherwise the share of the excess over the noise
    that the library and the core parameters explain."""
    winner = d.winner
    base_held = d.baseline_held_rms_sigma
    failed_before = _failed_names(d.tests_before)
    discover = discover_command(d, params_label)
    held = winner.held_rms_sigma if winner is not None else base_held
    kind = head_kind(member_kinds(winner), held, base_held, AT_NOISE_FLOOR)
    if kind == "nothing_missing" or winner is None:
        if kind == "nothing_missing":
            d.verdict, d.message = kind, _nothing_missing(d, failed_before)
            return
        d.verdict, d.next_command = kind, discover
        d.message = _unexplained(d, failed_before) + f"\nLook for the missing term beyond the library:\n  {discover}"
        return
    d.fit_command = fit_command(d, winner, params_label)
    cut = (f"cuts the held-out residual from {base_held:.3g} σ to {winner.held_rms_sigma:.3g} σ RMS "
           f"({100 * winner.held_reduction:.3g} % of the residual energy; ΔBIC {winner.delta_bic_held:.4g} against "
           "the nominal model)")
    if kind == "partial":
        share = excess_share(base_held, winner.held_rms_sigma)
        msg = (f"The library and the core parameters explain only {percent_share(share)} of the excess over the "
               f"noise: the most they reach with members these records show ({part_words(winner, base)}) "
               f"{cut.replace('cuts', 'cut', 1)} — above the {CURE_AT_MOST_SIGMA:g} σ a cure must reach")
    else:
        msg = _cure_head(d, winner, base, kind, cut)
    msg += f". Fitted: {winner.estimates_text()}."
    if winner.widened:
        msg += f" Range widened after the fit ended at a bound: {'; '.join(winner.widened)}."
    if kind == "missing" and winner.signature:
        msg += f" Its signature: {winner.signature}"
    if failed_before:
        after = _failed_names(d.tests_after)
        cleared = [n for n in failed_before if n not in after]
        msg += f" Residual tests failed by the nominal model: {', '.join(failed_before)}"
        msg += f"; with {winner.effect}: " + (f"{', '.join(cleared)} now pass" if cleared else "none clears")
        if after:
            msg += f", still failing: {', '.join(after)}"
        msg += "."
    d.identifiability = identifiability_lines(d, winner, base)
    if d.identifiability:
        msg += " Identifiability: " + "; ".join(d.identifiability) + "."
    if kind == "partial":
        msg += (f"\nThat part alone:\n  {d.fit_command}\nWhere the nominal model fails: "
                + " | ".join(d.where_it_fails) + f"\nLook for the rest beyond the library:\n  {discover}")
        d.next_command = discover
    else:
        msg += f"\nFit it:\n  {d.fit_command}"
    d.verdict, d.message = kind, msg
