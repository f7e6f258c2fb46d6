"""The not-in-the-library challenge: hide an effect the library does not have in a synthetic record, run
``shm discover``, refit the emitted effect file with the fit engine (``shm fit --add FILE.py``), and score.

A case (:class:`DiscoveryCase`) is an effect class (written outside the workbench — the project's own ones live in
``tests/workbench_foreign_effects.py``), the truth values of its parameters, and the words the discovery's description
must contain (the right signal and condition, e.g. ``("mass 3", "friction")``). :func:`run_discovery_case` runs one
case on one test kind, noise level and seed and reports:

* ``size_sigma`` — RMS of the noise-free tip reading of the truth minus the nominal model, in noise σ (a case
  *counts* for the targets above :data:`COUNTS_ABOVE`);
* ``named`` — every required word appears in the description of what was found (``named_among_twins``: in it or
  in the terms the records cannot tell from it, reported but not counted as named);
* ``held_after`` — held-out RMS (σ) after ``fit_records(..., add=[emitted file])``; target ≤ :data:`TARGET_SIGMA`.

Targets (issue 11): the emitted effect brings held-out error to ≤ 1.5 σ in ≥ 80 % of the counted cases, and the
description names the right signal and condition.

**The damage challenge** (issue 26 point 5; :func:`run_damage_case`, ``python -m bench --only damage_challenge``):
damage written by hand outside the project (``tests/workbench_foreign_damage.py``: breathing cracks, a stiffness drop
and a damping rise at an instant, a patch weaker in one polarity, root free play) is hidden in a record and
:func:`workbench.diagnose.diagnose` — the one command a user types — runs on it. Only the FIRST SENTENCE of its
verdict is scored (:func:`first_sentence`): it must name the right physics (:class:`PhysicsCheck`: the section and the
kind; for a time event also the instant, quoted in seconds within 2 % of the record) AND the fix it proposes must
reach ≤ 1.5 σ held out (:func:`fix_held_sigma`: the emitted effect file the verdict tells the user to ``--add``,
refitted by the fit engine; else the named candidate's own held-out error). The scorer is pure and unit-tested
(``tests/workbench/test_damage_challenge.py``).
"""

from __future__ import annotations

import re
import tempfile
import time
from collections.abc import Mapping, Sequence
from dataclasses import KW_ONLY, dataclass, field
from pathlib import Path
from typing import Any, Self

import numpy as np

from board_config.json_values import JsonFields
from plant import PhysicalEffect, PlantModel
from workbench.discover import discover
from workbench.fit import FitError, fit_records
from workbench.simulation import synth_record, synth_test, truth_model

TARGET_SIGMA = 1.5
COUNTS_ABOVE = 3.0
#: test kinds of the challenge (short records; the sweep is a 6 s 0.5 → 50 Hz chirp)
KINDS: dict[str, dict[str, Any]] = {"mbit-b": {}, "sweep": {"duration_s": 6.0}, "mbit-a": {}}
NOISE_LEVELS_M = (2e-6, 1e-5)


@dataclass(frozen=True)
class DiscoveryCase:
    """An effect outside the library at one strength, and the words its discovery must use."""

    label: str
    effect: type[PhysicalEffect]
    values: Mapping[str, float]
    words: tuple[str, ...]
    strength: str = "-"


@dataclass
class CaseOutcome(JsonFields):
    """What every case of the challenge reports: the case, the record it ran on and the verdict first; then whether
    it passed, its wall time (s), a note and the truth values (keyword-only: each result type's own fields follow
    the verdict in its constructor, and in its JSON after these)."""

    label: str
    strength: str
    kind: str
    noise_m: float
    seed: int
    size_sigma: float
    counts: bool
    verdict: str
    _: KW_ONLY
    passed: bool
    wall_s: float
    note: str = ""
    values: dict[str, float] = field(default_factory=dict)

    @classmethod
    def failed(cls, label: str, strength: str, kind: str, noise: float, seed: int, values: Mapping[str, float],
               exc: BaseException) -> Self:
        """The result of a case whose run raised ``exc``: a counted miss with the reason, the type's own fields
        as :meth:`nothing_found` gives them."""
        return cls(label, strength, kind, noise, seed, float("nan"), True, "error", **cls.nothing_found(),
                   passed=False, wall_s=0.0, note=f"{type(exc).__name__}: {exc}", values=dict(values))

    @classmethod
    def nothing_found(cls) -> dict[str, Any]:
        """The result type's own fields for a case whose run failed."""
        raise NotImplementedError(f"{cls.__name__} does not say what a failed run found")

    def case_columns(self, label_width: int) -> str:
        """The columns every challenge table starts with (:func:`case_columns_head`): case, strength, test kind,
        noise (µm), size (σ)."""
        return (f"{self.label:{label_width}} {self.strength:7} {self.kind:7} {self.noise_m * 1e6:5.3g}µ "
                f"{self.size_sigma:8.3g}")


