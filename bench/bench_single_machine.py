"""Issue 31's "nothing in the single-machine commands gets slower", as a same-run ratio: ``shm diagnose ONE.csv`` and
``shm health BOARD`` as a user runs them (``shm_cli.main.main``: the parser with the scale-out options, the
command's check for a folder/glob or ``--fleet``) against the command's single-machine body called directly in this
process — what the command ran before the batch layer existed (diagnose: the distinct-records check and
``_diagnose`` under the --out lock; health: ``_health_locked`` under the lock: ``assess_health`` and the outputs).

Both run in this process, interleaved A B B A ... so a change in the machine's load hits both alike; the ratio is
the median of the command's walls over the median of the direct walls (1.0: no cost; > 1: the batch layer costs).
Also the import time of the scale-out modules every ``shm`` start pays (``shm_cli.fleet_cmd``, loaded when the
parser is built), measured in a fresh interpreter. Noisy on a shared machine: quote as such.
"""

from __future__ import annotations

import contextlib
import io
import os
import statistics
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

from bench.bench_scale_out import CANDIDATES, _fleet, _records


def _diagnose_direct(argv: list[str]) -> int:
    """``shm diagnose`` as it was before the batch layer: the same checks and body, no folder/glob dispatch."""
    from shm_cli.common import out_dir
    from shm_cli.diagnose_cmd import _diagnose
    from shm_cli.main import build_parser
    from shm_cli.output_guard import locked_out
    from workbench.records import check_distinct_records

    args = build_parser().parse_args(argv)
    check_distinct_records(args.records)
    with locked_out(out_dir(args.out), "diagnose"):
        return _diagnose(args)


def _health_direct(argv: list[str]) -> int:
    """``shm health BOARD`` as it was before ``--fleet``: assess and write the outputs under the --out lock."""
    from shm_cli.common import out_dir
    from shm_cli.health_cmd import _health_locked
    from shm_cli.main import build_parser
    from shm_cli.run_lock import OutputLock
    from studies.health.assess import assess_health
    from studies.health.evaluate import LAMBDAS
    from studies.health.report import evaluation_text, four_levels_text, health_json, write_health_outputs

    args = build_parser().parse_args(argv)
    out = out_dir(args.out)
    lock = OutputLock(out, command="bench")
    lock.acquire()
    try:
        return _health_locked(args, out, assess_health, LAMBDAS, evaluation_text, four_levels_text, health_json,
                              write_health_outputs)
    finally:
        lock.release()


def _command(argv: list[str]) -> int:
    from shm_cli.main import main

    return main(argv)


def _timed(fn: Callable[[list[str]], int], argv: list[str]) -> float:
    t0 = time.perf_counter()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        code = fn(argv)
    wall = time.perf_counter() - t0
    if code != 0:
        raise RuntimeError(f"bench_single_machine: {fn.__name__} {argv} exited {code}")
    return wall


def compare(argv: list[str], direct: Callable[[list[str]], int], reps: int) -> dict[str, float]:
    """The command and its direct body ``reps`` times each, interleaved A B B A; medians and their ratio."""
    cmd_walls: list[float] = []
    direct_walls: list[float] = []
    _timed(_command, argv)  # first call: imports and compiled kernels, paid by neither side's timings
    for i in range(reps):
        pair = [(_command, cmd_walls), (direct, direct_walls)]
        for fn, walls in (pair if i % 2 == 0 else pair[::-1]):
            walls.append(_timed(fn, argv))
    cmd, dirc = statistics.median(cmd_walls), statistics.median(direct_walls)
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
                   _diagnose_direct, reps)
    health = compare(["health", str(board), "--follow", "never", "--locate", "never", "--out", str(base / "health")],
                     _health_direct, reps)
    return {**{f"diagnose_{k}": v for k, v in diag.items()}, **{f"health_{k}": v for k, v in health.items()},
            "scale_out_import_s": min(scale_out_import_s() for _ in range(3)),
            "load_average_1min": os.getloadavg()[0]}
