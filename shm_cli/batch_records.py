"""Many records in one command: ``shm compare|diagnose|discover|fit FOLDER-or-'GLOB' --scheduler ...`` (issue 31).

A folder or a glob (:mod:`studies.batch.inputs`) makes one task per record file and one per subfolder (a named
group, analysed together). Each task runs the single-record command itself on a worker
(:func:`run_command_task`: the same code, the same numbers) on the record's bytes, scattered to the workers once;
its report comes back and is written into ``--out/<task>/``; ``--out`` gets ``summary.csv``/``summary.html`` over
all tasks and ``batch.json`` (per task: exit code, message, the summary row; the run's cost). Exit 0 when every
task succeeded, 1 when one failed (the others are kept), 2 for bad input.
"""

from __future__ import annotations

import argparse
import contextlib
import copy
import functools
import io
import json
import os
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from board_config.errors import InputError
from shm_cli.batch_out import TASK_FILES, check_batch_out, earlier_task_files, write_task_folders
from shm_cli.common import dump_json, out_dir
from shm_cli.output_guard import locked_out
from shm_cli.run_lock import LOCK_NAME

#: the JSON document each command writes into its --out
DOC_NAME = {"run": "life.json",
            "compare": "compare.json", "diagnose": "diagnosis.json", "discover": "discover.json", "fit": "fit.json",
            "health": "health.json"}
#: the command's own page in its --out (the summary links to it)
REPORT_NAME = {"run": "report.html",
               "compare": "report.html", "diagnose": "diagnosis.html", "discover": "discover.json", "fit": "fit.html",
               "health": "report.html"}


def add_scheduler_arg(p: argparse.ArgumentParser) -> None:
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="with a folder or 'glob' of records: where the tasks run — local (default: local worker "
                        "processes), tcp://HOST:PORT (a Dask cluster) or synchronous (this process, for debugging); "
                        "docs/scale-out.md")


def wanted(args: argparse.Namespace, items: list[str]) -> bool:
    """Batch mode: an input is a folder or a glob. ``--scheduler`` alone (files only) is a usage error."""
    from studies.batch import is_batch_input

    if is_batch_input(items):
        return True
    if getattr(args, "scheduler", None) is not None:
        raise InputError("--scheduler runs one task per record of a folder or a 'glob' pattern; give a folder or a "
                         "quoted pattern (files listed one by one are analysed together, in this process)")
    return False


# --- on the worker -----------------------------------------------------------------------------------------------
def _scrub(text: str, tmp: str) -> str:
    """Worker-local paths out of a report: record names stay, the temporary folders go (same text anywhere)."""
    return text.replace(f"{tmp}/in/", "").replace(f"{tmp}/out/", "").replace(tmp, ".")


def _collect(out: Path, tmp: str) -> dict[str, bytes]:
    """The task's report files; not the ``--out`` lock file its command took in its temporary folder (an empty
    ``.shm-run.lock`` had been copied into every task's folder)."""
    files = {}
    for p in sorted(out.rglob("*")):
        if p.is_file() and p.name != LOCK_NAME:
            data = p.read_bytes()
            if p.suffix in (".json", ".html", ".txt", ".csv", ".py", ".md", ".toml"):
                data = _scrub(data.decode("utf-8", "replace"), tmp).encode("utf-8")
            files[str(p.relative_to(out))] = data
    return files


def _task_args(args: argparse.Namespace, tmp: Path, names: list[str], shared: dict[str, bytes]) -> argparse.Namespace:
    ns = copy.copy(args)
    if ns.command == "health":  # a board: its run directory (usage.db, records/)
        ns.sources, ns.fleet, ns.workers = [str(tmp / "in")], False, 1
    elif ns.command == "run":  # a board's life: its own scenario file, its visits in this task (no pool of its own)
        ns.scenario, ns.boards, ns.life_workers = str(tmp / "in" / names[0]), None, 1
    else:
        ns.records = [str(tmp / "in" / n) for n in names]
    ns.out = str(tmp / "out")
    ns.json = False
    ns.scheduler = None
    if "params" in shared:  # a parameter-set file: broadcast once, one copy per task folder
        (tmp / "params.toml").write_bytes(shared["params"])
        ns.params = str(tmp / "params.toml")
    if getattr(ns, "save", None):
        ns.save = str(tmp / "out" / Path(ns.save).name)
    if getattr(ns, "emit", None):
        ns.emit = str(tmp / "out" / Path(ns.emit).name)
    return ns