def case_columns_head(label_width: int) -> str:
    """The head of :meth:`CaseOutcome.case_columns`."""
    return f"{'case':{label_width}} {'str':7} {'test':7} {'noise':>6} {'size σ':>8}"


@dataclass
class DiscoveryCaseResult(CaseOutcome):
    found: list[str]
    description: str
    named: bool
    held_before: float
    held_discover: float
    held_after: float
    #: the right words only among the terms the records cannot tell from the one found (not counted as named)
    named_among_twins: bool = False
    twins: list[str] = field(default_factory=list)

    @classmethod
    def nothing_found(cls) -> dict[str, Any]:
        """A failed run: nothing found, nothing named, no held-out error."""
        nan = float("nan")
        return {"found": [], "description": "", "named": False, "held_before": nan, "held_discover": nan,
                "held_after": nan}


def case_size_sigma(truth: PlantModel, nominal: PlantModel, rec, noise: float) -> float:
    """RMS of the noise-free tip reading of truth minus nominal, in units of the noise."""
    inp = rec.input_signals()
    a = truth.simulate(inp, t_out=rec.t)["z3_meas"][0]
    b = nominal.simulate(inp, t_out=rec.t)["z3_meas"][0]
    return float(np.sqrt(np.mean((a - b) ** 2)) / noise)


def case_record(spec: Any, effect: type[PhysicalEffect], values: Mapping[str, float], noise: float,
                seed: int) -> tuple[Any, float]:
    """The synthetic record of test ``spec`` on the table-2 plant with ``effect`` at ``values`` (tip noise
    ``noise`` m, ``seed``), and the effect's size in the record (:func:`case_size_sigma`)."""
    truth = truth_model("table2", [effect], dict(values))
    rec = synth_record(spec, truth, noise={"z3": noise}, seed=seed, effects=[effect], values=values)
    return rec, case_size_sigma(truth, PlantModel("table2"), rec, noise)


def run_discovery_case(case: DiscoveryCase, kind: str, noise: float, seed: int, *,
                       workdir: str | Path | None = None, max_terms: int = 2) -> DiscoveryCaseResult:
    """One case on one record (see the module docstring)."""
    t0 = time.perf_counter()
    spec = synth_test(kind, **KINDS.get(kind, {}))
    rec, size = case_record(spec, case.effect, case.values, noise, seed)
    d = discover([rec], "table2", max_terms=max_terms)
    description = "; ".join(t.words for t in d.terms)
    named = bool(d.terms) and all(w.lower() in description.lower() for w in case.words)
    with_twins = "; ".join(t.description for t in d.terms)
    named_among_twins = bool(d.terms) and all(w.lower() in with_twins.lower() for w in case.words)
    held_after = float("nan")
    note = ""
    src = d.effect_source(effect_name="discovered_case")
    if src is not None:
        with tempfile.TemporaryDirectory(dir=workdir) as tmp:
            path = Path(tmp) / "discovered_case.py"
            path.write_text(src, encoding="utf-8")
            try:
                rep = fit_records([rec], "table2", add=[str(path)], max_nfev=20, bootstrap_replicates=0)
                held_after = rep.outcome.held_rms_sigma
            except FitError as exc:
                note = f"refit failed: {exc}"
    else:
        held_after = d.held_after
    passed = bool(np.isfinite(held_after) and held_after <= TARGET_SIGMA)
    return DiscoveryCaseResult(
        label=case.label, strength=case.strength, kind=kind, noise_m=noise, seed=seed, size_sigma=size,
        counts=size > COUNTS_ABOVE, verdict=d.verdict, found=[t.term.key for t in d.terms], description=description,
        named=named, held_before=d.held_before, held_discover=d.held_after, held_after=held_after, passed=passed,
        wall_s=time.perf_counter() - t0, note=note, values=dict(case.values), named_among_twins=named_among_twins,
        twins=[tw["key"] for t in d.terms for tw in t.twins])


