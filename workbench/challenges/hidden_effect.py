"""The hidden-effect challenge: hide what the model lacks in a synthetic record, then diagnose it.

A *case* (:class:`HiddenCase`) is a truth plant — the parameter set with hidden effects and/or wrong core
parameters — and what ``shm diagnose`` should blame (``expected``). Cases come in *kinds*, each a factory in the
registry :data:`CASE_KINDS` (:func:`register_case_kind`; part B of issue 11 adds effects outside the library
from its own module):

* ``library``   — one library effect at three strengths (:data:`STRENGTHS`: every library effect of the registry
  with the strengths its own file declares on its parameters — ``Parameter(..., challenge=(weak, medium, strong))``);
* ``parameter`` — one wrong core parameter at two deviations (:data:`PARAMETER_CASES`): the truth differs from the
  parameter set, nothing is missing;
* ``pair``      — two library effects at once (:data:`PAIRS`), two strengths;
* ``none``      — nothing hidden (the null cases are seeds, see ``bench/bench_hidden_effect.py``).

Each case is run on records of the test kinds :data:`KINDS` (MBIT.a, MBIT.b, a 15 s sweep) and noise levels
:data:`NOISE_LEVELS_M`. :func:`run_case` measures the case's *size* (RMS of the noise-free tip reading of the truth
minus the nominal model, in noise σ), diagnoses the record against the nominal model with every candidate and
scores: named first (the first thing diagnose blames is ``expected[0]``; a wrong parameter may also be found
inside the group that holds it), all found (every expected name among those blamed), the held-out error after the
fit. A case *counts* for the targets when its size exceeds :data:`COUNTS_ABOVE` of its kind (1 σ; 3 σ for wrong
parameters, the issue's threshold) — a pair when each of its effects alone exceeds
:data:`PAIR_MEMBER_COUNTS_ABOVE` (3 σ; every pair is still reported, ``pair_all_both_found_rate``).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from board_config import load_parameter_set
from board_config.json_values import JsonFields
from plant.effect import EffectError, registered_effects, resolve_effect
from plant.effect_declarations import STRENGTH_NAMES
from workbench.diagnose import diagnose
from workbench.fit import LIBRARY, PARAMETER_CANDIDATES
from workbench.simulation import synth_inputs, synth_record, synth_test, truth_model


def challenge_strengths(name: str) -> tuple[dict[str, float], ...]:
    """The weak, medium and strong parameter values of library effect ``name`` in the challenge (its parameters'
    ``challenge``, :meth:`plant.effect.PhysicalEffect.challenge_strengths`)."""
    cls = registered_effects().get(name)
    values = cls.challenge_strengths() if cls is not None else ()
    if not values:
        raise EffectError(f"library effect '{name}' declares no challenge strengths (Parameter(..., "
                          f"challenge=({', '.join(s.upper() for s in STRENGTH_NAMES)})) on a parameter)")
    return values


class LibraryStrengths(Mapping[str, tuple[dict[str, float], ...]]):
    """Library effect name -> its challenge strengths, read from the registry on every use."""

    def __getitem__(self, name: str) -> tuple[dict[str, float], ...]:
        if name not in LIBRARY:
            raise KeyError(name)
        return challenge_strengths(name)

    def __iter__(self) -> Iterator[str]:
        return iter(LIBRARY)

    def __len__(self) -> int:
        return len(LIBRARY)


#: three strengths per library effect (parameter values of the truth), weak → strong
STRENGTHS: Mapping[str, tuple[dict[str, float], ...]] = LibraryStrengths()
#: wrong core parameters: (name, relative factors of the truth against the parameter set, weaker first)
PARAMETER_CASES: tuple[tuple[str, tuple[float, ...]], ...] = (
    ("m3", (1.2, 1.5)),
    ("k2", (0.9, 0.8)),
    ("c1", (1.7, 3.0)),
    ("d_ep", (0.93, 0.85)),
    ("alpha_h", (0.85, 0.7)),
    ("C_ep", (1.15, 1.3)),
    ("k3", (1.1, 1.25)),
)
#: pairs of library effects hidden together, each at the given strength indices into STRENGTHS
PAIRS: tuple[tuple[str, str], ...] = (
    ("piezo_creep", "laser_sensor"),
    ("geometric_stiffening", "dielectric_leakage"),
    ("root_compliance", "thermal_drift"),
)
PAIR_LEVELS = (1, 2)
#: test kinds of the challenge and their overrides (the sweep is shortened to keep the suite affordable)
KINDS: dict[str, dict[str, Any]] = {
    "mbit-a": {},
    "mbit-b": {},
    "sweep": {"duration_s": 15.0},
}
NOISE_LEVELS_M = (2e-6, 1e-5)
#: a case counts for its kind's target when its size (σ) exceeds this
COUNTS_ABOVE: dict[str, float] = {"library": 1.0, "parameter": 3.0, "pair": 1.0, "none": 0.0}
#: a pair counts only when *each* of its effects alone changes the record by more than this (σ): "both found" asks
#: diagnose to name the weaker one too, which a record cannot show below a few σ (root compliance under the
#: quasi-static MBIT.a: 0.5 σ); such pairs are still run and reported (``member_sizes_sigma``, ``pair_all_*``)
PAIR_MEMBER_COUNTS_ABOVE = 3.0


@dataclass(frozen=True)
class HiddenCase:
    """What the truth hides and what diagnose should blame (names of effects or core parameters)."""

    kind: str
    label: str
    effects: tuple[Any, ...]
    values: Mapping[str, float]
    expected: tuple[str, ...]
    strength: str = "-"


def _library_cases() -> list[HiddenCase]:
    return [HiddenCase("library", e, (e,), dict(v), (e,), STRENGTH_NAMES[i])
            for e, vs in STRENGTHS.items() for i, v in enumerate(vs)]


def _parameter_cases() -> list[HiddenCase]:
    base = load_parameter_set("table2")
    out = []
    for name, factors in PARAMETER_CASES:
        for i, f in enumerate(factors):
            value = float(base.values[name]) * f
            out.append(HiddenCase("parameter", f"{name}{100 * (f - 1):+.0f}%", (), {name: value}, (name,),
                                  ("weaker", "stronger")[i]))
    return out


def _pair_cases() -> list[HiddenCase]:
    out = []
    for a, b in PAIRS:
        for i in PAIR_LEVELS:
            out.append(HiddenCase("pair", f"{a}+{b}", (a, b), STRENGTHS[a][i] | STRENGTHS[b][i], (a, b),
                                  STRENGTH_NAMES[i]))
    return out


#: case kinds: name -> factory of its cases (extend with :func:`register_case_kind`)
CASE_KINDS: dict[str, Callable[[], list[HiddenCase]]] = {
    "library": _library_cases,
    "parameter": _parameter_cases,
    "pair": _pair_cases,
}


def register_case_kind(name: str, factory: Callable[[], list[HiddenCase]], counts_above: float = 1.0) -> None:
    """Add a kind of hidden case (e.g. effects outside the library) to the challenge."""
    CASE_KINDS[name] = factory
    COUNTS_ABOVE.setdefault(name, counts_above)


def cases_of(kind: str) -> list[HiddenCase]:
    return CASE_KINDS[kind]()


def null_case() -> HiddenCase:
    return HiddenCase("none", "none", (), {}, ())


@dataclass
class CaseResult(JsonFields):
    """One hidden case and what diagnose made of it."""

    effect: str  # the case label ("none" for an effect-free record)
    strength: str
    values: dict[str, float]
    kind: str  # test kind
    noise_m: float
    seed: int
    size_sigma: float  # RMS(truth − nominal model) / σ, noise-free
    counts: bool  # size above its kind's threshold (the targets apply)
    verdict: str
    diagnosed: str  # what diagnose blames ("a + b"), or "nothing missing" / "unexplained"
    ranked_first: bool
    true_rank: int  # 1-based rank of the first expected name among the candidates (0: not ranked / none)
    held_after_winner_sigma: float
    held_after_true_sigma: float
    held_before_sigma: float
    wall_s: float
    ranking: list[str] = field(default_factory=list)
    case_kind: str = "library"
    expected: list[str] = field(default_factory=list)
    found: list[str] = field(default_factory=list)
    all_found: bool = False
    #: a pair's effects, each alone: RMS change of the noise-free tip reading in noise σ
    member_sizes_sigma: dict[str, float] = field(default_factory=dict)


def _inputs(kind: str):
    from plant import InputSignals

    spec = synth_test(kind, **KINDS.get(kind, {}))
    t, u, _ = synth_inputs(spec)
    return t, InputSignals(0.0, 1.0 / spec.rate_hz, u)


def case_size_sigma(kind: str, case: HiddenCase, noise: float, params: str = "table2") -> float:
    """RMS difference of the noise-free tip readings of the truth and the nominal model, in noise σ."""
    t, inp = _inputs(kind)
    with_it = truth_model(params, list(case.effects), dict(case.values)).simulate(inp, t_out=t)
    without = truth_model(params).simulate(inp, t_out=t)
    d = with_it["z3_meas"][0] - without["z3_meas"][0]
    return float(np.sqrt(np.mean(d ** 2)) / noise)


def effect_size_sigma(kind: str, effect: str, values: Mapping[str, float], noise: float,
                      params: str = "table2") -> float:
    """RMS difference of the noise-free tip readings with and without the effect, in noise σ."""
    return case_size_sigma(kind, HiddenCase("library", effect, (effect,), dict(values), (effect,)), noise, params)


def _named_first(found: Sequence[str], expected: Sequence[str]) -> bool:
    if not found or not expected:
        return False
    if found[0] == expected[0]:
        return True
    group = next((p for p in PARAMETER_CANDIDATES if p.name == found[0]), None)
    return group is not None and len(group.members) > 1 and expected[0] in group.members and len(expected) == 1


def run_hidden_case(case: HiddenCase, kind: str, noise: float, seed: int, *, params: str = "table2",
                    candidates: Sequence[str] | None = None, size_sigma: float | None = None,
                    workers: int = 1) -> CaseResult:
    """Hide ``case`` in a synthetic ``kind`` record and diagnose it (see the module docstring)."""
    t0 = time.perf_counter()
    effects = list(case.effects)
    spec = synth_test(kind, **KINDS.get(kind, {}))
    values = dict(case.values)
    rec = synth_record(spec, truth_model(params, effects, values), noise={"z3": noise}, seed=seed,
                       effects=effects, values=values)
    if size_sigma is None:
        size_sigma = case_size_sigma(kind, case, noise, params) if case.expected else 0.0
    members: dict[str, float] = {}
    counts = bool(case.expected) and size_sigma > COUNTS_ABOVE.get(case.kind, 1.0)
    if case.kind == "pair":
        members = {str(e): effect_size_sigma(kind, str(e), _own_values(str(e), values), noise, params)
                   for e in case.effects}
        counts = counts and min(members.values()) > PAIR_MEMBER_COUNTS_ABOVE
    d = diagnose([rec], params, candidates, workers=workers, seed=seed)
    names = d.ranked_names
    found = list(d.found)
    diagnosed = " + ".join(found) if found else ("nothing missing" if d.verdict == "nothing_missing" else
                                                 "unexplained")
    exp = list(case.expected)
    true = next((c for c in d.ranking if exp and c.effect == exp[0] and c.outcome is not None), None)
    rank = next((i + 1 for i, c in enumerate(d.ranking) if exp and exp[0] in c.members), 0)
    return CaseResult(
        effect=case.label, strength=case.strength, values=values, kind=kind, noise_m=noise, seed=seed,
        size_sigma=size_sigma, counts=counts,
        verdict=d.verdict, diagnosed=diagnosed, ranked_first=_named_first(found, exp), true_rank=rank,
        held_after_winner_sigma=d.winner.held_rms_sigma if d.winner else d.baseline_held_rms_sigma,
        held_after_true_sigma=true.held_rms_sigma if true else float("nan"),
        held_before_sigma=d.baseline_held_rms_sigma, wall_s=time.perf_counter() - t0, ranking=names,
        case_kind=case.kind, expected=exp, found=found, all_found=bool(exp) and set(exp) <= set(found),
        member_sizes_sigma=members)


def _own_values(effect: str, values: Mapping[str, float]) -> dict[str, float]:
    """The entries of ``values`` that are parameters of ``effect``."""
    own = {p.name for p in resolve_effect(effect).parameters}
    return {k: v for k, v in values.items() if k in own}


def run_case(effect: str | None, values: Mapping[str, float] | None, kind: str, noise: float, seed: int, *,
             strength: str = "", params: str = "table2", candidates: Sequence[str] | None = None,
             size_sigma: float | None = None, workers: int = 1) -> CaseResult:
    """One library effect (None: nothing) hidden in a ``kind`` record and diagnosed (the part-2 interface)."""
    case = (HiddenCase("library", effect, (effect,), dict(values or {}), (effect,), strength or "custom")
            if effect else null_case())
    return run_hidden_case(case, kind, noise, seed, params=params, candidates=candidates, size_sigma=size_sigma,
                           workers=workers)


def truth_label(r: CaseResult) -> str:
    """The confusion matrix row of a case: the effect, "x wrong" for a wrong parameter x, "pair: a+b"."""
    if r.case_kind == "library" or r.case_kind == "none":
        return r.effect
    if r.case_kind == "parameter":
        return r.expected[0] + " wrong"
    return r.case_kind + ": " + r.effect


def _diag_label(r: CaseResult, known: set[str]) -> str:
    if not r.found:
        return r.diagnosed
    if len(r.found) > 1:
        return "combination"
    f = r.found[0]
    if f in LIBRARY:
        return f
    return f + " wrong" if f + " wrong" in known else "other parameter"


def confusion_matrix(results: Sequence[CaseResult]) -> tuple[list[str], list[str], np.ndarray]:
    """(truth labels, diagnosis labels, counts[truth, diagnosis]) over ``results``."""
    truths = list(dict.fromkeys(truth_label(r) for r in results))
    known = set(truths)
    diags = list(dict.fromkeys([*[t for t in truths if t != "none" and not t.startswith("pair")],
                                *(_diag_label(r, known) for r in results), "nothing missing"]))
    m = np.zeros((len(truths), len(diags)), dtype=int)
    for r in results:
        m[truths.index(truth_label(r)), diags.index(_diag_label(r, known))] += 1
    used = [j for j in range(len(diags)) if m[:, j].any() or diags[j] in truths or diags[j] == "nothing missing"]
    return truths, [diags[j] for j in used], m[:, used]


#: short column labels of the verdicts; a library effect's is its ``short_name`` (else its name)
_SHORT = {"nothing missing": "nothing", "combination": "combo", "other parameter": "other_par",
          "unexplained": "unexpl"}


def _short(name: str) -> str:
    reg = registered_effects()
    effects = {n: reg[n].short_name or n for n in LIBRARY}
    for k, v in {**effects, **_SHORT}.items():
        name = name.replace(k, v)
    return name.replace(" wrong", "✗").replace("pair: ", "")


def format_confusion(results: Sequence[CaseResult]) -> str:
    """The confusion matrix as text (rows: hidden truth; columns: diagnosis; "x✗": parameter x wrong)."""
    truths, diags, m = confusion_matrix(results)
    w = max(len(_short(t)) for t in truths) + 2
    cw = max(max(len(_short(d)) for d in diags), 4) + 1
    lines = ["truth \\ diagnosis".ljust(w) + "".join(_short(d).rjust(cw) for d in diags)]
    for i, t in enumerate(truths):
        lines.append(_short(t).ljust(w) + "".join(str(x).rjust(cw) for x in m[i]))
    return "\n".join(lines)


def _rate(num: int, den: int) -> float:
    return num / den if den else float("nan")


def summarise(results: Sequence[CaseResult]) -> dict[str, Any]:
    """The challenge's targets per case kind: named first / all found (cases above the size threshold), held-out
    after the fit, null verdicts."""
    counting = [r for r in results if r.counts]
    nulls = [r for r in results if r.case_kind == "none"]
    lib = [r for r in counting if r.case_kind == "library"]
    par = [r for r in counting if r.case_kind == "parameter"]
    pairs = [r for r in counting if r.case_kind == "pair"]
    first = [r for r in counting if r.ranked_first]
    lib_fit = [r for r in lib if np.isfinite(r.held_after_true_sigma) and r.held_after_true_sigma <= 1.5]
    out: dict[str, Any] = {
        "cases": len(results),
        "cases_above_noise": len(counting),
        "ranked_first_rate": _rate(len(first), len(counting)),
        "library_top1_rate": _rate(sum(r.ranked_first for r in lib), len(lib)),
        "library_cases_counted": len(lib),
        "parameter_named_first_rate": _rate(sum(r.ranked_first for r in par), len(par)),
        "parameter_cases_counted": len(par),
        "pair_both_found_rate": _rate(sum(r.all_found for r in pairs), len(pairs)),
        "pair_cases_counted": len(pairs),
        "pair_all_both_found_rate": _rate(sum(r.all_found for r in results if r.case_kind == "pair"),
                                          sum(r.case_kind == "pair" for r in results)),
        "pair_all_cases": sum(r.case_kind == "pair" for r in results),
        "held_after_true_fit_within_1p5_sigma_rate": _rate(len(lib_fit), len(lib)),
        "held_after_winner_fit_within_1p5_sigma_rate": _rate(
            sum(r.held_after_winner_sigma <= 1.5 for r in first), len(first)),
        "null_cases": len(nulls),
        "null_nothing_missing_rate": _rate(sum(r.verdict == "nothing_missing" for r in nulls), len(nulls)),
        "misses": [f"{r.case_kind} {r.effect}/{r.strength}/{r.kind}/noise {r.noise_m:g} m/seed {r.seed}: diagnosed "
                   f"{r.diagnosed} (size {r.size_sigma:.3g} σ, first expected ranked {r.true_rank})"
                   for r in counting if not (r.all_found if r.case_kind == "pair" else r.ranked_first)],
        "false_alarms": [f"{r.kind}/noise {r.noise_m:g} m/seed {r.seed}: {r.diagnosed}" for r in nulls
                         if r.verdict != "nothing_missing"],
    }
    per_kind: dict[str, Any] = {}
    for kind in dict.fromkeys(r.kind for r in results):
        per_kind[kind] = {}
        for ck in dict.fromkeys(r.case_kind for r in results):
            c = [r for r in counting if r.kind == kind and r.case_kind == ck]
            if c:
                ok = sum((r.all_found if ck == "pair" else r.ranked_first) for r in c)
                per_kind[kind][ck] = f"{ok}/{len(c)}"
    out["per_kind"] = per_kind
    return out
