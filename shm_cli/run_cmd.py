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
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from board_config.errors import InputError
from shm_cli.command_args import add_command
from shm_cli.common import (
    Decorations,
    add_out_arg,
    check_memory,
    dump_json,
    nonnegative_float,
    out_dir,
)
from shm_cli.live_args import add_live_args, attach_live_board, refuse_live_for_a_life, start_live
from shm_cli.output_folder import last_visit_number, previous_run, remove_run_outputs
from shm_cli.output_guard import add_force_arg
from shm_cli.stop_signal import StopOnSignal, StoppableScheduler
from studies.board_run.timeline import format_event

if TYPE_CHECKING:
    from board_config.board import BoardConfig
    from board_config.scenario import Scenario

#: bytes of memory per board tick kept for the whole run (the per-tick trace, the wall-clock tick statistics)
BYTES_PER_TICK = 8 * 16


def register(sub: argparse._SubParsersAction) -> None:
    p = add_command(
        sub, "run", "run the board firmware through a scenario (flight, abnormal loads, maintenance MBITs)",
        """Run the 100 Hz board firmware mock against a rig for one scenario: regime changes, usage summaries, MBIT
        verdicts and incidents go to an SQLite log; a timeline is printed; plots and an HTML summary are written to
        --out.""")
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
    add_force_arg(keep, "an earlier run in --out")
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

    def __init__(self, echo: bool, telemetry_every_s: float, write: Callable[[str], None] | None = None) -> None:
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
def _prepare_out(args: argparse.Namespace, out: Path) -> None:
    """Refuse to overwrite an earlier run (unless --force / --append); with --force remove its files."""
    from firmware_sim.usage_log import check_is_usage_log
    from shm_cli.main import CliError

    if args.append:
        check_is_usage_log(out / "usage.db")
        return
    previous = previous_run(out)
    if previous is None:
        return
    if not args.force:
        raise CliError(f"--out {out} holds an earlier run ({previous}); not overwriting it: use --force to replace "
                       "it, --append to add this run to its usage.db, or choose another --out")
    remove_run_outputs(out)


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


# --- the command --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class RunPlan:
    """What one ``shm run`` of a scenario without ``[life]`` does, checked before ``--out`` is touched."""

    scenario: Scenario
    seed: int
    params: str  # parameter set of the board's nominal model and of the simulated rig's truth
    cfg: BoardConfig
    duration: float  # s of board time
    out: Path

    @property
    def db_path(self) -> Path:
        return self.out / "usage.db"


def cmd_run(args: argparse.Namespace) -> int:
    if args.boards is not None:  # a fleet of boards through a [life] scenario (docs/scale-out.md)
        from shm_cli.fleet_cmd import run_fleet_boards

        return run_fleet_boards(args)
    from board_config.scenario import load_scenario
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
    if args.scheduler is not None:  # it would be ignored: one board's run is one process
        raise CliError(f"--scheduler runs a [life] scenario's visits or --boards N lives on Dask; {scenario.source} "
                       "has no [life] section and one run is one process: drop --scheduler, or add --boards N")
    plan = _plan_run(args, scenario)
    # --live (docs/live.md): before anything in --out is touched, so a port in use leaves an earlier run there
    args.live_session = live = start_live(args, report=plan.out / "report.html")
    lock = OutputLock(plan.out, command=f"shm run --scenario {args.scenario} --out {args.out}")
    lock.acquire()
    try:
        _prepare_out(args, plan.out)
        # from here to the last file written, SIGINT/SIGTERM ask for a clean stop (see StopOnSignal)
        with StopOnSignal() as stopper:
            code = BoardRunJob(args, plan, stopper).run()
    finally:
        lock.release()
    return live.linger(code, interrupted=stopper.requested) if live is not None else code


def _plan_run(args: argparse.Namespace, scenario: Scenario) -> RunPlan:
    """The seed, parameter set, board configuration and duration of the run, each checked (exit 2), and ``--out``."""
    from board_config.board import load_board_config
    from shm_cli.main import CliError

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
    return RunPlan(scenario, seed, params, cfg, duration, out_dir(args.out))