def cases_from(effects: Mapping[str, tuple[type[PhysicalEffect], Sequence[Mapping[str, float]], Sequence[str]]]
               ) -> list[DiscoveryCase]:
    """Cases from ``{label: (class, strengths, words)}`` (strengths weak → strong)."""
    names = ("weak", "strong", "stronger")
    return [DiscoveryCase(label, cls, dict(v), tuple(words), names[i] if i < len(names) else str(i))
            for label, (cls, strengths, words) in effects.items() for i, v in enumerate(strengths)]


def summarise(results: Sequence[DiscoveryCaseResult]) -> dict[str, Any]:
    counted = [r for r in results if r.counts]
    both = [r for r in counted if r.passed and r.named]
    return {
        "cases": len(results),
        "counted (size > 3 σ)": len(counted),
        "held_out_within_1.5_sigma": sum(r.passed for r in counted),
        "named_right": sum(r.named for r in counted),
        "named_among_twins": sum(r.named_among_twins for r in counted),
        "both": len(both),
        "rate_held_out": (sum(r.passed for r in counted) / len(counted)) if counted else None,
        "rate_named": (sum(r.named for r in counted) / len(counted)) if counted else None,
        "rate_both": (len(both) / len(counted)) if counted else None,
        "rate_both_among_twins": (sum(r.passed and r.named_among_twins for r in counted) / len(counted)
                                  if counted else None),
        "misses": [f"{r.label} {r.strength} {r.kind} {r.noise_m * 1e6:g} µm: size {r.size_sigma:.3g} σ, {r.verdict} "
                   f"{'/'.join(r.found) or '-'}, held-out {r.held_after:.3g} σ, named {r.named}"
                   for r in counted if not (r.passed and r.named)],
    }


def format_table(results: Sequence[DiscoveryCaseResult]) -> str:
    lines = [f"{case_columns_head(22)} {'found':28} {'held σ':>14} {'named':>5}"]
    for r in results:
        lines.append(f"{r.case_columns(22)} {('/'.join(r.found) or '-')[:28]:28} "
                     f"{r.held_before:6.3g}→{r.held_after:<6.3g} {'yes' if r.named else 'no':>5}")
    return "\n".join(lines)


# --- the damage challenge (issue 26 point 5): the FIRST SENTENCE of the diagnose verdict, honestly scored ---------

#: a time event's instant must be quoted within this share of the record (at least EVENT_TOLERANCE_MIN_S)
EVENT_TOLERANCE_SHARE = 0.02
EVENT_TOLERANCE_MIN_S = 0.1

_SENTENCE_END = re.compile(r"[.!?](?=\s|$)")
#: a number in seconds: "20.0 s", "t = 20.0 ± 0.1 s", "at 3.3s" (not m/s, N*s/m, ms)
_SECONDS = re.compile(r"(?<![\w.])(\d+(?:\.\d+)?(?:[eE][-+]?\d+)?)\s*(?:±\s*\d+(?:\.\d+)?(?:[eE][-+]?\d+)?\s*)?s"
                      r"(?![\w/*·^²])")
_EMITTED = re.compile(r"--add\s+(\S+?\.py)\b")


@dataclass(frozen=True)
class PhysicsCheck:
    """What the first sentence must say: every group of words (any word of a group, case-insensitive) and, for a
    time event, an instant in seconds within ``t_tolerance_s`` of ``t_event_s``."""

    groups: tuple[tuple[str, ...], ...]
    t_event_s: float | None = None
    t_tolerance_s: float = 0.0


