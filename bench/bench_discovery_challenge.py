"""The not-in-the-library challenge (issue 11 point 5, part B): every effect of ``tests/workbench_foreign_effects.py``
(written only there, loaded by file path) at two strengths, hidden in MBIT.b and 6 s sweep records at 2 µm and
10 µm laser noise; ``shm discover`` on each, the emitted file refitted with ``shm fit``'s engine. Targets: held-out
error ≤ 1.5 σ in ≥ 80 % of the cases larger than 3 σ, and the description naming the right signal and condition.
Cases run as tasks on ``--scheduler`` (:func:`studies.batch.cases.run_cases`: two local worker processes by
default), logged in case order as they come in."""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

FOREIGN_FILE = Path(__file__).parents[1] / "tests" / "workbench_foreign_effects.py"


def _one(args: tuple) -> dict:
    os.environ.setdefault("MFC_SHM_THREADS", "1")
    from plant.effect import load_effect_file
    from workbench.challenges.discovery import DiscoveryCase, run_discovery_case

    cls_name, values, words, strength, kind, noise, seed = args
    mod = load_effect_file(FOREIGN_FILE)
    case = DiscoveryCase(cls_name, getattr(mod, cls_name), values, tuple(words), strength)
    try:
        return run_discovery_case(case, kind, noise, seed).to_dict()
    except Exception as exc:  # one case's failure is a result (a miss with the reason), not the end of the run
        from workbench.challenges.discovery import DiscoveryCaseResult

        return DiscoveryCaseResult.failed(cls_name, strength, kind, noise, seed, values, exc).to_dict()


def cases(quick: bool) -> list[tuple]:
    from plant.effect import load_effect_file

    foreign = load_effect_file(FOREIGN_FILE).FOREIGN
    kinds = ["sweep"] if quick else ["sweep", "mbit-b"]
    noises = [2e-6] if quick else [2e-6, 1e-5]
    out = []
    for name, (strengths, words) in foreign.items():
        for i, v in enumerate(strengths):
            for kind in kinds:
                for noise in noises:
                    out.append((name, dict(v), list(words), ("weak", "strong")[i], kind, noise, 5 + i))
    return out


def run(out_dir: Path, quick: bool, scheduler: str | None = None) -> dict:
    from studies.batch.cases import run_cases
    from workbench.challenges.discovery import DiscoveryCaseResult, format_table, summarise

    todo = cases(quick)
    results = []
    progress = Path(out_dir) / "discovery_challenge_progress.jsonl"
    with progress.open("w") as log:
        def logged(r: dict) -> None:  # in case order; each case logged as soon as the cases before it are in
            results.append(DiscoveryCaseResult(**r))
            log.write(json.dumps(r, default=float) + "\n")
            log.flush()
            print(f"   [{len(results)}/{len(todo)}] {r['label']} {r['strength']} {r['kind']} "
                  f"{r['noise_m'] * 1e6:g} µm: {r['verdict']} {'/'.join(r['found']) or '-'}, held-out "
                  f"{r['held_before']:.3g} → {r['held_after']:.3g} σ, named {r['named']} ({r['wall_s']:.0f} s)",
                  file=sys.stderr, flush=True)

        run_cases(_one, [(t,) for t in todo], scheduler=scheduler, workers=min(2, os.cpu_count() or 1),
                  on_result=logged, what="discovery challenge")
    table = format_table(results)
    (out_dir / "discovery_challenge.txt").write_text(table + "\n")
    (out_dir / "discovery_challenge_cases.json").write_text(json.dumps([r.to_dict() for r in results], indent=1,
                                                                       default=float))
    print(table)
    return summarise(results) | {"table": str(out_dir / "discovery_challenge.txt")}
