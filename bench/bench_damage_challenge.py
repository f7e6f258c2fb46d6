"""The damage challenge (issue 26 point 5): every damage of ``tests/workbench_foreign_damage.py`` (written only
there, by hand, in forms the discovery dictionary does not name on purpose: breathing cracks in section 2 and at the
root, a stiffness drop and a damping rise at an instant inside the record, a patch weaker for negative drive, free
play at the root) at two strengths, hidden in a 6 s sweep, MBIT.a and MBIT.b at 2 µm and 10 µm laser noise;
``workbench.diagnose.diagnose`` on each record. Scored on the FIRST SENTENCE of the verdict: it names the right
physics (section and kind; a time event's instant within 2 % of the record) AND the fix it proposes (the emitted
effect file refitted by ``shm fit``'s engine, else the named candidate) reaches ≤ 1.5 σ held out. Target: ≥ 80 % of
the cases larger than 3 σ. Cases run as tasks on ``--scheduler`` (studies.batch.cases: two local workers by default),
each logged in case order as it comes in.

``python -m bench --only damage_challenge`` (72 cases); ``--quick``: the sweep at 2 µm only (12 cases).
``DAMAGE_CHALLENGE_ONLY=Name1,Name2`` restricts the damage classes (a partial run, not for quoting)."""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

DAMAGE_FILE = Path(__file__).parents[1] / "tests" / "workbench_foreign_damage.py"
KINDS = ("sweep", "mbit-a", "mbit-b")
NOISES_M = (2e-6, 1e-5)


def _one(args: tuple) -> dict:
    os.environ.setdefault("MFC_SHM_THREADS", "1")
    from plant.effect import load_effect_file
    from workbench.challenges.discovery import DamageCase, DamageCaseResult, run_damage_case

    cls_name, values, groups, strength, kind, noise, seed = args
    mod = load_effect_file(DAMAGE_FILE)
    case = DamageCase(cls_name, getattr(mod, cls_name), values, tuple(tuple(g) for g in groups), strength)
    try:
        return run_damage_case(case, kind, noise, seed).to_dict()
    except Exception as exc:  # one case's failure is a result (a miss with the reason), not the end of the run
        return DamageCaseResult.failed(cls_name, strength, kind, noise, seed, values, exc).to_dict()


def cases(quick: bool, only: str | None = None) -> list[tuple]:
    from plant.effect import load_effect_file

    damage = load_effect_file(DAMAGE_FILE).DAMAGE
    names = [n for n in damage if not only or n in only.split(",")]
    kinds = ("sweep",) if quick else KINDS
    noises = NOISES_M[:1] if quick else NOISES_M
    return [(name, dict(v), [list(g) for g in damage[name][1]], ("weak", "strong")[i], kind, noise, 7 + i)
            for name in names for i, v in enumerate(damage[name][0]) for kind in kinds for noise in noises]


def run(out_dir: Path, quick: bool, scheduler: str | None = None) -> dict:
    from studies.batch.cases import run_cases
    from workbench.challenges.discovery import DamageCaseResult, format_damage_table, summarise_damage

    todo = cases(quick, os.environ.get("DAMAGE_CHALLENGE_ONLY"))
    results = []
    progress = Path(out_dir) / "damage_challenge_progress.jsonl"
    with progress.open("w") as log:
        def logged(r: dict) -> None:  # in case order; each case logged as soon as the cases before it are in
            results.append(DamageCaseResult(**r))
            k = len(results)
            log.write(json.dumps(r, default=float) + "\n")
            log.flush()
            print(f"   [{k}/{len(todo)}] {r['label']} {r['strength']} {r['kind']} {r['noise_m'] * 1e6:g} µm: "
                  f"size {r['size_sigma']:.3g} σ, named {r['named']}, {r['fix']} {r['held_before']:.3g} → "
                  f"{r['held_fix']:.3g} σ ({r['wall_s']:.0f} s): {r['sentence'][:140]}", file=sys.stderr,
                  flush=True)

        run_cases(_one, [(t,) for t in todo], scheduler=scheduler, workers=min(2, os.cpu_count() or 1),
                  on_result=logged, what="damage challenge")
    table = format_damage_table(results)
    summary = summarise_damage(results)
    share = summary["rate_both"]
    table += (f"\n\nfirst sentence names the right physics AND the fix reaches ≤ 1.5 σ held out: {summary['both']} of "
              f"{summary['counted (size > 3 σ)']} counted cases"
              + (f" ({100 * share:.0f} %; target ≥ 80 %)" if share is not None else ""))
    (out_dir / "damage_challenge.txt").write_text(table + "\n")
    (out_dir / "damage_challenge_cases.json").write_text(json.dumps([r.to_dict() for r in results], indent=1,
                                                                    default=float))
    print(table)
    return summary | {"table": str(out_dir / "damage_challenge.txt")}