def first_sentence(text: str) -> str:
    """The verdict's first sentence: up to the first '.', '!' or '?' followed by white space or the end (a
    decimal point is not an end), or the first blank line; white space collapsed."""
    head = re.split(r"\n\s*\n", text.strip(), maxsplit=1)[0] if text.strip() else ""
    m = _SENTENCE_END.search(head)
    return " ".join((head[:m.end()] if m else head).split())


def times_quoted_s(sentence: str) -> list[float]:
    """Every number followed by the unit s (seconds) in ``sentence``."""
    return [float(m.group(1)) for m in _SECONDS.finditer(sentence)]


def check_physics(sentence: str, check: PhysicsCheck) -> tuple[bool, list[str]]:
    """``(named right, what is missing)`` for one sentence against one case's :class:`PhysicsCheck`."""
    low = sentence.lower()
    missing = ["any of " + "/".join(g) for g in check.groups if not any(w.lower() in low for w in g)]
    if check.t_event_s is not None:
        quoted = times_quoted_s(sentence)
        if not any(abs(q - check.t_event_s) <= check.t_tolerance_s for q in quoted):
            missing.append(f"the instant {check.t_event_s:.3g} ± {check.t_tolerance_s:.2g} s (quoted: "
                           f"{', '.join(f'{q:g} s' for q in quoted) or 'none'})")
    return not missing, missing


def emitted_file(message: str, workdir: str | Path | None = None) -> Path | None:
    """The effect file the verdict tells the user to add (``--add FILE.py``), when it exists (relative paths
    are looked up in ``workdir``)."""
    for m in _EMITTED.finditer(message):
        p = Path(m.group(1))
        for cand in ([p] if p.is_absolute() else [Path(workdir or ".") / p, p]):
            if cand.is_file():
                return cand
    return None


@dataclass(frozen=True)
class DamageCase:
    """Damage outside the library at one strength, and the physics the verdict's first sentence must name.
    ``values`` may hold ``t_event_frac``: the event's instant as a fraction of the record (set per record)."""

    label: str
    effect: type[PhysicalEffect]
    values: Mapping[str, float]
    groups: tuple[tuple[str, ...], ...]
    strength: str = "-"

    def truth_values(self, duration_s: float) -> dict[str, float]:
        v = dict(self.values)
        if "t_event_frac" in v:
            v["t_event"] = v.pop("t_event_frac") * duration_s
        return v

    def check(self, duration_s: float) -> PhysicsCheck:
        t = self.truth_values(duration_s).get("t_event")
        return PhysicsCheck(self.groups, t, max(EVENT_TOLERANCE_MIN_S, EVENT_TOLERANCE_SHARE * duration_s)
                            if t is not None else 0.0)


@dataclass
class DamageCaseResult(CaseOutcome):
    sentence: str
    named: bool
    missing: list[str]
    fix: str  # "emitted FILE" | "named WINNER" | "none"
    held_before: float
    held_fix: float

    @property
    def both(self) -> bool:
        return self.named and self.passed

    @classmethod
    def nothing_found(cls) -> dict[str, Any]:
        """A failed run: nothing named, no fix, no held-out error."""
        nan = float("nan")
        return {"sentence": "", "named": False, "missing": ["the run failed"], "fix": "none", "held_before": nan,
                "held_fix": nan}


def fix_held_sigma(d: Any, rec: Any, workdir: str | Path | None, *, max_nfev: int = 20) -> tuple[str, float, str]:
    """``(fix, held-out σ, note)`` of what the verdict proposes: the emitted file refitted by the fit engine
    (``shm fit --add FILE.py``) when the verdict names one, else the named (winning) candidate's own held-out
    error, else the nominal model's."""
    path = emitted_file(d.message, workdir)
    if path is not None:
        try:
            return f"emitted {path.name}", fit_records([rec], "table2", add=[str(path)], max_nfev=max_nfev,
                                                      bootstrap_replicates=0).outcome.held_rms_sigma, ""
        except FitError as exc:
            return f"emitted {path.name}", float("nan"), f"refit failed: {exc}"
    if d.winner is not None:
        return f"named {d.winner.effect}", float(d.winner.held_rms_sigma), ""
    return "none", float(d.baseline_held_rms_sigma), ""


