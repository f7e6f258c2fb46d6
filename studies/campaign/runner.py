"""Run a campaign's batches on an executor — in-process, a local process pool (default) or a Dask cluster — and
keep every finished batch in the result store, whatever happens to the others.

All three paths submit the same module-level task (:func:`~studies.campaign.worker.run_batch`) through the
``concurrent.futures`` interface (Dask's ``Client.get_executor()``), and the results do not depend on which one
ran them (see :mod:`studies.campaign.spec`). A worker that dies (a crashed process, a Dask ``KilledWorker``)
or a task that raises is reported per batch; the batches that finished are already stored, and rerunning the
same campaign into the same directory computes only what is missing.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import threading
import time
from collections.abc import Callable
from concurrent.futures import Executor, Future, ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from multiprocessing.context import BaseContext
from pathlib import Path
from typing import Any

from board_config.errors import InputError
from firmware_sim.mbit import ClampReport
from studies.batch.runner import counted
from studies.campaign.results import CampaignResult
from studies.campaign.spec import BatchSpec, CampaignSpec
from studies.campaign.store import ResultStore
from studies.campaign.worker import BatchResult, mbit_sequence, model_from_toml, nominal_prediction, run_batch

ProgressFn = Callable[[int], None]
BatchFn = Callable[..., BatchResult]


class CampaignError(InputError):
    """The campaign cannot start (e.g. the Dask scheduler is unreachable)."""


@dataclass(frozen=True)
class BatchFailure:
    key: str
    message: str


@dataclass
class CampaignOutcome:
    """What a call of :func:`run_campaign` achieved."""

    spec: CampaignSpec
    out_dir: Path
    result: CampaignResult | None  # None unless every batch finished
    n_batches: int
    n_reused: int  # batches taken from the store (resume)
    n_computed: int
    failures: list[BatchFailure]
    notes: list[str] = field(default_factory=list)
    wall_s: float = 0.0
    executor: str = ""
    #: per MBIT key, its sequence's clamp report (campaign.json shows each one's describe())
    clamp: dict[str, ClampReport] = field(default_factory=dict)
    compute_s: float = 0.0  # summed task wall time over all workers (s)
    cpu_s: float = 0.0  # summed task CPU time over all workers (s): what the work costs, whatever the load

    @property
    def complete(self) -> bool:
        return self.result is not None

    def failure_message(self) -> str:
        done = self.n_reused + self.n_computed
        lines = [f"{len(self.failures)} of {counted(self.n_batches, 'batch', 'batches')} did not finish ({done} "
                 f"finished and stored in {self.out_dir / 'batches'}):"]
        lines += [f"  {f.key}: {f.message}" for f in self.failures[:10]]
        if len(self.failures) > 10:
            lines.append(f"  ... and {len(self.failures) - 10} more")
        lines.append("rerun the same command with the same --out to resume (finished batches are reused)")
        return "\n".join(lines)


def _describe_exception(exc: BaseException) -> str:
    if isinstance(exc, BrokenProcessPool):
        return ("a worker process died (crashed or was killed) while this batch was running or queued: "
                f"{exc}")
    name = type(exc).__name__
    if name == "KilledWorker":
        return f"the Dask workers running this batch died repeatedly (KilledWorker): {exc}"
    return f"{name}: {exc}"


#: how often a pool worker checks that the campaign process is still alive (s)
PARENT_CHECK_S = 0.5
_PR_SET_PDEATHSIG = 1


def _parent_alive(pid: int) -> bool:
    """True while process ``pid`` exists and is not a zombie (a killed parent not yet reaped counts as dead)."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as fh:
            state = fh.read().rsplit(b")", 1)[1].split()[0]
        return state not in (b"Z", b"X")
    except FileNotFoundError:
        return False
    except (OSError, IndexError):  # no /proc (not Linux): ask the kernel
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return False
        except OSError:
            return True
        return True


def _watch_parent(pid: int, ppid: int) -> None:
    while True:
        time.sleep(PARENT_CHECK_S)
        if os.getppid() != ppid or not _parent_alive(pid):
            os._exit(1)  # the campaign is gone: nobody will read this worker's results