def run_command_task(key: str, files: dict[str, bytes], shared: dict[str, bytes], args: argparse.Namespace) -> Any:
    """One record (or group): the single-record command on the worker, its report returned as bytes."""
    from studies.batch import TaskResult

    t0, c0 = time.perf_counter(), time.process_time()
    with tempfile.TemporaryDirectory(prefix="shm-task-") as tmp_name:
        tmp = Path(tmp_name)
        (tmp / "in").mkdir()
        for rel, data in files.items():
            (tmp / "in" / rel).parent.mkdir(parents=True, exist_ok=True)
            (tmp / "in" / rel).write_bytes(data)
        ns = _task_args(args, tmp, list(files), shared)
        log = io.StringIO()
        try:
            with contextlib.redirect_stdout(log), contextlib.redirect_stderr(log):
                code = int(ns.func(ns) or 0)
            message = ""
        except InputError as exc:
            code, message = 2, " ".join(str(exc).split())
        except Exception as exc:  # one task failing must not lose the others: reported in its row
            code, message = 1, f"{type(exc).__name__}: {' '.join(str(exc).split())}"
        message = _scrub(message, tmp_name)  # 'broken.csv, line 2: ...', not the worker's temporary folder
        out = tmp / "out"
        out.mkdir(exist_ok=True)
        (out / "log.txt").write_text(log.getvalue() + (f"\n{message}\n" if message else ""), encoding="utf-8")
        result = _collect(out, tmp_name)
    doc_name = DOC_NAME[args.command]
    doc = json.loads(result[doc_name]) if doc_name in result else {}
    if not message:
        message = str(doc.get("message") or doc.get("verdict") or ("done" if code == 0 else f"exit {code}"))
    return TaskResult(key, code, message.splitlines()[0] if message else "", doc, result,
                      time.perf_counter() - t0, time.process_time() - c0, f"{os.uname().nodename}:{os.getpid()}")


#: the rooms each command imports when it runs (imported by the warm-up, so a worker's first task is not seconds
#: longer than the others: 2.4 s against 0.55 s of CPU for a diagnose task before)
COMMAND_MODULES = {"diagnose": ("workbench.diagnose", "workbench.fit", "workbench.localise"),
                   "fit": ("workbench.fit", "workbench.diagnose"),
                   "compare": ("workbench.compare", "workbench.fit", "workbench.localise"),
                   "discover": ("workbench.discover",),
                   # a fleet's board: the health rooms, the fit room they call per visit, scipy.optimize under them
                   # and scipy.interpolate (the trip boundary's grid): 0.5 s of CPU in each worker's first board before
                   "health": ("studies.health.assess", "studies.health.report", "workbench.fit", "scipy.interpolate")}


def warm_workbench(command: str | None = None) -> None:
    """Load the commands' modules and ``command``'s rooms, draw one figure in memory (fonts, math text), and compile
    or load the nominal model's kernel on a worker (before its first task)."""
    import importlib

    import shm_cli.main  # noqa: F401  (every command's module)
    from reporting.figures import warm_up
    from workbench.simulation import synth_record, synth_test, truth_model

    for name in COMMAND_MODULES.get(command or "", ()):
        importlib.import_module(name)
    warm_up()  # fonts and the math-text parser of the first report
    nominal = truth_model("table2", [], {})
    synth_record(synth_test("mbit-b", duration_s=0.2, t_step_s=0.05), nominal)
    warm_lanes(nominal)


def warm_lanes(model: Any) -> None:
    """Load (or compile) ``model``'s lane integrator: a fit's batches of >= 16 parameter sets run on it, and a
    synthetic record (one trajectory) does not touch it — otherwise a worker's first fit loads it."""
    import numpy as np

    from plant import InputSignals

    model.simulate(InputSignals(0.0, 1e-3, np.zeros((20, 3))), params=np.tile(model.p_nominal, (2, 1)), lanes=True)


def dask_setup(worker: Any) -> None:
    """``dask worker --preload shm_cli.batch_records`` (or ``LocalCluster(preload=[...])``): every command's rooms
    and kernels loaded when the worker starts, once for the worker's life, instead of in each run's warm-up (seconds
    per worker that a run on a standing cluster then does not wait for; docs/scale-out.md)."""
    for command in COMMAND_MODULES:
        warm_workbench(command)


# --- in the command's process ------------------------------------------------------------------------------------
def summary_row(command: str, doc: dict[str, Any]) -> dict[str, Any]:
    from studies.batch.summary import scalar_columns

    row = scalar_columns(doc, skip=("wall_s",))
    if command == "diagnose" and isinstance(doc.get("baseline"), dict):
        row["nominal_held_rms_sigma"] = doc["baseline"].get("held_rms_sigma")
    if command == "fit":
        row.update(fit_columns(doc))
    for rec in doc.get("records", []) if command == "compare" else []:
        for ch, m in (rec.get("metrics") or {}).items():
            row[f"{ch}_verdict"] = (rec.get("verdicts") or {}).get(ch)
            row[f"{ch}_fit_pct"] = m.get("fit_pct")
            row[f"{ch}_rmse_{m.get('unit', 'SI')}"] = m.get("rmse")
    return row


