"""Issue 31: every shell example of docs/scale-out.md and of README's "Many records and a fleet on Dask" section runs
as copied, in order, in a shell (quotes and globs as a user's shell treats them) — ``shm ...`` lines and the
``dask scheduler``/``dask worker`` lines of the by-hand cluster. What a reader replaces is replaced: the example
cluster ``tcp://10.0.0.5:8786`` and port 8786 by this test's cluster on a free loopback port, ``--boards 20`` by 2,
the 24-visit ``aging`` life by README's ``short-aging.toml`` (5 visits 250 h apart), and ``records/`` holds two short
records. Both docs run in one folder, in order, as a reader who follows both would; a line README repeats word for
word from docs/scale-out.md runs once (its output is already there for the lines after it). The ``python -m bench``
lines are test_scale_out_cases.py's. Each line must exit 0; a ``--json`` line prints one JSON document."""

from __future__ import annotations

import json
import os
import re
import shlex
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from workbench.records import write_record
from workbench.simulation import synth_record, synth_test, truth_model

pytestmark = pytest.mark.slow
ROOT = Path(__file__).resolve().parents[2]
BIN = Path(sys.executable).parent
COMMAND = re.compile(r"(shm|dask) ")


def _blocks(text: str) -> list[str]:
    return re.findall(r"^```[a-z]*\n(.*?)^```", text, flags=re.S | re.M)


def example_lines(text: str) -> list[str]:
    """The command lines of ``text``'s fenced blocks (``$ `` prompts removed; a program's output lines — a
    progress line ``shm run --boards: 1/2 ...`` — are not commands: a word of theirs ends with a colon)."""
    lines = []
    for block in _blocks(text):
        for line in block.splitlines():
            line = line.removeprefix("$ ").split(" #")[0].strip()
            if COMMAND.match(line) and not any(w.endswith(":") for w in line.split()):
                lines.append(line)
    return lines


def doc_examples() -> dict[str, list[str]]:
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    section = readme[readme.index("Many records and a fleet on Dask"):readme.index("## Dependencies and why")]
    return {"docs/scale-out.md": example_lines((ROOT / "docs" / "scale-out.md").read_text(encoding="utf-8")),
            "README.md": example_lines(section)}


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _setup(folder: Path) -> None:
    from board_config.scenario import load_scenario

    (folder / "records").mkdir(parents=True)
    for i in range(2):
        rec = synth_record(synth_test("mbit-b", duration_s=1.0), truth_model("table2", [], {}), noise={"z3": 2e-6},
                           seed=i)
        write_record(rec, folder / "records" / f"visit{i}.csv")
    text = Path(load_scenario("aging").source).read_text(encoding="utf-8")
    short = text.replace('visits = { value = 24, unit = "1" }', 'visits = { value = 5, unit = "1" }').replace(
        'visit_interval = { value = 100, unit = "h" }', 'visit_interval = { value = 250, unit = "h" }')
    assert short != text
    (folder / "short-aging.toml").write_text(short, encoding="utf-8")


def _as_run_here(line: str, example_port: int, port: int) -> str:
    line = line.replace("tcp://10.0.0.5:8786", f"tcp://127.0.0.1:{example_port}").replace("8786", str(port))
    line = line.replace("--boards 20", "--boards 2")
    return re.sub(r"--scenario aging\b", "--scenario short-aging.toml", line)


def test_the_examples_are_found():
    found = doc_examples()
    assert len(found["docs/scale-out.md"]) >= 10 and len(found["README.md"]) >= 5, found
    assert any(ln.startswith("dask scheduler") for ln in found["docs/scale-out.md"])
    assert not any(":" in ln.split()[1] for lines in found.values() for ln in lines)  # no output line taken


def test_every_shell_example_runs_as_copied(tmp_path):
    env = os.environ | {"PATH": f"{BIN}{os.pathsep}{os.environ.get('PATH', '')}", "MPLBACKEND": "Agg",
                        "PYTHONPATH": str(ROOT), "PYTHONHASHSEED": "0"}
    example_port, port = _free_port(), _free_port()
    daemons: list[subprocess.Popen] = []
    failures = []

    def start(command: str, log: Path) -> None:
        daemons.append(subprocess.Popen(shlex.split(command), cwd=log.parent, env=env, stdout=log.open("w"),
                                        stderr=subprocess.STDOUT))

    # the cluster the examples' tcp://10.0.0.5:8786 stands for (the by-hand block starts its own on `port`)
    start(f"dask scheduler --host 127.0.0.1 --port {example_port} --no-dashboard", tmp_path / "example_cluster.log")
    start(f"dask worker tcp://127.0.0.1:{example_port} --nthreads 1 --no-dashboard", tmp_path / "example_worker.log")
    here = tmp_path / "reader"  # one folder, the docs read in order: README's lines follow docs/scale-out.md's
    _setup(here)
    done: set[str] = set()
    try:
        for doc, lines in doc_examples().items():
            for line in lines:
                command = _as_run_here(line, example_port, port)
                if command.endswith("&"):  # the by-hand cluster: kept running for the lines after it
                    start(command.rstrip("&"), here / f"daemon{len(daemons)}.log")
                    continue
                if command in done:  # the same line in both docs, already run here: its output is in place
                    continue
                done.add(command)
                r = subprocess.run(["bash", "-c", command], cwd=here, env=env, capture_output=True, text=True,
                                   timeout=600)
                if r.returncode != 0:
                    failures.append(f"{doc}: {line!r} -> exit {r.returncode}: {r.stderr.strip()[-600:]}")
                elif "--json" in command.split():
                    json.loads(r.stdout)  # exactly one document
    finally:
        for p in daemons:
            p.terminate()
        for p in daemons:
            try:
                p.wait(timeout=10)
            except subprocess.TimeoutExpired:
                p.kill()
    assert not failures, "\n".join(failures)
