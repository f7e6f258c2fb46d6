"""``shm run``: the board firmware living through a scenario on a rig — the main job (``make run``).

    shm run [--scenario FILE|NAME] [--link sim|URL] [--params NAME] [--seed S] [--realtime|--virtual]
            [--duration-s S] [--board-config FILE] [--json] [--quiet] --out DIR

Writes to ``--out``: ``usage.db`` (the board's SQLite usage/event log), ``timeline.txt`` (what was printed),
``trace.csv`` (10 Hz) and ``trace.npz`` (every tick), ``overview.png``, ``maintenance.png``, ``usage.png``,
``summary.json`` and ``report.html`` (self-contained).

Nothing a user made is lost: ``--out`` is locked while a run uses it (a second run on it refuses, naming the running
one: pid, start time, command); a directory holding an earlier run is refused unless ``--force`` (replace it) or
``--append`` (add this run to its ``usage.db``; the other files then describe this run); ``--append`` refuses a
database that is not an mfc-shm usage log. SIGTERM and Ctrl-C end the run cleanly after the current tick: the board
closes, the run's status is recorded as ``interrupted``, the timeline, traces, summary and report are written (of
the part that ran), and the exit code is 130 (Ctrl-C) or 143 (SIGTERM); a second signal aborts at once. A scenario
with ``[life]`` is run by :mod:`shm_cli.life_cmd` (visits on worker processes; a stop keeps the finished visits).

Exit code 0 when the run completed with the expected verdict (or the scenario expects none), 1 when the verdict is
not the expected one or the run could not complete (the rig's integration failed, the log could not be written),
2 for bad input, 130/143 when interrupted.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import shutil
import signal
import sys
import threading
import time
from pathlib import Path
from typing import Any

from board_config.errors import InputError
from shm_cli.common import (
    Decorations,
    add_out_arg,
    check_memory,
    dump_json,
    nonnegative_float,
    out_dir,
)
from shm_cli.live_args import add_live_args, attach_live_board, refuse_live_for_a_life, start_live
from studies.board_run.timeline import format_event

EXIT_SIGINT = 130
EXIT_SIGTERM = 143
#: files a run writes into --out (removed by --force before a new run, so that two runs' files never mix)
RUN_OUTPUTS: tuple[str, ...] = ("usage.db", "usage.db-wal", "usage.db-shm", "timeline.txt", "trace.csv",
                                "trace.npz", "summary.json", "report.html", "overview.png", "maintenance.png",
                                "usage.png", "records", "life.json", "life.png")
#: bytes of memory per board tick kept for the whole run (the per-tick trace, the wall-clock tick statistics)
BYTES_PER_TICK = 8 * 16


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "run", help="run the board firmware through a scenario (flight, abnormal loads, maintenance MBITs)",
        description="Run the 100 Hz board firmware mock against a rig for one scenario: regime changes, usage "
                    "summaries, MBIT verdicts and incidents go to an SQLite log; a timeline is printed; plots and "
                    "an HTML summary are written to --out.")
    from board_config.scenario import available_scenarios

    p.add_argument("--scenario", default="default", metavar="FILE|NAME",
                   help=f"scenario TOML file or shipped name ({', '.join(available_scenarios())}); "
                        "format in docs/scenarios.md")
    p.add_argument("--link", default="sim", metavar="URL",
                   help="rig link: 'sim' (in-process simulated rig, default) or a hardware-link URL "
                        "(serial:PATH, socket://HOST:PORT, modbus-tcp://HOST:PORT, modbus-rtu:PATH)")
    p.add_argument("--params", default=None, metavar="NAME",
                   help="parameter set of the board's nominal model and of the simulated rig's truth "
                        "(default: the scenario's [rig] params)")
    p.add_argument("--seed", type=int, default=None,
                   help="seed of the simulated rig, 0 .. 2^32-1 (default: the scenario's)")
    pace = p.add_mutually_exclusive_group()
    pace.add_argument("--realtime", action="store_true",
                      help="pace the 100 Hz tick on the wall clock (default for hardware links)")
    pace.add_argument("--virtual", action="store_true",
                      help="virtual time, as fast as possible (default for --link sim)")
    p.add_argument("--duration-s", type=float, default=None, help="stop after this much board time (s)")
    from shm_cli.hil_cmd import sched_slice_arg

    p.add_argument("--sched-slice-ms", type=sched_slice_arg, default=0.2, metavar="MS",
                   help="hardware links, paced: CPU time slice asked for the board's link thread (Linux >= 6.12: it "
                        "preempts a CPU-bound neighbour when a reply arrives; normal priority kept; 0: off; "
                        "docs/real-rig.md)")
    p.add_argument("--board-config", default=None, metavar="FILE", help="board configuration (default: shipped)")
    p.add_argument("--timeline-every-s", type=nonnegative_float, default=60.0,
                   help="print a telemetry line this often (s of board time; 0 = never); every record is logged")
    keep = p.add_mutually_exclusive_group()
    keep.add_argument("--append", action="store_true",
                      help="add this run to the usage.db already in --out (must be an mfc-shm usage log); the "
                           "other files are rewritten for this run")
    keep.add_argument("--force", action="store_true",
                      help="replace an earlier run's files in --out (without it a directory holding a run is "
                           "refused)")
    p.add_argument("--log-sync", choices=("normal", "full"), default="normal",
                   help="SQLite synchronous mode of the usage log: normal (every committed record survives a killed "
                        "process; default) or full (also an OS crash or power cut; one fsync per record)")
    p.add_argument("--json", action="store_true", help="print the run summary as JSON at the end")
    p.add_argument("--quiet", action="store_true", help="no timeline on stdout and no progress bar")
    add_live_args(p, "the running board")
    from shm_cli.fleet_cmd import add_fleet_args

    add_fleet_args(p, boards=True)
    add_out_arg(p, default="out/run")
    p.set_defaults(func=cmd_run)


# --- timeline ---------------------------------------------------------------------------------------------
class TimelinePrinter:
    """Prints (and keeps) timeline lines for events as they are committed to the log."""

    def __init__(self, echo: bool, telemetry_every_s: float, write=None) -> None:
        self.echo = echo
        self.every = telemetry_every_s
        self.lines: list[str] = []
        self._next_tel = 0.0
        self._write = write or (lambda s: print(s, flush=True))

    def add_line(self, line: str) -> None:
        self.lines.append(line)
        if self.echo:
            self._write(line)

    def __call__(self, ev: Any) -> None:
        if ev.kind == "telemetry":
            if self.every <= 0 or ev.time + 1e-9 < self._next_tel:
                return
            self._next_tel = ev.time + self.every
        line = format_event(ev)
        if line is not None:
            self.add_line(line)


# --- output directory: locked, never overwritten by accident ----------------------------------------------
def _previous_run(out: Path) -> str | None:
    """What an earlier run left in ``out`` (None: nothing of a run)."""
    present = [n for n in RUN_OUTPUTS if (out / n).exists()]
    if not present:
        return None
    what = ""
    summary = out / "summary.json"
    if summary.exists():
        try:
            d = json.loads(summary.read_text())
            what = f"scenario '{d.get('scenario')}', {d.get('ticks')} ticks, status {d.get('status', 'finished')}"
        except (OSError, ValueError):
            what = ""
    if not what and (out / "usage.db").exists():
        import sqlite3

        try:
            db = sqlite3.connect(f"file:{out / 'usage.db'}?mode=ro", uri=True)
            try:
                row = db.execute("SELECT count(*), max(started_utc), "
                                 "(SELECT status FROM runs ORDER BY run_id DESC LIMIT 1) FROM runs").fetchone()
            finally:
                db.close()
            what = f"{row[0]} run(s) in usage.db, the last started {row[1]}, status {row[2]}"
        except sqlite3.DatabaseError:
            what = "usage.db"
    return what or ", ".join(present)


def _last_visit_number(records: Path) -> int:
    """Highest NNN of the ``visit-NNN_mbit-X.csv`` files in ``records`` (0: none)."""
    best = 0
    for f in records.glob("visit-*_mbit-*.csv") if records.is_dir() else ():
        num = f.name[len("visit-"):].split("_", 1)[0]
        if num.isdigit():
            best = max(best, int(num))
    return best


def _prepare_out(args: argparse.Namespace, out: Path) -> None:
    """Refuse to overwrite an earlier run (unless --force / --append); with --force remove its files."""
    from firmware_sim.usage_log import check_is_usage_log
    from shm_cli.main import CliError

    if args.append:
        check_is_usage_log(out / "usage.db")
        return
    previous = _previous_run(out)
    if previous is None:
        return
    if not args.force:
        raise CliError(f"--out {out} holds an earlier run ({previous}); not overwriting it: use --force to replace "
                       "it, --append to add this run to its usage.db, or choose another --out")
    for name in RUN_OUTPUTS:
        target = out / name
        if target.is_dir() and not target.is_symlink():
            shutil.rmtree(target)
        else:
            target.unlink(missing_ok=True)


def _check_link_url(url: str) -> None:
    """A ``scheme://HOST:PORT`` link whose port is not a number in 1 .. 65535 is bad input (exit 2), refused before
    the link layer tries to open it."""
    from shm_cli.main import CliError

    if "://" not in url:
        return
    hostport = url.split("://", 1)[1].split("?", 1)[0].split("/", 1)[0]
    host, sep, port = hostport.rpartition(":")
    if not sep:
        return
    if not port.isdigit() or not 1 <= int(port) <= 65535:
        raise CliError(f"--link {url!r}: port {port!r} is not a TCP port number (1 .. 65535)")
    if not host:
        raise CliError(f"--link {url!r}: no host before ':{port}'")


# --- clean interruption ----------------------------------------------------------------------------------
class StopOnSignal:
    """SIGINT (Ctrl-C) and SIGTERM request a clean stop after the current tick (a second signal aborts at once
    with KeyboardInterrupt). Installed only in the main thread; restores the previous handlers on exit."""

    def __init__(self) -> None:
        self.signal: int | None = None
        self._old: dict[int, Any] = {}

    def _handler(self, signum: int, frame: Any) -> None:
        if self.signal is not None:
            raise KeyboardInterrupt
        self.signal = signum

    @property
    def requested(self) -> bool:
        return self.signal is not None

    @property
    def exit_code(self) -> int:
        return EXIT_SIGTERM if self.signal == signal.SIGTERM else EXIT_SIGINT

    @property
    def name(self) -> str:
        return "SIGTERM" if self.signal == signal.SIGTERM else "SIGINT (Ctrl-C)"

    def __enter__(self) -> StopOnSignal:
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                self._old[sig] = signal.signal(sig, self._handler)
        return self

    def __exit__(self, *exc: object) -> None:
        for sig, old in self._old.items():
            signal.signal(sig, old)
        self._old.clear()


class StoppableScheduler:
    """A scheduler whose run ends after the tick (or quiet span) in which ``stop.requested`` became true."""

    def __init__(self, inner: Any, stop: StopOnSignal) -> None:
        self._inner = inner
        self._stop = stop
        self.rate = inner.rate
        self.period = inner.period
        self.paced = inner.paced

    def __getattr__(self, name: str) -> Any:
        return getattr(self._inner, name)

    def run(self, n_ticks: int, step: Any, first_tick: int = 0, progress: Any = None) -> Any:
        stop = self._stop

        def guarded(k: int, overran: bool) -> bool:
            return bool(step(k, overran)) or stop.requested

        return self._inner.run(n_ticks, guarded, first_tick=first_tick, progress=progress)

    def run_blocks(self, n_ticks: int, block: Any, first_tick: int = 0, progress: Any = None) -> Any:
        """Virtual time with quiet spans: ends after the block in which ``stop.requested`` became true."""
        stop = self._stop

        def guarded(k: int, left: int) -> tuple[int, bool]:
            d, halt = block(k, left)
            return d, bool(halt) or stop.requested

        return self._inner.run_blocks(n_ticks, guarded, first_tick=first_tick, progress=progress)


# --- the command --------------------------------------------------------------------------------------
def cmd_run(args: argparse.Namespace) -> int:
    if args.boards is not None:  # a fleet of boards through a [life] scenario (docs/scale-out.md)
        from shm_cli.fleet_cmd import run_fleet_boards

        return run_fleet_boards(args)
    from board_config.board import load_board_config
    from board_config.scenario import load_scenario
    from drivers.link import open_link
    from drivers.sim_link import InProcessLink
    from firmware_sim.board import Board
    from firmware_sim.runner import BoardRunner
    from firmware_sim.scheduler import Scheduler, VirtualClock, WallClock
    from firmware_sim.usage_log import LogError, UsageLog
    from hil_stub.rig import SimulatedRig
    from shm_cli.main import CliError
    from shm_cli.run_lock import OutputLock

    for opt, value in (("--scenario", args.scenario), ("--params", args.params), ("--board-config", args.board_config),
                       ("--link", args.link)):
        if value is not None and not str(value).strip():
            raise CliError(f"{opt} is empty: give a name or a path")
    scenario = load_scenario(args.scenario)
    if scenario.life is not None:  # many visits over an operating life (issue 17): studies.health.life
        refuse_live_for_a_life(args, scenario)
        from shm_cli.life_cmd import run_life_command

        return run_life_command(args, scenario)
    seed = args.seed if args.seed is not None else scenario.seed
    if not 0 <= seed < 2**32:
        raise CliError(f"--seed must be in [0, 2^32-1], got {seed}")
    params = args.params or scenario.rig.params
    cfg = load_board_config(args.board_config, overrides=scenario.board_overrides, overrides_source=scenario.source)
    duration = scenario.duration if args.duration_s is None else float(args.duration_s)
    if not duration > 0 or duration != duration:
        raise CliError(f"--duration-s must be positive, got {duration!r}")
    n_ticks = duration * cfg.tick_rate
    src = f"--duration-s {args.duration_s:g}" if args.duration_s is not None else \
        f"the scenario's duration ({scenario.source}: {duration:g} s)"
    check_memory(f"{src} = {n_ticks:.3g} board ticks", n_ticks * BYTES_PER_TICK,
                 hint="run a shorter stretch (--duration-s) or split the scenario")
    out = out_dir(args.out)
    # --live (docs/live.md): before anything in --out is touched, so a port in use leaves an earlier run there
    args.live_session = live = start_live(args, report=out / "report.html")
    lock = OutputLock(out, command=f"shm run --scenario {args.scenario} --out {args.out}")
    lock.acquire()
    try:
        _prepare_out(args, out)
        # from here to the last file written, SIGINT/SIGTERM ask for a clean stop (see StopOnSignal)
        with StopOnSignal() as stopper:
            code = _run_locked(args, scenario, seed, params, cfg, duration, out, stopper, Board, BoardRunner,
                               InProcessLink, LogError, Scheduler, SimulatedRig, UsageLog, VirtualClock, WallClock,
                               open_link)
    finally:
        lock.release()
    return live.linger(code, interrupted=stopper.requested) if live is not None else code


def _run_locked(args, scenario, seed, params, cfg, duration, out, stopper, Board, BoardRunner, InProcessLink,
                LogError, Scheduler, SimulatedRig, UsageLog, VirtualClock, WallClock, open_link) -> int:
    db_path = out / "usage.db"
    t_setup = time.perf_counter()
    # every URL is opened by drivers.open_link with the run's defaults for what it leaves out: a bare 'sim' is the
    # run's own simulated rig (the scenario's [rig], --seed, --params, the board tick)
    defaults = {"scenario": scenario, "seed": args.seed, "params": args.params, "tick": cfg.tick_period}
    link = None
    try:
        if args.link == "sim":
            link = open_link(args.link, **defaults)
        board = Board(cfg, nominal=params)
    except InputError as exc:  # the scenario's [rig] (params, effects, deviations): say which file it came from
        if scenario.source in str(exc) or (args.params is not None and args.params in str(exc)):
            raise
        raise InputError(f"{scenario.source}: [rig]: {exc}") from None
    if link is None:
        _check_link_url(args.link)
        try:
            link = open_link(args.link, **defaults)
        except InputError as exc:
            raise InputError(f"--link {args.link!r}: {exc}") from None
    rig = link.rig if isinstance(link, InProcessLink) else None
    paced = args.realtime or (args.link != "sim" and not args.virtual)
    if paced and rig is None:  # the thread that exchanges with a hardware link: a short slice (drivers.latency_slice)
        from drivers.latency_slice import request_slice

        request_slice(args.sched_slice_ms / 1e3)
    scheduler = StoppableScheduler(Scheduler(cfg.tick_rate, WallClock() if paced else VirtualClock()), stopper)
    # --live: the page reads what the board publishes after each tick; the link is timed
    live, link, scheduler = attach_live_board(args, board, link, scheduler, scenario.name, duration, paced)
    setup_s = time.perf_counter() - t_setup

    bar = None
    if not args.quiet:
        from tqdm import tqdm

        bar = tqdm(total=round(duration * cfg.tick_rate), unit="tick", desc=f"shm run {scenario.name}",
                   file=sys.stderr, mininterval=0.5, leave=False)
        # --json: stdout carries the JSON document only; the timeline goes to stderr
        timeline_to = sys.stderr if args.json else sys.stdout
        printer = TimelinePrinter(True, args.timeline_every_s, write=lambda s: bar.write(s, file=timeline_to))
    else:
        printer = TimelinePrinter(False, args.timeline_every_s)
    printer.add_line(f"shm run: scenario '{scenario.name}' ({scenario.source}), seed {seed}, link {args.link}, "
                     f"params {params}, {'real time' if paced else 'virtual time'}, {duration:g} s of board time")
    printer.add_line(f"{'time':>11}  event")

    status = "failed"
    log = None
    failed: dict[str, str] = {}  # step of the run -> why it failed (the run then exits 1, its results written)
    recorder: Any = None
    try:
        log = UsageLog(db_path, synchronous=args.log_sync.upper())
        run_id = log.start_run(scenario=scenario.name, seed=seed, link_url=args.link, params=params,
                               board_config=cfg.as_dict(), rig=rig.describe() if rig is not None else {})
        from studies.health.visit_records import VisitRecordWriter  # every completed MBIT -> records/ (issue 17)

        def make_recorder() -> VisitRecordWriter:
            rec = VisitRecordWriter(out, db_path, params=params, z3_noise_m=scenario.rig.z3_noise,
                                    scenario=scenario.name, run_id=run_id)
            if args.append:  # the earlier runs' visit records stay: number this run's visits after theirs
                rec.visit = _last_visit_number(out / "records")
            return rec

        if paced:  # a record written inside a tick is missed deadlines in a row: written beside the ticks
            from studies.board_run.background_records import BackgroundRecorder

            recorder = BackgroundRecorder(make_recorder)
        else:
            recorder = make_recorder()

        def on_event(ev) -> None:
            printer(ev)
            if live is not None:
                live.on_event(ev)
            try:  # a record that cannot be written is a failed step of the run, never the end of the board's run
                recorder(ev)
            except Exception as exc:
                why = f"{type(exc).__name__}: {' '.join(str(exc).split())}"
                if "the visit records" not in failed:
                    print(f"shm run: could not write a visit record ({why}); the run goes on", file=sys.stderr)
                failed.setdefault("the visit records", why)

        runner = BoardRunner(board, link, sink=log, scheduler=scheduler,
                             rearm_times=[e.at for e in scenario.events_of("rearm")], on_event=on_event)
        last = [0]

        def progress(i: int) -> None:
            if bar is not None:
                bar.update(i - last[0])
                last[0] = i

        link.open()
        try:
            result = runner.run(duration, progress=progress)
        finally:
            link.close()
        status = "interrupted" if stopper.requested else "finished"
    except FloatingPointError as exc:
        print(f"shm run: the rig's plant integration failed: {exc}", file=sys.stderr)
        return 1
    except LogError as exc:
        print(f"shm run: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        status = "interrupted"
        raise
    finally:
        if recorder is not None:  # every record written (a paced run's: waited for) before anything else
            with contextlib.suppress(Exception):
                recorder.close()
        if log is not None:
            try:
                log.close(status)
            except Exception:  # the log already failed; its error is what the user sees
                pass
        if bar is not None:
            bar.close()

    if getattr(recorder, "failure", None):
        failed.setdefault("the visit records", recorder.failure)
    deco = Decorations("run", args)
    deco.failed.update(failed)
    from studies.board_run.outputs import RunContext, write_run_outputs

    ctx = RunContext(args.link, scenario, seed, params, cfg, board, result, rig, setup_s, paced, db_path, run_id)
    summary = write_run_outputs(ctx, status, stopper.name if status == "interrupted" else None, printer, out, link,
                                deco, dump_json, runner.lost_exchanges)
    figures = summary["figures"]
    if live is not None:
        live.finish(status)
    if args.json:
        print(dump_json(summary))
    elif not args.quiet:
        print(f"results in {out}/ (usage.db, timeline.txt, report.html, {', '.join(figures)})")
    if stopper.requested:
        if status == "interrupted":
            print(f"shm run: interrupted by {stopper.name} at {result.duration_s:.2f} s of board time; status "
                  f"'interrupted' recorded in {db_path}, partial results in {out}/", file=sys.stderr)
        else:
            print(f"shm run: {stopper.name} received after the run finished; its results are complete in {out}/",
                  file=sys.stderr)
        return stopper.exit_code
    if summary["verdict_as_expected"] is False:
        print(f"shm run: the final maintenance verdict is not the one scenario '{scenario.name}' expects "
              f"(expected {summary['expected_verdict']}): exit 1", file=sys.stderr)
        return 1
    if not deco.ok:
        print(f"shm run: the run's results are in {out}/, but these steps failed: {'; '.join(deco.failed)}: exit 1",
              file=sys.stderr)
    return 0 if status == "finished" and deco.ok else 1


