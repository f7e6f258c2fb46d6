"""Issue 31 point 4: a real Dask cluster from the command line (``dask scheduler`` + two ``dask worker`` on
loopback, random free ports): a multi-record diagnose and a small fleet (``shm run --boards``, ``shm health
--fleet``) through ``--scheduler tcp://...`` equal the in-process run bit for bit (timings aside), and a worker
killed (SIGKILL) mid-run loses nothing — its tasks rerun, the results are the same, the progress line says a worker
was lost."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from timings_support import timeless

from shm_cli.main import main
from workbench.records import write_record
from workbench.simulation import synth_record, synth_test, truth_model

BIN = Path(sys.executable).parent
ENV = os.environ | {"MPLBACKEND": "Agg", "PYTHONHASHSEED": "0",
                    "NUMBA_CACHE_DIR": os.environ.get("NUMBA_CACHE_DIR",
                                                      str(Path.home() / ".cache/mfc-shm/numba"))}
DIAGNOSE = ["--candidates", "geometric_stiffening,m3", "--no-discover"]
N_RECORDS = 4


def _records(folder: Path) -> Path:
    folder.mkdir()
    for i in range(N_RECORDS):
        rec = synth_record(synth_test("mbit-b", duration_s=1.0),
                           truth_model("table2", ["geometric_stiffening"], {"kappa_nl": 1e4 * (1 + i)}),
                           noise={"z3": 2e-6}, seed=i)
        write_record(rec, folder / f"board{i}.csv")
    return folder


def _results(out: Path) -> dict[str, object]:
    got: dict[str, object] = {"summary.csv": (out / "summary.csv").read_bytes()}
    for p in sorted(out.glob("*/diagnosis.json")):
        got[p.parent.name] = timeless(json.loads(p.read_text()))
    return got


class Cluster:
    """``dask scheduler`` and ``dask worker`` processes (no nanny: a killed worker stays dead)."""

    def __init__(self, tmp: Path, n_workers: int) -> None:
        self.file = tmp / "scheduler.json"
        self.procs: list[subprocess.Popen] = []
        self.procs.append(self._start(["scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                                       "--scheduler-file", str(self.file)], tmp / "scheduler.log"))
        deadline = time.monotonic() + 30
        while not self.file.exists() and time.monotonic() < deadline:
            time.sleep(0.1)
        assert self.file.exists(), (tmp / "scheduler.log").read_text()
        time.sleep(0.2)
        self.address = json.loads(self.file.read_text())["address"]
        self.workers = [self._start(["worker", "--scheduler-file", str(self.file), "--nthreads", "1", "--no-nanny",
                                     "--host", "127.0.0.1", "--no-dashboard", "--memory-limit", "0"],
                                    tmp / f"worker{i}.log") for i in range(n_workers)]
        self.procs += self.workers
        self._wait_workers(n_workers)

    def _start(self, argv: list[str], log: Path) -> subprocess.Popen:
        return subprocess.Popen([str(BIN / "dask"), *argv], stdout=subprocess.DEVNULL, stderr=log.open("w"),
                                env=ENV, cwd=log.parent)

    def _wait_workers(self, n: int) -> None:
        from distributed import Client

        with Client(self.address, timeout="20s", set_as_default=False) as c:
            c.wait_for_workers(n, timeout=60)

    def busy_worker(self) -> subprocess.Popen:
        """The worker process that is running a task now (waits up to 10 s for one)."""
        from distributed import Client

        with Client(self.address, timeout="20s", set_as_default=False) as c:
            deadline = time.monotonic() + 10
            while time.monotonic() < deadline:
                busy = [a for a, tasks in c.processing().items() if tasks]
                if busy:
                    pid = c.run(os.getpid, workers=busy[:1])[busy[0]]
                    return next(p for p in self.workers if p.pid == pid)
                time.sleep(0.02)
        raise AssertionError("no worker was running a task")

    def close(self) -> None:
        for p in reversed(self.procs):
            if p.poll() is None:
                p.terminate()
        for p in self.procs:
            try:
                p.wait(timeout=3)
            except subprocess.TimeoutExpired:
                p.kill()


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("cluster")
    records = _records(tmp / "records")
    ref = tmp / "ref"
    assert main(["diagnose", str(records), *DIAGNOSE, "--scheduler", "synchronous", "--out", str(ref)]) == 0
    cluster = Cluster(tmp, 2)
    try:
        yield tmp, records, _results(ref), cluster
    finally:
        cluster.close()


@pytest.mark.slow
def test_cluster_diagnose_equals_the_in_process_run(setup):
    tmp, records, reference, cluster = setup
    out = tmp / "cluster"
    assert main(["diagnose", str(records), *DIAGNOSE, "--scheduler", cluster.address, "--out", str(out)]) == 0
    assert len(reference) == N_RECORDS + 1
    assert _results(out) == reference
    cost = json.loads((out / "batch.json").read_text())["cost"]
    assert cost["workers"] == 2 and cost["workers_lost"] == 0
    assert set(cost["warm_s"]) == set(cost["warm_s"]) and len(cost["warm_s"]) == 2  # both workers warmed once
    assert cost["bytes_scattered"] == sum(p.stat().st_size for p in records.iterdir())  # each record sent once


@pytest.mark.slow
def test_cluster_fleet_equals_the_in_process_run(setup):
    """The small fleet through the same cluster: ``shm run --boards 2`` (a short aging life) and ``shm health
    --fleet`` on it give the in-process run's boards table, fleet table and health reports (timings aside)."""
    from board_config.scenario import load_scenario

    tmp, _records, _reference, cluster = setup
    text = Path(load_scenario("aging").source).read_text(encoding="utf-8")
    short = text.replace('visits = { value = 24, unit = "1" }', 'visits = { value = 4, unit = "1" }').replace(
        'visit_interval = { value = 100, unit = "h" }', 'visit_interval = { value = 300, unit = "h" }')
    assert short != text
    (tmp / "short.toml").write_text(short, encoding="utf-8")
    for where in ("synchronous", cluster.address):
        name = "here" if where == "synchronous" else "cluster"
        assert main(["run", "--scenario", str(tmp / "short.toml"), "--boards", "2", "--seed", "3", "--scheduler",
                     where, "--out", str(tmp / f"boards_{name}")]) == 0
    assert (tmp / "boards_here" / "boards.csv").read_bytes() == (tmp / "boards_cluster" / "boards.csv").read_bytes()
    boards = [str(tmp / "boards_cluster" / b) for b in ("board000", "board001")]
    for where in ("synchronous", cluster.address):
        name = "here" if where == "synchronous" else "cluster"
        assert main(["health", "--fleet", *boards, "--follow", "never", "--locate", "never", "--scheduler", where,
                     "--out", str(tmp / f"fleet_{name}")]) == 0
    assert (tmp / "fleet_here" / "fleet.csv").read_bytes() == (tmp / "fleet_cluster" / "fleet.csv").read_bytes()
    for b in ("board000", "board001"):
        here, there = (json.loads((tmp / f"fleet_{n}" / b / "health.json").read_text()) for n in ("here", "cluster"))
        assert timeless(here) == timeless(there)
    assert json.loads((tmp / "fleet_cluster" / "fleet.json").read_text())["cost"]["scheduler"] == \
        f"dask {cluster.address}"