class BoardRunJob:
    """One ``shm run`` in ``plan.out`` (locked, prepared), as named stages: open the board and its link, choose the
    scheduler, start the timeline, run the board with the usage log open, write the outputs, say how it ended."""

    def __init__(self, args: argparse.Namespace, plan: RunPlan, stopper: StopOnSignal) -> None:
        self.args = args
        self.plan = plan
        self.stopper = stopper
        self.paced = bool(args.realtime or (args.link != "sim" and not args.virtual))
        self.failed: dict[str, str] = {}  # step of the run -> why it failed (the run then exits 1, results written)
        self.status = "failed"
        self.bar: Any = None  # the progress bar (None with --quiet)

    def run(self) -> int:
        t_setup = time.perf_counter()
        board, link, rig = self._open_board_and_link()
        scheduler = self._scheduler(rig is None)
        # --live: the page reads what the board publishes after each tick; the link is timed
        live, link, scheduler = attach_live_board(self.args, board, link, scheduler, self.plan.scenario.name,
                                                  self.plan.duration, self.paced)
        setup_s = time.perf_counter() - t_setup
        printer = self._start_timeline()
        ran = self._run_logged(board, link, rig, scheduler, live, printer)
        if ran is None:
            return 1
        result, runner, run_id = ran
        from studies.board_run.outputs import RunContext

        plan = self.plan
        ctx = RunContext(self.args.link, plan.scenario, plan.seed, plan.params, plan.cfg, board, result, rig,
                         setup_s, self.paced, plan.db_path, run_id)
        return self._write_outputs(ctx, printer, link, live, runner.lost_exchanges)

    def _open_board_and_link(self) -> tuple[Any, Any, Any]:
        """The board and the link (every URL opened by ``drivers.open_link`` with the run's defaults for what it
        leaves out: a bare 'sim' is the run's own simulated rig: the scenario's [rig], --seed, --params, the board
        tick), and the in-process rig behind the link (None for a hardware link)."""
        from drivers.link import open_link
        from drivers.sim_link import InProcessLink
        from firmware_sim.board import Board
        from hil_stub import rig as _registers_the_sim_link  # noqa: F401  (open_link('sim') needs it registered)

        args, plan = self.args, self.plan
        scenario = plan.scenario
        defaults = {"scenario": scenario, "seed": args.seed, "params": args.params, "tick": plan.cfg.tick_period}
        link = None
        try:
            if args.link == "sim":
                link = open_link(args.link, **defaults)
            board = Board(plan.cfg, nominal=plan.params)
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
        return board, link, link.rig if isinstance(link, InProcessLink) else None

    def _scheduler(self, hardware: bool) -> StoppableScheduler:
        """The 100 Hz scheduler (paced on the wall clock or virtual), stopped by a signal after the current tick."""
        from firmware_sim.scheduler import Scheduler, VirtualClock, WallClock

        if self.paced and hardware:  # the thread that exchanges with a hardware link: a short slice
            from drivers.latency_slice import request_slice

            request_slice(self.args.sched_slice_ms / 1e3)
        clock = WallClock() if self.paced else VirtualClock()
        return StoppableScheduler(Scheduler(self.plan.cfg.tick_rate, clock), self.stopper)

    def _start_timeline(self) -> TimelinePrinter:
        """The timeline printer (echoing on stdout, or stderr with --json, above the progress bar; silent with
        --quiet) with the run's first two lines."""
        args, plan = self.args, self.plan
        if not args.quiet:
            from tqdm import tqdm

            self.bar = bar = tqdm(total=round(plan.duration * plan.cfg.tick_rate), unit="tick",
                                  desc=f"shm run {plan.scenario.name}", file=sys.stderr, mininterval=0.5, leave=False)
            # --json: stdout carries the JSON document only; the timeline goes to stderr
            timeline_to = sys.stderr if args.json else sys.stdout
            printer = TimelinePrinter(True, args.timeline_every_s, write=lambda s: bar.write(s, file=timeline_to))
        else:
            printer = TimelinePrinter(False, args.timeline_every_s)
        printer.add_line(f"shm run: scenario '{plan.scenario.name}' ({plan.scenario.source}), seed {plan.seed}, "
                         f"link {args.link}, params {plan.params}, {'real time' if self.paced else 'virtual time'}, "
                         f"{plan.duration:g} s of board time")
        printer.add_line(f"{'time':>11}  event")
        return printer

    def _run_logged(self, board: Any, link: Any, rig: Any, scheduler: StoppableScheduler, live: Any,
                    printer: TimelinePrinter) -> tuple[Any, Any, int] | None:
        """Run the board with the usage log open: (the run's result, its runner, its run id), or None when the run
        could not complete (said on stderr; the log is closed with status 'failed'). Every visit record is written
        and the log closed, whatever ends the run."""
        from firmware_sim.runner import BoardRunner
        from firmware_sim.usage_log import LogError, UsageLog

        args, plan = self.args, self.plan
        log = None
        recorder: Any = None
        try:
            log = UsageLog(plan.db_path, synchronous=args.log_sync.upper())
            run_id = log.start_run(scenario=plan.scenario.name, seed=plan.seed, link_url=args.link,
                                   params=plan.params, board_config=plan.cfg.as_dict(),
                                   rig=rig.describe() if rig is not None else {})
            recorder = self._visit_recorder(run_id)
            runner = BoardRunner(board, link, sink=log, scheduler=scheduler,
                                 rearm_times=[e.at for e in plan.scenario.events_of("rearm")],
                                 on_event=self._event_handler(printer, live, recorder))
            link.open()
            try:
                result = runner.run(plan.duration, progress=self._progress())
            finally:
                link.close()
            self.status = "interrupted" if self.stopper.requested else "finished"
        except FloatingPointError as exc:
            print(f"shm run: the rig's plant integration failed: {exc}", file=sys.stderr)
            return None
        except LogError as exc:
            print(f"shm run: {exc}", file=sys.stderr)
            return None
        except KeyboardInterrupt:
            self.status = "interrupted"
            raise
        finally:
            if recorder is not None:  # every record written (a paced run's: waited for) before anything else
                with contextlib.suppress(Exception):
                    recorder.close()
            if log is not None:
                with contextlib.suppress(Exception):  # the log already failed; its error is what the user sees
                    log.close(self.status)
            if self.bar is not None:
                self.bar.close()
        if getattr(recorder, "failure", None):
            self.failed.setdefault("the visit records", recorder.failure)
        return result, runner, run_id

    def _visit_recorder(self, run_id: int) -> Any:
        """Every completed MBIT -> records/ (issue 17); a paced run's written beside the ticks (a record written
        inside a tick is missed deadlines in a row)."""
        from studies.health.visit_records import VisitRecordWriter

        args, plan = self.args, self.plan

        def make_recorder() -> VisitRecordWriter:
            rec = VisitRecordWriter(plan.out, plan.db_path, params=plan.params, z3_noise_m=plan.scenario.rig.z3_noise,
                                    scenario=plan.scenario.name, run_id=run_id)
            if args.append:  # the earlier runs' visit records stay: number this run's visits after theirs
                rec.visit = last_visit_number(plan.out / "records")
            return rec

        if self.paced:
            from studies.board_run.background_records import BackgroundRecorder

            return BackgroundRecorder(make_recorder)
        return make_recorder()

    def _event_handler(self, printer: TimelinePrinter, live: Any, recorder: Any) -> Callable[[Any], None]:
        """What sees each event once it is in the usage log: the timeline, the live page, the visit records."""
        failed = self.failed

        def on_event(ev: Any) -> None:
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

        return on_event

    def _progress(self) -> Callable[[int], None]:
        bar = self.bar
        last = [0]

        def progress(i: int) -> None:
            if bar is not None:
                bar.update(i - last[0])
                last[0] = i

        return progress

    def _write_outputs(self, ctx: Any, printer: TimelinePrinter, link: Any, live: Any, lost_exchanges: int) -> int:
        """Timeline, traces, figures, summary and report into --out; the exit code (see the module docstring)."""
        from studies.board_run.outputs import write_run_outputs

        args, stopper, status, out = self.args, self.stopper, self.status, self.plan.out
        deco = Decorations("run", args)
        deco.failed.update(self.failed)
        summary = write_run_outputs(ctx, status, stopper.name if status == "interrupted" else None, printer, out,
                                    link, deco, dump_json, lost_exchanges)
        if live is not None:
            live.finish(status)
        if args.json:
            print(dump_json(summary))
        elif not args.quiet:
            print(f"results in {out}/ (usage.db, timeline.txt, report.html, {', '.join(summary['figures'])})")
        if stopper.requested:
            return stopper.report(status == "interrupted", f" at {ctx.result.duration_s:.2f} s of board time; status "
                                  f"'interrupted' recorded in {ctx.db_path}, partial results in {out}/", "the run",
                                  f"{out}/")
        if summary["verdict_as_expected"] is False:
            print(f"shm run: the final maintenance verdict is not the one scenario '{ctx.scenario.name}' expects "
                  f"(expected {summary['expected_verdict']}): exit 1", file=sys.stderr)
            return 1
        if not deco.ok:
            print(f"shm run: the run's results are in {out}/, but these steps failed: {'; '.join(deco.failed)}: "
                  "exit 1", file=sys.stderr)
        return 0 if status == "finished" and deco.ok else 1