def fit_columns(doc: dict[str, Any]) -> dict[str, Any]:
    """A fit's row: the held-out and training RMS before and after (in sigma), whether the model explains the
    record, and each estimate with its standard error, unit in the name (``k3_N_per_m``, ``k3_stderr_N_per_m``)."""
    row: dict[str, Any] = {}
    for part in ("held", "train"):
        rms = doc.get(f"{part}_rms_sigma")
        if isinstance(rms, dict):
            row.update({f"{part}_rms_{when}_sigma": rms.get(when) for when in ("before", "after")})
    if "model_explains_record" in doc:
        row["model_explains_record"] = doc["model_explains_record"]
    for est in doc.get("estimates") or []:
        unit = str(est.get("unit") or "1").replace("*", "").replace("/", "_per_").replace(" ", "").replace("^", "")
        row[f"{est['name']}_{unit}"] = est.get("value")
        row[f"{est['name']}_stderr_{unit}"] = est.get("stderr")
    return row


def _progress_printer(command: str):
    last = [""]

    def show(p) -> None:
        line = p.line(f"shm {command}")
        if line != last[0]:
            print(line, file=sys.stderr, flush=True)
            last[0] = line
    return show


def run_batch(command: str, args: argparse.Namespace, items: list[str]) -> int:
    """The batch: tasks, the scheduler, each task's report in its subfolder, the summary, batch.json."""
    from studies.batch import expand_inputs
    from studies.batch.runner import check_scheduler, reach_scheduler

    scheduler = check_scheduler(getattr(args, "scheduler", None))
    tasks = expand_inputs(items)
    shared = {}
    params = getattr(args, "params", None)
    if params and Path(params).is_file():
        shared["params"] = Path(params).read_bytes()
    check_batch_out(Path(args.out), command, [t.key for t in tasks], ("summary.csv", "summary.html", "batch.json"),
                    DOC_NAME[command], bool(getattr(args, "force", False)), force_hint=hasattr(args, "force"))
    reach_scheduler(scheduler)  # an unknown host or a closed port: one line, before --out is made
    out = out_dir(args.out)
    with locked_out(out, command):
        return _run_batch_locked(command, args, tasks, shared, scheduler, out)


def _run_batch_locked(command: str, args: argparse.Namespace, tasks: list[Any], shared: dict[str, bytes],
                      scheduler: str | None, out: Path) -> int:
    from studies.batch import run_tasks
    from studies.batch.runner import counted
    from studies.batch.summary import write_summary

    args.command = command
    print(f"shm {command}: {counted(len(tasks), 'task')} ({counted(sum(len(t.files) for t in tasks), 'record')}) on "
          f"{scheduler or 'local'}", file=sys.stderr, flush=True)
    outcome = run_tasks([(t.key, t.read()) for t in tasks], run_command_task, args, shared=shared,
                        scheduler=scheduler, warm=functools.partial(warm_workbench, command),
                        progress=_progress_printer(command),
                        longest_first=True)
    task_files = write_task_folders(out, {r.key: r.files for r in outcome.results},
                                    earlier_task_files(out, "batch.json"), f"shm {command}")
    rows, report_of = [], {}
    for r in outcome.results:
        if REPORT_NAME[command] in r.files:
            report_of[r.key] = f"{r.key}/{REPORT_NAME[command]}"
        rows.append({"task": r.key, "records": " ".join(t.name for t in _files_of(tasks, r.key)),
                     "exit_code": r.code, **summary_row(command, r.doc), "message": r.message})
    paths = write_summary(out, f"shm {command}: {counted(len(rows), 'task')}", rows, report_of)
    doc = {"command": command, "tasks": rows, "files": {k: str(v) for k, v in paths.items()},
           "cost": outcome.cost()}
    (out / "batch.json").write_text(dump_json({**doc, TASK_FILES: task_files}), encoding="utf-8")
    failed = [r for r in outcome.results if r.code != 0]
    for r in failed:
        print(f"shm {command}: {r.key}: exit {r.code}: {r.message}", file=sys.stderr)
    print(f"shm {command}: {len(rows) - len(failed)} of {counted(len(rows), 'task')} done in {outcome.wall_s:.1f} s "
          f"({outcome.scheduler}); summary: {paths['html']}", file=sys.stderr)
    if args.json:
        print(dump_json(doc))
    return 1 if failed else 0


def _files_of(tasks, key: str) -> tuple[Path, ...]:
    return next(t.files for t in tasks if t.key == key)