@pytest.mark.slow
def test_a_worker_killed_mid_run_loses_nothing(setup):
    tmp, records, reference, cluster = setup
    out = tmp / "killed"
    proc = subprocess.Popen([str(BIN / "shm"), "diagnose", str(records), *DIAGNOSE, "--scheduler", cluster.address,
                             "--out", str(out)], stderr=subprocess.PIPE, text=True, env=ENV)
    assert proc.stderr is not None
    lines: list[str] = []
    victim: subprocess.Popen | None = None
    for line in proc.stderr:
        lines.append(line)
        # the first progress line while tasks remain (two tasks may finish in one poll, so no exact count):
        # kill a worker that is running a task right now, so that task must be rerun
        if victim is None and (m := re.search(r"(\d+)/(\d+) tasks done", line)) and int(m[1]) < int(m[2]):
            victim = cluster.busy_worker()
            victim.send_signal(signal.SIGKILL)
    assert proc.wait(timeout=120) == 0, "".join(lines)
    assert victim is not None and victim.poll() is not None, "".join(lines)
    assert any("1 worker lost" in line and "rerun" in line for line in lines), "".join(lines)
    assert _results(out) == reference
    cost = json.loads((out / "batch.json").read_text())["cost"]
    assert cost["workers_lost"] == 1 and cost["reruns"] >= 1
