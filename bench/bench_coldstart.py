"""Cold start benchmark (issue 27.1): ``shm model info``, ``shm diagnose``, ``shm discover`` and ``shm run`` on a
fresh clone's empty numba cache, after ``make setup``'s kernel step (:mod:`workbench.warm`), and warm (run again).

Each command runs in a subprocess (:mod:`bench.output_timing`) three times:

* **cold** — ``NUMBA_CACHE_DIR`` an empty directory: every kernel it needs compiles on first use;
* **after setup** — a copy of a cache that only ``python -m workbench.warm`` filled (what a fresh clone has after
  ``make setup``): what the set-up step leaves to compile shows here;
* **warm** — again on the cold run's cache: every kernel loaded.

For each: wall time, time to the first output line, the longest stretch without output, the tail from the last line
to the exit (the interpreter's teardown), how many compiles the plant announced, and the stretches the no-silence
rule does not accept (none expected). The set-up step's own time is
reported too. Bounded: a 2 s record, diagnose over three candidates, discover keeping one term, a 30 s board run.
"""

from __future__ import annotations

import itertools
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from bench.output_timing import TimedRun, cold_env, exit_tail_s, run_timed, unexplained_silences

SHM = [sys.executable, "-m", "shm_cli.main"]


def _commands(record: Path, work: Path) -> dict[str, list[str]]:
    return {
        "model_info": [*SHM, "model", "info"],
        "diagnose": [*SHM, "diagnose", str(record), "--candidates", "geometric_stiffening,dielectric_leakage,k3",
                     "--out", str(work / "diagnose")],
        "discover": [*SHM, "discover", str(record), "--max-terms", "1", "--out", str(work / "discover")],
        "run": [*SHM, "run", "--scenario", "patch_leakage", "--duration-s", "30", "--force",
                "--out", str(work / "run")],
    }


def _summary(run: TimedRun) -> dict[str, Any]:
    times = [0.0, *(t for t, _ in run.lines)]
    return {"wall_s": round(run.wall_s, 2), "exit": run.returncode,
            "first_line_s": round(run.lines[0][0], 2) if run.lines else None,
            "longest_gap_s": round(max((b - a for a, b in itertools.pairwise(times)), default=0.0), 2),
            "exit_tail_s": round(exit_tail_s(run), 2),
            "compiles_announced": sum(line.startswith("compiling ") for _, line in run.lines),
            "unexplained_silences": unexplained_silences(run)}


def _record(path: Path, env: dict[str, str]) -> Path:
    subprocess.run([*SHM, "synth", "--test", "mbit-b", "--effect", "geometric_stiffening", "--set", "kappa_nl=2e4",
                    "--duration-s", "2", "--noise", "z3=2e-6", "--out", str(path)], env=env, check=True,
                   capture_output=True)
    return path


def run(out_dir: Path, quick: bool) -> dict:
    root = Path(tempfile.mkdtemp(prefix="bench_coldstart_"))

    def env(cache: Path) -> dict[str, str]:
        # the generated kernel sources in one place for every variant: numba files a module's cache under a name
        # derived from the source's directory, so a copied cache is found only with the sources where they were
        return cold_env(cache, MFC_SHM_KERNEL_DIR=str(root / "kernel_sources"))

    try:
        record = _record(root / "stiff.csv", env(root / "synth_cache"))
        setup_cache = root / "setup_cache"
        t0 = time.perf_counter()
        warm = subprocess.run([sys.executable, "-m", "workbench.warm", "--jobs", "2"], env=env(setup_cache),
                              capture_output=True, text=True)
        setup_s = time.perf_counter() - t0
        (out_dir / "coldstart_setup.txt").write_text(warm.stdout + warm.stderr)
        result: dict[str, Any] = {"setup_warm_s": round(setup_s, 1), "setup_exit": warm.returncode}
        names = ["model_info", "run"] if quick else ["model_info", "diagnose", "discover", "run"]
        for name in names:
            cold_cache, work = root / f"cold_{name}", root / f"work_{name}"
            after_cache = root / f"after_setup_{name}"
            shutil.copytree(setup_cache, after_cache)
            argv = _commands(record, work)[name]
            row = {}
            for label, cache in (("cold", cold_cache), ("after_setup", after_cache), ("warm", cold_cache)):
                timed = run_timed(argv, env(cache), timeout_s=1200, cwd=root)
                row[label] = _summary(timed)
                (out_dir / f"coldstart_{name}_{label}.txt").write_text(timed.text())
            result[name] = row
            result[f"{name}_cold_s"] = row["cold"]["wall_s"]
            result[f"{name}_after_setup_s"] = row["after_setup"]["wall_s"]
            result[f"{name}_warm_s"] = row["warm"]["wall_s"]
        return result
    finally:
        shutil.rmtree(root, ignore_errors=True)
