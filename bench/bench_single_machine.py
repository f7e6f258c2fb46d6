"""Issue 31's "nothing in the single-machine commands gets slower", as a same-run ratio: ``shm diagnose ONE.csv`` and
``shm health BOARD`` as a user runs them (``shm_cli.main.main``: the parser with the scale-out options, the
command's check for a folder/glob or ``--fleet``) against the command's single-machine body called directly — what
the command ran before the batch layer existed (diagnose: the distinct-records check and
``_diagnose`` under the --out lock; health: ``_health_locked`` under the lock: ``assess_health`` and the outputs).

Each run is a fresh process (``python -m shm_cli.main ...`` against ``python -c <the body>``: the startup a user pays
counts, and the bench imports nothing of shm_cli), interleaved A B B A ... so a change in the machine's load hits
both alike; the ratio is the median of the command's walls over the median of the direct walls (1.0: no cost;
> 1: the batch layer costs).
Also the import time of the scale-out modules every ``shm`` start pays (``shm_cli.fleet_cmd``, loaded when the
parser is built), measured in a fresh interpreter. Noisy on a shared machine: quote as such.
"""

from __future__ import annotations

import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

from bench.bench_scale_out import _fleet, _records

#: the command's single-machine body, run in a fresh interpreter (``python -c``) on ``sys.argv[1:]``
DIRECT = {
    # shm diagnose before the batch layer: the distinct-records check and _diagnose under the --out lock
    "diagnose": """
import sys
from shm_cli.common import out_dir
from shm_cli.diagnose_cmd import _diagnose
from shm_cli.main import build_parser
from shm_cli.output_guard import locked_out
from workbench.records import check_distinct_records

args = build_parser().parse_args(sys.argv[1:])
check_distinct_records(args.records)
with locked_out(out_dir(args.out), "diagnose"):
    sys.exit(_diagnose(args))
""",
    # shm health BOARD before --fleet: assess and write the outputs under the --out lock
    "health": """
import sys
from shm_cli.common import out_dir
from shm_cli.health_cmd import _health_locked
from shm_cli.main import build_parser
from shm_cli.run_lock import OutputLock

args = build_parser().parse_args(sys.argv[1:])
out = out_dir(args.out)
lock = OutputLock(out, command="bench")
lock.acquire()
try:
    code = _health_locked(args, out)
finally:
    lock.release()
sys.exit(code)
""",
}

#: two candidates, no discovery step: a short diagnose whose cost is mostly the command around it
CANDIDATES = ["--candidates", "geometric_stiffening,m3", "--no-discover"]


def process_argv(kind: str, argv: list[str]) -> list[str]:
    """The process that runs ``argv`` as a user's command (``command``) or as its direct body (``direct``)."""
    if kind == "command":
        return [sys.executable, "-m", "shm_cli.main", *argv]
    return [sys.executable, "-c", DIRECT[argv[0]], *argv]


def _timed(kind: str, argv: list[str]) -> float:
    """Wall time of one process (interpreter start, imports, the analysis, the outputs)."""
    t0 = time.perf_counter()
    done = subprocess.run(process_argv(kind, argv), capture_output=True, text=True,
                          env=os.environ | {"MPLBACKEND": "Agg"})
    wall = time.perf_counter() - t0
    if done.returncode != 0:
        raise RuntimeError(f"bench_single_machine: {kind} {argv} exited {done.returncode}: {done.stderr[-500:]}")
    return wall


def compare(argv: list[str], reps: int) -> dict[str, float]:
    """The command and its direct body ``reps`` times each, interleaved A B B A; medians and their ratio."""
    walls: dict[str, list[float]] = {"command": [], "direct": []}
    _timed("command", argv)  # first run: caches (compiled kernels, trip boundary) for both sides alike
    for i in range(reps):
        for kind in (("command", "direct") if i % 2 == 0 else ("direct", "command")):
            walls[kind].append(_timed(kind, argv))
    cmd, dirc = statistics.median(walls["command"]), statistics.median(walls["direct"])
    return {"command_s": cmd, "direct_s": dirc, "ratio": cmd / dirc, "reps": reps}


def scale_out_import_s() -> float:
    """Seconds a fresh interpreter spends importing the scale-out modules ``shm`` loads at start (the rest of the
    command's modules already loaded): the only cost the batch layer adds before a single-machine command runs."""
    code = ("import time, shm_cli.common, shm_cli.output_guard, board_config.errors; t0 = time.perf_counter(); "
            "import shm_cli.fleet_cmd, studies.batch; print(time.perf_counter() - t0)")
    out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True,
                         env=os.environ | {"MPLBACKEND": "Agg"})
    return float(out.stdout.strip().splitlines()[-1])


def run(out_dir: Path, quick: bool) -> dict:
    base = Path(out_dir) / "single_machine"
    _records(base / "records", 1)
    board = _fleet(base / "fleet", 1)[0]
    reps = 2 if quick else 5
    diag = compare(["diagnose", str(base / "records" / "rec000.csv"), *CANDIDATES, "--out", str(base / "diag")],
                   reps)
    health = compare(["health", str(board), "--follow", "never", "--locate", "never", "--out", str(base / "health")],
                     reps)
    return {**{f"diagnose_{k}": v for k, v in diag.items()}, **{f"health_{k}": v for k, v in health.items()},
            "scale_out_import_s": min(scale_out_import_s() for _ in range(3)),
            "load_average_1min": os.getloadavg()[0]}