def diagnose_options(workdir: str | Path) -> dict[str, Any]:
    """Keyword arguments for :func:`workbench.diagnose.diagnose` that send what it writes (an emitted effect
    file) to ``workdir``: its settings' ``emit_dir`` (without it diagnose runs no discovery step at all)."""
    return {"emit_dir": str(workdir)}


def run_damage_case(case: DamageCase, kind: str, noise: float, seed: int, *,
                    workdir: str | Path | None = None, **diagnose_kwargs: Any) -> DamageCaseResult:
    """One damage case on one record: synth → ``diagnose`` → first sentence scored → the fix refitted."""
    from workbench.diagnose import diagnose

    t0 = time.perf_counter()
    spec = synth_test(kind, **KINDS.get(kind, {}))
    values = case.truth_values(spec.duration_s)
    rec, size = case_record(spec, case.effect, values, noise, seed)
    with tempfile.TemporaryDirectory(dir=workdir) as tmp:
        d = diagnose([rec], "table2", **(diagnose_options(tmp) | diagnose_kwargs))
        sentence = first_sentence(d.message)
        named, missing = check_physics(sentence, case.check(spec.duration_s))
        fix, held, note = fix_held_sigma(d, rec, tmp)
    passed = bool(np.isfinite(held) and held <= TARGET_SIGMA)
    return DamageCaseResult(
        label=case.label, strength=case.strength, kind=kind, noise_m=noise, seed=seed, size_sigma=size,
        counts=size > COUNTS_ABOVE, verdict=d.verdict, sentence=sentence, named=named, missing=missing, fix=fix,
        held_before=d.baseline_held_rms_sigma, held_fix=held, passed=passed, wall_s=time.perf_counter() - t0,
        note=note, values=values)


def damage_cases_from(damage: Mapping[str, tuple[type[PhysicalEffect], Sequence[Mapping[str, float]],
                                                 Sequence[Sequence[str]]]]) -> list[DamageCase]:
    """Cases from ``{label: (class, strengths, word groups)}`` (strengths weak → strong)."""
    names = ("weak", "strong", "stronger")
    return [DamageCase(label, cls, dict(v), tuple(tuple(g) for g in groups), names[i] if i < len(names) else str(i))
            for label, (cls, strengths, groups) in damage.items() for i, v in enumerate(strengths)]


def summarise_damage(results: Sequence[DamageCaseResult]) -> dict[str, Any]:
    """Counts and shares over the counted cases (size > :data:`COUNTS_ABOVE` σ); the target is ``rate_both``."""
    counted = [r for r in results if r.counts]
    n = len(counted)

    def share(k: int) -> float | None:
        return k / n if n else None

    return {
        "cases": len(results), "counted (size > 3 σ)": n,
        "first_sentence_names_right": sum(r.named for r in counted),
        "fix_within_1.5_sigma": sum(r.passed for r in counted),
        "both": sum(r.both for r in counted),
        "rate_named": share(sum(r.named for r in counted)), "rate_fix": share(sum(r.passed for r in counted)),
        "rate_both": share(sum(r.both for r in counted)),
        "misses": [f"{r.label} {r.strength} {r.kind} {r.noise_m * 1e6:g} µm: size {r.size_sigma:.3g} σ, "
                   f"\"{r.sentence}\" — missing {'; '.join(r.missing) or '-'}; {r.fix} held-out {r.held_fix:.3g} σ"
                   + (f" ({r.note})" if r.note else "") for r in counted if not r.both],
    }


def format_damage_table(results: Sequence[DamageCaseResult]) -> str:
    lines = [f"{case_columns_head(24)} {'named':>5} {'fix':28} {'held σ':>15} {'both':>4}  first sentence"]
    for r in results:
        lines.append(f"{r.case_columns(24)} {'yes' if r.named else 'no':>5} {r.fix[:28]:28} "
                     f"{r.held_before:7.3g}→{r.held_fix:<7.3g} "
                     f"{('yes' if r.both else 'no') if r.counts else '(-)':>4}  {r.sentence[:160]}")
    return "\n".join(lines)