def die_with_parent(parent_pid: int) -> None:
    """Pool-worker initializer: the worker ends when the campaign process ends, however it ends (SIGKILL included).

    Two guards: ``prctl(PR_SET_PDEATHSIG, SIGKILL)`` (Linux: the kernel kills the worker the moment its parent
    process — the campaign, or the forkserver, which itself exits with the campaign — dies), and a daemon thread
    that checks every :data:`PARENT_CHECK_S` that the campaign process ``parent_pid`` is alive (other systems, and
    the start methods where the worker's parent is not the campaign)."""
    import ctypes
    import signal

    ppid = os.getppid()
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
    except (OSError, AttributeError):
        pass
    if not _parent_alive(ppid) or not _parent_alive(parent_pid):  # died before the guard was in place
        os._exit(1)
    threading.Thread(target=_watch_parent, args=(parent_pid, ppid), name="die-with-parent", daemon=True).start()


def _process_executor(workers: int) -> tuple[ProcessPoolExecutor, str]:
    """A local process pool. ``fork`` when this process runs a single thread (the workers then inherit the loaded
    model kernels and nominal predictions: no start-up cost); otherwise ``forkserver`` (fork with live threads can
    deadlock), else ``spawn``."""
    methods = mp.get_all_start_methods()
    ctx: BaseContext
    if "fork" in methods and threading.active_count() == 1:
        method = "fork"
        ctx = mp.get_context("fork")
    elif "forkserver" in methods:
        method = "forkserver"
        ctx = mp.get_context("forkserver")
        ctx.set_forkserver_preload(["studies.campaign.worker"])
    else:
        method = "spawn"
        ctx = mp.get_context("spawn")
    return ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=die_with_parent,
                               initargs=(os.getpid(),)), method


def connect_dask(address: str, timeout_s: float = 10.0) -> Any:
    """A ``distributed.Client`` for ``address``; a clear :class:`CampaignError` if it cannot be reached."""
    try:
        from distributed import Client
    except ImportError:
        raise CampaignError("--dask-scheduler needs Dask: install the optional extra, "
                            "pip install 'mfc-shm[cluster]'") from None
    try:
        return Client(address, timeout=f"{timeout_s}s", set_as_default=False)
    except (OSError, TimeoutError) as exc:
        raise CampaignError(f"cannot reach the Dask scheduler at {address!r} within {timeout_s:g} s ({exc})"
                            ) from None
    except Exception as exc:  # malformed address and other connection errors
        raise CampaignError(f"cannot connect to the Dask scheduler at {address!r}: {type(exc).__name__}: {exc}"
                            ) from None


@dataclass
class _Tally:
    """The batches computed in this call: stored as each one finishes, their arrays, wall and CPU time."""

    store: ResultStore
    progress: ProgressFn | None
    computed: dict[str, dict] = field(default_factory=dict)
    compute_s: float = 0.0  # summed task wall time (s)
    cpu_s: float = 0.0  # summed task CPU time (s)
    failures: list[BatchFailure] = field(default_factory=list)

    def accept(self, batch: BatchSpec, res: BatchResult) -> None:
        self.store.save(res)
        self.computed[batch.key] = res.arrays
        self.compute_s += res.elapsed_s
        self.cpu_s += res.cpu_s
        if self.progress is not None:
            self.progress(batch.n)

    def fail(self, batch: BatchSpec, exc: BaseException) -> None:
        self.failures.append(BatchFailure(batch.key, _describe_exception(exc)))


def _check_executor_choice(workers: int | None, dask_scheduler: str | None) -> None:
    if workers is not None and workers < 1:
        raise InputError(f"--workers must be >= 1, got {workers}")
    if dask_scheduler is not None and workers is not None:
        raise InputError("--workers and --dask-scheduler are exclusive (the cluster decides its workers)")


def _open_executor(n_todo: int, workers: int | None, dask_scheduler: str | None, dask_client: Any,
                   dask_timeout_s: float) -> tuple[Executor | None, Any, str]:
    """The executor for ``n_todo`` batches (``None``: run them in this process), the Dask client it came from
    (``None`` unless Dask) and its description for the outcome."""
    if not n_todo:
        return None, None, "none (all batches reused from the store)"
    if dask_scheduler is not None or dask_client is not None:
        if dask_client is not None:
            client = dask_client
        else:
            assert dask_scheduler is not None  # one of the two, by the condition above
            client = connect_dask(dask_scheduler, dask_timeout_s)
        return client.get_executor(pure=False), client, f"dask {client.scheduler.address}"
    if (workers or os.cpu_count() or 1) == 1:
        return None, None, "in-process"
    n_proc = min(workers or os.cpu_count() or 1, n_todo)
    executor, method = _process_executor(n_proc)
    return executor, None, f"process pool ({counted(n_proc, 'worker')}, {method})"


