"""The verdict of ``shm diagnose`` in words: what is missing or wrong, by how much, the command to fix it, what the
records cannot tell apart, and — when the candidates do not suffice — the ``shm discover`` command to run next."""

from __future__ import annotations

import math
import shlex
from collections.abc import Sequence
from typing import Any

from board_config import ParameterSet
from workbench.candidate_fit import AT_NOISE_FLOOR, CandidateResult, explained
from workbench.residual_tests import ResidualTests

#: how parameter values are shown: SI unit -> (factor, shown unit)
_SHOW = {"kg": (1e3, "g"), "F": (1e6, "µF"), "m/V": (1e6, "µm/V"), "ohm": (1.0, "Ω")}


def show(value: float, unit: str) -> str:
    f, u = _SHOW.get(unit, (1.0, unit))
    return f"{value * f:.4g} {u}".strip()


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


def parameter_words(cand: CandidateResult, base: ParameterSet) -> str:
    """'m3 is wrong: 2.09 g instead of 1.39 g (+50 %)' (or a group scaled together, or a pair)."""
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
            phrases.append(f"{pc.description} are off by the same factor: ×{s:.3g} ({100 * (s - 1):+.0f} %; "
                           f"{changes})")
            continue
        bits = []
        for n in pc.members:
            e = est[n]
            old = float(base.values[n])
            rel = f" ({100 * (e.value / old - 1):+.0f} %)" if old != 0 else ""
            bits.append(f"{n} is wrong: {show(e.value, e.unit)} instead of {show(old, e.unit)}{rel}")
        phrases.append("; ".join(bits))
    return "; ".join(phrases)


def _unit(name: str) -> str:
    from board_config import CORE_SCHEMA

    return CORE_SCHEMA[name].unit


def _effect_words(cand: CandidateResult) -> str:
    if cand.spec is None or not cand.spec.effects or cand.outcome is None:
        return cand.effect
    est = {e.name: e for e in cand.outcome.estimates}
    out = []
    for cls in cand.spec.effects:
        vals = ", ".join(est[p.name].describe() for p in cls.own_parameters() if p.name in est)
        out.append(f"{cls.name} is missing ({cls.description}; {vals})")
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
    from workbench.identifiability import confusions

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
    """The verdict's kind (docs/workbench.md, "Verdicts"): no accepted candidate → "nothing_missing" when the nominal
    model is at the noise floor (held-out RMS ≤ :data:`AT_NOISE_FLOOR` σ), else "unexplained"; a winner that does not
    bring the held-out error to the noise floor (:func:`explained`) → "partial"; otherwise by the winner's kind: a
    re-estimation → "wrong_parameter", an effect → "missing", a set → "combination"."""
    if winner_kind is None:
        return "nothing_missing" if base_held_sigma <= AT_NOISE_FLOOR else "unexplained"
    if not explained_by_winner:
        return "partial"
    return {"parameter": "wrong_parameter", "effect": "missing"}.get(winner_kind, "combination")


def verdict_for(d: Any, base: ParameterSet, params_label: str) -> None:
    """Fill ``d.verdict``, ``d.message``, ``d.fit_command``, ``d.next_command``, ``d.identifiability``."""
    winner = d.winner
    base_held = d.baseline_held_rms_sigma
    ranking = d.ranking
    failed_before = _failed_names(d.tests_before)
    discover = discover_command(d, params_label)
    if winner is None:
        best = next((c for c in ranking if c.stable and c.outcome is not None), None)
        verdict = verdict_kind(None, False, base_held)
        if verdict == "nothing_missing":
            msg = (f"Nothing missing: the nominal model already explains the held-out data to the noise floor "
                   f"({base_held:.3g} σ RMS), and no candidate reduces the held-out error by the required margin")
            if best is not None:
                msg += f" (best: {best.effect}, {100 * best.held_reduction:+.2g} % of the held-out residual energy)"
                if best.delta_bic_held > 10 and best.held_reduction > 0:
                    msg += (f". Note: {best.effect} is significant on the held-out data "
                            f"(ΔBIC {best.delta_bic_held:.3g}) but too small to matter here; a longer record or less "
                            "noise would tell")
            if failed_before:
                msg += f". Residual tests that still fail: {', '.join(failed_before)}"
            d.verdict, d.message = verdict, msg + "."
            return
        msg = (f"Not explained by the library: the nominal model misses the held-out data by {base_held:.3g} σ RMS, "
               "but no candidate effect or parameter re-estimation removes enough of it on held-out data")
        if best is not None:
            msg += (f" (best: {best.effect}, {100 * best.held_reduction:.3g} % of the residual energy, "
                    f"ΔBIC {best.delta_bic_held:.3g})")
        msg += ". Where it fails: " + " | ".join(d.where_it_fails)
        if failed_before:
            msg += f". Failed residual tests: {', '.join(failed_before)}"
        msg += f".\nLook for the missing term beyond the library:\n  {discover}"
        d.verdict, d.message, d.next_command = verdict, msg, discover
        return
    d.fit_command = fit_command(d, winner, params_label)
    ok = explained(winner.held_rms_sigma, base_held, winner.n_eff_held)
    kind = winner.kind
    cut = (f"cuts the held-out residual from {base_held:.3g} σ to {winner.held_rms_sigma:.3g} σ RMS "
           f"({100 * winner.held_reduction:.3g} % of the residual energy; ΔBIC {winner.delta_bic_held:.4g} against "
           "the nominal model)")
    runner = next((c for c in ranking if c is not winner and c.accepted and c.members != winner.members), None)
    if kind == "parameter":
        head = f"{parameter_words(winner, base)} — re-estimate it. Re-estimating {winner.effect} {cut}"
    elif kind == "effect":
        head = (f"Missing effect: {winner.effect} — {winner.description}. Adding it {cut}" if ok else
                f"Partly explained by {winner.effect} — {winner.description}. Adding it {cut}")
    else:
        words = []
        for step in d.steps:
            words.append(f"{step.effect} alone: {step.held_rms_sigma:.3g} σ")
        parts = []
        spec = winner.spec
        if spec is not None and spec.params:
            from workbench.candidates import CandidateSpec

            sub = CandidateResult(winner.effect, "", "", "", winner.free, winner.outcome,
                                  spec=CandidateSpec(params=spec.params))
            parts.append(parameter_words(sub, base))
        if spec is not None and spec.effects:
            parts.append(_effect_words(winner))
        head = (f"{'Two' if len(winner.members) == 2 else 'Several'} things at once: {'; and '.join(parts)}. "
                f"Together they {cut.replace('cuts', 'cut', 1)}; found step by step ({', '.join(words)})")
        shares = term_shares_words(d, winner)
        if shares:
            head += f". What each explains: {shares}"
    msg = head
    if runner is not None and kind != "combination":
        msg += f"; runner-up {runner.effect} ({runner.held_rms_sigma:.3g} σ, ΔBIC {runner.delta_bic_held:.4g})"
    msg += f". Fitted: {winner.estimates_text()}."
    if winner.widened:
        msg += f" Range widened after the fit ended at a bound: {'; '.join(winner.widened)}."
    if kind == "effect" and winner.signature:
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
    msg += f"\nFit it:\n  {d.fit_command}"
    if not ok:
        msg += (f"\nThe fitted model is still {winner.held_rms_sigma:.3g} σ from the held-out data (noise floor 1 σ), "
                "so this is at best part of the story. Where the nominal model fails: " + " | ".join(d.where_it_fails)
                + f"\nLook for the rest beyond the library:\n  {discover}")
        d.next_command = discover
    d.verdict, d.message = verdict_kind(kind, ok, base_held), msg
