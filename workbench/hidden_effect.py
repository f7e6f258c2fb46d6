"""The hidden-effect challenge: hide one library effect in a synthetic record, then diagnose and fit it.

A *case* is (effect or none, strength, noise level, test kind, seed). The truth plant is the parameter set plus the
hidden effect at that strength (:mod:`workbench.synth`, the hardware-in-the-loop stub's seam); the record is what
the rig would log (tip laser with white noise). :func:`run_case` then

1. measures the effect's *size*: the RMS difference between the noise-free truth with and without the effect,
   in units of the noise σ (a case "counts" for the ranking target when the size exceeds 1 σ);
2. runs :func:`workbench.diagnose.diagnose` against the nominal model with every library candidate;
3. reports whether the true effect was ranked first, the verdict, and the held-out error after fitting (of the
   winner and of the true effect), in σ.

:func:`confusion_matrix` tabulates truth against diagnosis. ``bench/bench_hidden_effect.py`` runs the full sweep
(every library effect × strengths × noise levels × MBIT.a / MBIT.b / sweep, and effect-free seeds); the test suite
runs a small subset.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from workbench.diagnose import diagnose
from workbench.effect_library import LIBRARY
from workbench.synth import synth_inputs, synth_record, synth_test, truth_model

#: three strengths per library effect (parameter values of the truth), weak → strong
STRENGTHS: dict[str, tuple[dict[str, float], ...]] = {
    "piezo_creep": ({"gamma_creep": 0.01, "tau_creep": 0.5}, {"gamma_creep": 0.03, "tau_creep": 1.0},
                    {"gamma_creep": 0.1, "tau_creep": 2.0}),
    "geometric_stiffening": ({"kappa_nl": 2e3}, {"kappa_nl": 1e4}, {"kappa_nl": 5e4}),
    "air_damping": ({"c_air": 0.02}, {"c_air": 0.08}, {"c_air": 0.3}),
    "dielectric_leakage": ({"G_leak": 2e-6}, {"G_leak": 1e-5}, {"G_leak": 5e-5}),
    "amplifier_current_limit": ({"I_max": 0.2}, {"I_max": 0.05}, {"I_max": 0.008}),
    "laser_sensor": ({"z_offset": 5e-6, "tau_sensor": 1e-3}, {"z_offset": 2e-5, "tau_sensor": 3e-3},
                     {"z_offset": 1e-4, "tau_sensor": 1e-2}),
    "root_compliance": ({"clamp_compliance": 1e-3}, {"clamp_compliance": 4e-3}, {"clamp_compliance": 1.5e-2}),
    "thermal_drift": ({"dT_dt": 0.05}, {"dT_dt": 0.2}, {"dT_dt": 1.0}),
}
STRENGTH_NAMES = ("weak", "medium", "strong")
#: test kinds of the challenge and their overrides (the sweep is shortened to keep the suite affordable)
KINDS: dict[str, dict[str, Any]] = {
    "mbit-a": {},
    "mbit-b": {},
    "sweep": {"duration_s": 15.0},
}
NOISE_LEVELS_M = (2e-6, 1e-5)


@dataclass
class CaseResult:
    """One hidden-effect case and what diagnose made of it."""

    effect: str  # "none" for an effect-free record
    strength: str
    values: dict[str, float]
    kind: str
    noise_m: float
    seed: int
    size_sigma: float  # RMS(truth with effect − truth without) / σ, noise-free
    counts: bool  # size above the noise (the ranking target applies)
    verdict: str
    diagnosed: str  # winner's name, or "nothing missing" / "unexplained"
    ranked_first: bool
    true_rank: int  # 1-based rank of the true effect among all candidates (0 for none)
    held_after_winner_sigma: float
    held_after_true_sigma: float
    held_before_sigma: float
    wall_s: float
    ranking: list[str] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def effect_size_sigma(kind: str, effect: str, values: Mapping[str, float], noise: float,
                      params: str = "table2") -> float:
    """RMS difference of the noise-free tip readings with and without the effect, in noise σ."""
    spec = synth_test(kind, **KINDS.get(kind, {}))
    from plant import InputSignals

    t, u, _ = synth_inputs(spec)
    inp = InputSignals(0.0, 1.0 / spec.rate_hz, u)
    with_eff = truth_model(params, [effect], values).simulate(inp, t_out=t)
    without = truth_model(params).simulate(inp, t_out=t)
    d = with_eff["z3_meas"][0] - without["z3_meas"][0]
    return float(np.sqrt(np.mean(d ** 2)) / noise)


def run_case(effect: str | None, values: Mapping[str, float] | None, kind: str, noise: float, seed: int, *,
             strength: str = "", params: str = "table2", candidates: Sequence[str] = LIBRARY,
             size_sigma: float | None = None, workers: int = 1) -> CaseResult:
    """Hide ``effect`` (None: nothing) in a synthetic ``kind`` record and diagnose it (see the module docstring)."""
    t0 = time.perf_counter()
    values = dict(values or {})
    effects = [effect] if effect else []
    spec = synth_test(kind, **KINDS.get(kind, {}))
    rec = synth_record(spec, truth_model(params, effects, values), noise={"z3": noise}, seed=seed,
                       effects=effects, values=values)
    if size_sigma is None:
        size_sigma = effect_size_sigma(kind, effect, values, noise, params) if effect else 0.0
    d = diagnose([rec], params, candidates, workers=workers, seed=seed)
    names = d.ranked_names
    winner = d.winner.effect if d.winner else ("nothing missing" if d.verdict == "nothing_missing" else
                                               "unexplained")
    true = next((c for c in d.ranking if c.effect == effect), None)
    return CaseResult(
        effect=effect or "none", strength=strength or ("-" if effect is None else "custom"), values=values,
        kind=kind, noise_m=noise, seed=seed, size_sigma=size_sigma, counts=bool(effect) and size_sigma > 1.0,
        verdict=d.verdict, diagnosed=winner, ranked_first=bool(effect) and winner == effect,
        true_rank=(names.index(effect) + 1) if effect in names else 0,
        held_after_winner_sigma=d.winner.held_rms_sigma if d.winner else d.baseline_held_rms_sigma,
        held_after_true_sigma=true.held_rms_sigma if true else d.baseline_held_rms_sigma,
        held_before_sigma=d.baseline_held_rms_sigma, wall_s=time.perf_counter() - t0, ranking=names)


def confusion_matrix(results: Sequence[CaseResult]) -> tuple[list[str], list[str], np.ndarray]:
    """(truth labels, diagnosis labels, counts[truth, diagnosis]) over ``results``."""
    truths = [e for e in (*LIBRARY, "none") if any(r.effect == e for r in results)]
    diags = [*LIBRARY, "nothing missing", "unexplained"]
    m = np.zeros((len(truths), len(diags)), dtype=int)
    for r in results:
        m[truths.index(r.effect), diags.index(r.diagnosed)] += 1
    used = [j for j in range(len(diags)) if m[:, j].any() or diags[j] in truths or diags[j] == "nothing missing"]
    return truths, [diags[j] for j in used], m[:, used]


def format_confusion(results: Sequence[CaseResult]) -> str:
    """The confusion matrix as text (rows: hidden truth; columns: diagnosis)."""
    truths, diags, m = confusion_matrix(results)
    short = {n: n.replace("amplifier_current_limit", "amp_limit").replace("geometric_stiffening", "stiffening")
             .replace("dielectric_leakage", "leakage").replace("nothing missing", "nothing").replace(
                 "root_compliance", "root_compl") for n in [*truths, *diags]}
    w = max(len(short[t]) for t in truths) + 2
    cw = max(max(len(short[d]) for d in diags), 4) + 1
    lines = ["truth \\ diagnosis".ljust(w) + "".join(short[d].rjust(cw) for d in diags)]
    for i, t in enumerate(truths):
        lines.append(short[t].ljust(w) + "".join(str(x).rjust(cw) for x in m[i]))
    return "\n".join(lines)


def summarise(results: Sequence[CaseResult]) -> dict[str, Any]:
    """The challenge's targets: ranked first (cases above the noise), held-out after fit, null verdicts."""
    counting = [r for r in results if r.counts]
    nulls = [r for r in results if r.effect == "none"]
    first = [r for r in counting if r.ranked_first]
    fit_ok = [r for r in counting if r.held_after_true_sigma <= 1.5]
    out: dict[str, Any] = {
        "cases": len(results),
        "cases_above_noise": len(counting),
        "ranked_first_rate": len(first) / len(counting) if counting else float("nan"),
        "held_after_true_fit_within_1p5_sigma_rate": len(fit_ok) / len(counting) if counting else float("nan"),
        "held_after_winner_fit_within_1p5_sigma_rate": (
            sum(r.held_after_winner_sigma <= 1.5 for r in first) / len(first) if first else float("nan")),
        "null_cases": len(nulls),
        "null_nothing_missing_rate": (sum(r.verdict == "nothing_missing" for r in nulls) / len(nulls)
                                      if nulls else float("nan")),
        "misses": [f"{r.effect}/{r.strength}/{r.kind}/noise {r.noise_m:g} m/seed {r.seed}: diagnosed {r.diagnosed} "
                   f"(size {r.size_sigma:.3g} σ, true effect rank {r.true_rank})" for r in counting
                   if not r.ranked_first],
        "false_alarms": [f"{r.kind}/noise {r.noise_m:g} m/seed {r.seed}: {r.diagnosed}" for r in nulls
                         if r.verdict != "nothing_missing"],
    }
    per_kind = {}
    for kind in dict.fromkeys(r.kind for r in results):
        c = [r for r in counting if r.kind == kind]
        per_kind[kind] = {"above_noise": len(c), "ranked_first": sum(r.ranked_first for r in c)}
    out["per_kind"] = per_kind
    return out