def _run_batches(todo: list[BatchSpec], executor: Executor | None, batch_fn: BatchFn, tally: _Tally) -> None:
    """Run ``todo`` in this process (``executor`` None, the plant's own batch threads) or on ``executor`` (one
    thread per task); every finished batch is stored at once and a failing batch never loses the others."""
    if executor is None:
        for batch in todo:
            try:
                tally.accept(batch, batch_fn(batch, None))
            except Exception as exc:  # a failing batch must not lose the others
                tally.fail(batch, exc)
        return
    futures: dict[Future, BatchSpec] = {executor.submit(batch_fn, b, 1): b for b in todo}
    for fut in as_completed(futures):
        batch = futures[fut]
        try:
            res = fut.result()
        except Exception as exc:
            tally.fail(batch, exc)
            continue
        tally.accept(batch, res)


def run_campaign(
    spec: CampaignSpec,
    out_dir: str | Path,
    *,
    workers: int | None = None,
    dask_scheduler: str | None = None,
    dask_client: Any = None,
    dask_timeout_s: float = 10.0,
    fresh: bool = False,
    progress: ProgressFn | None = None,
    batch_fn: BatchFn = run_batch,
) -> CampaignOutcome:
    """Run (or resume) a campaign into ``out_dir``.

    ``workers``: local processes (default ``os.cpu_count()``); ``1`` runs in this process (with the plant's
    batch threads). ``dask_scheduler``: address of a Dask scheduler (``tcp://host:8786``) — or pass a connected
    ``dask_client`` — to run the same tasks there. ``progress(n_runs)`` is called as runs finish (reused batches
    first). ``batch_fn`` is the task (a module-level callable taking ``(BatchSpec, threads)``).
    """
    t_start = time.perf_counter()
    _check_executor_choice(workers, dask_scheduler)
    out_dir = Path(out_dir)
    # fail fast on the model and the MBIT sequences in this process (clear errors, clamp reports)
    model = model_from_toml(spec.params_toml)
    for m in spec.mbits:
        nominal_prediction(spec, m)  # fails fast here, and forked workers inherit it
    clamp = {m.key: mbit_sequence(m).clamp for m in spec.mbits}
    notes = [mbit_sequence(m).clamp.message(m.label) for m in spec.mbits if mbit_sequence(m).clamp.clamped]
    store = ResultStore(out_dir, spec, fresh=fresh)
    batches = spec.batches()
    stored = store.finished()
    todo = [b for b in batches if b.key not in stored]
    if progress is not None and stored:
        progress(sum(b.n for b in batches if b.key in stored))

    tally = _Tally(store, progress)
    executor, client, desc = _open_executor(len(todo), workers, dask_scheduler, dask_client, dask_timeout_s)
    try:
        _run_batches(todo, executor, batch_fn, tally)
    finally:
        if isinstance(executor, ProcessPoolExecutor):
            executor.shutdown(wait=True, cancel_futures=True)
        if client is not None and dask_client is None:
            client.close()

    notes += store.notes
    result = None
    if not tally.failures:
        arrays = [stored[b.key] if b.key in stored else tally.computed[b.key] for b in batches]
        result = CampaignResult.from_batches(spec, arrays, tuple(model.param_units[model.param_index(n)]
                                                                 for n in spec.deviated))
    failures = sorted(tally.failures, key=lambda f: f.key)
    return CampaignOutcome(spec=spec, out_dir=out_dir, result=result, n_batches=len(batches),
                           n_reused=len(stored), n_computed=len(tally.computed), failures=failures, notes=notes,
                           wall_s=time.perf_counter() - t_start, executor=desc, clamp=clamp,
                           compute_s=tally.compute_s, cpu_s=tally.cpu_s)
