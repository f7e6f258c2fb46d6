"""``shm hil serve``: the simulated rig, paced in real time (or lock-step), on serial / Modbus TCP / Modbus RTU at once.

Example (two terminals)::

    shm hil serve --scenario maintenance --modbus-tcp 127.0.0.1:5020 --serial pty
    shm run --scenario maintenance --realtime --link modbus-tcp://127.0.0.1:5020

The stub prints, per endpoint, the URL the board passes to ``--link``. Fault flags make the rig misbehave on
purpose (all seeded by ``--seed``). Stop with Ctrl-C (or ``--duration``); a summary of what happened is printed
(and written as JSON with ``--summary FILE``).
"""

from __future__ import annotations

import argparse
import gc
import json
import logging
import signal
import sys
import threading
import time
from pathlib import Path

from shm_cli.common import (
    float_in_range,
    int_in_range,
    nonnegative_float,
    output_file_arg,
    positive_float,
    positive_int,
    seed_int,
    to_jsonable,
)


def _listen_endpoint(text: str, scheme: str, hostport: str) -> str:
    """``text`` (its ``hostport``: ``HOST:PORT``, port 0 = any free one) checked as a place the stub can listen on;
    argparse error naming ``text``, the part that is wrong and what is allowed."""
    from drivers.link_url import LinkUrlError, network_endpoint

    try:
        host, _ = network_endpoint(text, scheme, None, 0, part=scheme + hostport)
    except LinkUrlError as exc:
        raise argparse.ArgumentTypeError(f"'{text}': {exc.reason}") from None
    if ":" in host:
        raise argparse.ArgumentTypeError(f"'{text}': the stub listens on an IPv4 address or a host name "
                                         "(e.g. 127.0.0.1:5020, 0.0.0.0:502); IPv6 is not served")
    return text


def tcp_endpoint_arg(text: str) -> str:
    """argparse ``type=`` of ``--modbus-tcp HOST:PORT``: a malformed host or a port outside 0 .. 65535 is refused at
    parse time, before the rig is built."""
    return _listen_endpoint(text, "modbus-tcp://", text)


def serial_endpoint_arg(text: str) -> str:
    """argparse ``type=`` of ``--serial``: ``pty``, ``pty:PATH``, ``socket://HOST:PORT`` (to listen on) or a
    device path; another URL protocol is refused at parse time."""
    if text.startswith("socket://"):
        _listen_endpoint(text, "socket://", text.removeprefix("socket://").split("?", 1)[0])
    elif "://" in text:
        raise argparse.ArgumentTypeError(f"'{text}': allowed pty, pty:PATH, socket://HOST:PORT (to listen on) or a "
                                         "serial device path")
    return text


def rtu_endpoint_arg(text: str) -> str:
    """argparse ``type=`` of ``--modbus-rtu``: ``pty`` or an existing serial device path."""
    if text != "pty" and not Path(text).exists():
        raise argparse.ArgumentTypeError(f"'{text}': no such serial device (allowed: pty, or the path of a serial "
                                         "device or one end of a socat pair)")
    return text


def sched_slice_arg(text: str) -> float:
    """argparse ``type=`` of ``--sched-slice-ms``: 0 (off) or 0.1 .. 100 ms."""
    from board_config.errors import InputError
    from drivers.latency_slice import check_slice_ms

    try:
        value = float(text)
        check_slice_ms(value)
    except (ValueError, InputError) as exc:
        raise argparse.ArgumentTypeError(f"'{text}': allowed 0 (off) or 0.1 .. 100 ms") from exc
    return value


#: the serving threads' slice when ``--sched-slice-ms`` is not given (ms), per link (docs/real-rig.md, measured on a
#: quiet machine with a CPU hog per core): 0.2 ms shortens the client-seen FC 23 p99 on Modbus TCP (5.25 -> 3.96 ms)
#: and lengthens it on Modbus RTU over a pty (4.25 -> 5.90 ms; the stub's own answer p99 0.59 -> 5.04 ms), so a stub
#: serving a serial or RTU endpoint keeps the kernel's default
DEFAULT_SLICE_MS = {"tcp": 0.2, "serial": 0.0}


def serving_slice_ms(chosen: float | None, serial_endpoints: int) -> float:
    """The serving threads' slice (ms): ``--sched-slice-ms`` as given, else :data:`DEFAULT_SLICE_MS` for the links
    served (``serial_endpoints``: how many framed-serial or Modbus RTU endpoints). Pure."""
    if chosen is not None:
        return chosen
    return DEFAULT_SLICE_MS["serial" if serial_endpoints else "tcp"]


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("hil", help="hardware-in-the-loop stub: the simulated rig served over serial / Modbus",
                       description="The simulated rig as hardware: serial frames, Modbus TCP, Modbus RTU.")
    hsub = p.add_subparsers(dest="hil_command", metavar="SUBCOMMAND")
    hsub.required = True
    s = hsub.add_parser(
        "serve", help="serve the rig on every requested endpoint at once",
        description="Run the truth plant paced in real time (or lock-step) and serve it on every requested endpoint "
                    "at once. Prints the pty paths and ports and the --link URL for each.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="endpoints (repeatable, at least one):\n"
               "  --serial pty              a new pty; the board opens the printed stable link\n"
               "  --serial socket://H:P     listen on TCP for the board's socket://H:P\n"
               "  --serial /dev/ttyS1       a serial device (or one end of a socat pair)\n"
               "  --modbus-tcp H:P          Modbus TCP server (port 0: any free port)\n"
               "  --modbus-rtu pty|PATH     Modbus RTU slave on a built-in pty or a serial device\n")
    g = s.add_argument_group("endpoints")
    g.add_argument("--serial", action="append", default=[], metavar="pty|URL", type=serial_endpoint_arg,
                   help="framed serial protocol endpoint")
    g.add_argument("--modbus-tcp", action="append", default=[], metavar="HOST:PORT", type=tcp_endpoint_arg,
                   help="Modbus TCP endpoint")
    g.add_argument("--modbus-rtu", action="append", default=[], metavar="pty|PATH", type=rtu_endpoint_arg,
                   help="Modbus RTU endpoint")
    g.add_argument("--unit", type=int_in_range(1, 247), default=1, help="Modbus unit id (default 1)")
    g.add_argument("--baud", type=positive_int, default=115200,
                   help="serial line speed, RTU and device paths (default 115200)")
    g.add_argument("--parity", choices=("N", "E", "O"), default="N", help="RTU parity (default N)")
    r = s.add_argument_group("rig")
    r.add_argument("--params", default=None, metavar="NAME",
                   help="parameter set of the truth plant (default: the scenario's, else table2)")
    r.add_argument("--scenario", default=None, metavar="NAME|FILE",
                   help="the rig's environment: vibration, HV presence, scheduled incidents (default: a quiet bench "
                        "rig with the amplifier connected)")
    r.add_argument("--seed", type=seed_int, default=None, help="seeds the environment, sensor noise and faults")
    r.add_argument("--hv", choices=("scenario", "present", "absent"), default="scenario",
                   help="HV equipment presence: follow the scenario (default), or force it")
    r.add_argument("--clock", choices=("realtime", "lockstep"), default="realtime",
                   help="realtime: 100 Hz wall-clock loop (run the board with --realtime); lockstep: one tick per "
                        "board command (run the board in virtual time); every new board run starts the lockstep rig "
                        "again from t = 0, a real-time rig plays its scenario once")
    r.add_argument("--start", choices=("first-command", "now"), default="first-command",
                   help="when rig time starts (default: at the board's first command)")
    r.add_argument("--duration", type=positive_float, default=None, metavar="S",
                   help="stop after S seconds (wall clock)")
    r.add_argument("--summary", default=None, metavar="FILE", type=output_file_arg,
                   help="write the end-of-run summary as JSON")
    r.add_argument("--status-every", type=nonnegative_float, default=10.0, metavar="S",
                   help="print a status line every S seconds (0: never)")
    r.add_argument("--sched-slice-ms", type=sched_slice_arg, default=None, metavar="MS",
                   help="CPU time slice asked for the serving threads (Linux >= 6.12, EEVDF: a short slice lets them "
                        "preempt a CPU-bound neighbour when a request arrives; normal priority and nice kept; "
                        "0.1 .. 100, 0: off; default 0.2 when every endpoint is Modbus TCP, 0 when a serial or "
                        "Modbus RTU endpoint is served — measured per link, docs/real-rig.md)")
    r.add_argument("--clock-slice-ms", type=sched_slice_arg, default=None, metavar="MS",
                   help="CPU time slice of the rig clock thread (the physics step), apart from the serving threads "
                        "(default: the same as --sched-slice-ms; 0: the kernel's default; docs/real-rig.md)")
    r.add_argument("--modbus-path", choices=("hot", "pymodbus"), default="hot",
                   help="who answers Modbus FC 03/04/16/23 (TCP and RTU): the stub's own hot path (default: answered "
                        "in the data callback from the register tables) or pymodbus' request chain, as before "
                        "(docs/real-rig.md)")
    r.add_argument("--rig-clock", choices=("loop", "thread"), default="loop",
                   help="where the realtime rig clock runs when a Modbus endpoint is served: on the Modbus event "
                        "loop's thread (default: one serving thread, no GIL hand-over between a request and its "
                        "reply) or in a thread of its own (as before; docs/real-rig.md)")
    _add_fault_options(s.add_argument_group("fault injection (seeded by --seed)"))
    from shm_cli.live_args import add_live_args

    add_live_args(s, "the rig")
    s.set_defaults(func=cmd_serve)


def _add_fault_options(f: argparse._ArgumentGroup) -> None:
    """`shm hil serve`'s fault injection options (wire, timing, sensor and truth faults)."""
    f.add_argument("--drop", type=float_in_range(0.0, 1.0), default=0.0, metavar="FRAC",
                   help="fraction of replies dropped")
    f.add_argument("--corrupt", type=float_in_range(0.0, 1.0), default=0.0, metavar="FRAC",
                   help="fraction of replies with one bit flipped")
    f.add_argument("--latency-ms", type=nonnegative_float, default=0.0,
                   help="added to the sample reply of every exchange (serial: the SAMPLE; Modbus: the FC04 read; "
                        "command acknowledgements are not delayed) (ms)")
    f.add_argument("--processing-ms", type=nonnegative_float, default=0.0,
                   help="the rig's processing time for every request, each Modbus transaction included (ms): a "
                        "slow rig (docs/real-rig.md states the budget per link)")
    f.add_argument("--jitter-ms", type=nonnegative_float, default=0.0, help="uniform extra reply latency 0..J ms")
    f.add_argument("--disconnect-at", type=nonnegative_float, default=None, metavar="S",
                   help="every endpoint disappears at this rig time (s)")
    f.add_argument("--disconnect-for", type=nonnegative_float, default=1.0, metavar="S", help="... for this long (s)")
    f.add_argument("--noise", action="append", default=[], metavar="CH=SIGMA",
                   help="sensor noise, SI units (z3 m, v_patch V, z0dd m/s^2, v_battery V); repeatable")
    f.add_argument("--stuck", action="append", default=[], metavar="CH[@T]",
                   help="a channel frozen from rig time T (z3, v_patch, z0dd, v_battery, seq); repeatable")
    f.add_argument("--deviation", action="append", default=[], metavar="NAME=REL",
                   help="relative parameter deviation of the truth plant (k3=-0.3: k3 × 0.7); repeatable")
    f.add_argument("--effect", action="append", default=[], metavar="NAME|module:Class",
                   help="add a physical effect to the truth plant (registered name or dotted path); repeatable")


def fault_plan(args: argparse.Namespace, seed: int):
    """The :class:`~hil_stub.faults.FaultPlan` of the command line (ValueError names a bad flag)."""
    from hil_stub.faults import FaultPlan, LinkFaults, SensorFaults, TruthChanges, parse_assignments, parse_stuck

    link = LinkFaults(drop=args.drop, corrupt=args.corrupt, latency_s=args.latency_ms / 1e3,
                      jitter_s=args.jitter_ms / 1e3, processing_s=args.processing_ms / 1e3,
                      disconnect_at_s=args.disconnect_at,
                      disconnect_for_s=args.disconnect_for)
    sensors = SensorFaults(noise=parse_assignments("--noise", args.noise), stuck=parse_stuck(args.stuck))
    truth = TruthChanges(deviations=parse_assignments("--deviation", args.deviation), effects=tuple(args.effect))
    return FaultPlan(link=link, sensors=sensors, truth=truth, seed=seed)


def _announce(args: argparse.Namespace, desc: dict, seed: int, service, plan, slice_note: str) -> None:
    """The lines `shm hil serve` prints once it serves: the rig, each endpoint with its --link URL, the faults."""
    print(f"shm hil: rig {desc['params']}"
          + (f", scenario {desc['scenario']}" if desc["scenario"] else ", no scenario (bench rig)")
          + f", seed {seed}; clock {args.clock} at {1 / service.host.dt:g} Hz"
          + (", rig time starts at the board's first command" if args.start == "first-command" else "")
          + ("; every board run starts the rig again from t = 0" if args.clock == "lockstep" else
             "; the scenario plays once (one board run per stub run)"),
          flush=True)
    for srv in service.servers:
        print(f"  {srv.describe()}", flush=True)
        print(f"    board: --link {srv.board_url}", flush=True)
    for line in plan.describe():
        print(f"  fault: {line}", flush=True)
    print(f"  scheduler slice: {slice_note}", flush=True)


def _serve_until_stopped(args: argparse.Namespace, service, stop: threading.Event) -> None:
    """Serve until ``stop`` (a signal) or ``--duration``; a status line every ``--status-every`` s."""
    t0 = time.monotonic()
    next_status = t0 + args.status_every if args.status_every > 0 else float("inf")
    while not stop.is_set():
        stop.wait(0.1)
        now = time.monotonic()
        if args.duration is not None and now - t0 >= args.duration:
            break
        if now >= next_status:
            next_status += args.status_every
            h = service.host
            p = h.pacing
            print(f"  [{now - t0:7.1f} s] rig t = {h.snapshot.sample.t:8.2f} s, commands {h.commands}, "
                  f"refused {h.refused_count}, deadline misses {p.deadline_misses}, incidents {h.incident_count}",
                  file=sys.stderr, flush=True)


def _report(args: argparse.Namespace, service, slice_note) -> None:
    """The end-of-run summary: one line on stdout, the JSON file with ``--summary``."""
    summary = service.summary()
    summary["sched_slice"] = {"applied": slice_note.applied, "slice_ms": 1e3 * slice_note.slice_s,
                              "note": slice_note.note, "rig_clock": service.host.clock_slice_note}
    summary["incident_log"] = service.host.incidents[-50:]
    print("shm hil: stopped. " + json.dumps(to_jsonable({k: v for k, v in summary.items() if k != "incident_log"})),
          flush=True)
    if args.summary:
        Path(args.summary).write_text(json.dumps(to_jsonable(summary), indent=2))


def cmd_serve(args: argparse.Namespace) -> int:
    from shm_cli.main import CliError

    if not (args.serial or args.modbus_tcp or args.modbus_rtu):
        raise CliError("no endpoint requested: give at least one of --serial pty|URL, --modbus-tcp HOST:PORT, "
                       "--modbus-rtu pty|PATH")
    if args.duration is not None and not args.duration > 0:
        raise CliError(f"--duration {args.duration!r}: must be > 0 s")
    logging.basicConfig(level=logging.WARNING, format="%(asctime)s %(name)s: %(message)s", stream=sys.stderr)
    logging.getLogger("pymodbus").setLevel(logging.CRITICAL)
    from drivers.latency_slice import request_process_slice

    # every thread: the serving threads started later (Modbus event loop, serial servers, rig clock) inherit it
    slice_note = request_process_slice(serving_slice_ms(args.sched_slice_ms,
                                                        len(args.serial) + len(args.modbus_rtu)) / 1e3)
    # at once, before the imports and the truth plant's kernels (a cold cache compiles them: announced by the plant)
    print(f"shm hil: building the rig ({'scenario ' + args.scenario if args.scenario else 'bench rig'}); the "
          f"endpoints open when it is ready …", file=sys.stderr, flush=True)
    from board_config.scenario import load_scenario
    from hil_stub.service import HilService
    from hil_stub.truth import build_truth_rig

    scenario = load_scenario(args.scenario) if args.scenario else None
    seed = args.seed if args.seed is not None else (scenario.seed if scenario else 0)
    plan = fault_plan(args, seed)
    from workbench.fit import probe_effects  # an effect giving NaN: refused, not served mute

    probe_effects(args.effect, args.params or "table2", "--effect")
    hv = {"scenario": None, "present": True, "absent": False}[args.hv]
    # real time: integrate tick by tick (an idle rig would otherwise integrate 50 ticks in one go, a ~0.1 s step)
    def build():
        return build_truth_rig(scenario, seed=seed, params=args.params, truth=plan.truth, hv_present=hv,
                               lookahead_ticks=1 if args.clock == "realtime" else None)

    rig = build()
    # lockstep: every board run gets the rig from t = 0 (docs/real-rig.md); a real-time rig plays its scenario once
    clock_slice = None if args.clock_slice_ms is None else args.clock_slice_ms / 1e3
    service = HilService(rig, mode=args.clock, plan=plan, start=args.start, restart=build, clock_slice_s=clock_slice,
                         rig_clock=args.rig_clock, hot_path=args.modbus_path == "hot")
    for where in args.serial:
        service.add_serial(where, baudrate=args.baud)
    for where in args.modbus_tcp:
        service.add_modbus_tcp(where, unit=args.unit)
    for where in args.modbus_rtu:
        service.add_modbus_rtu(where, unit=args.unit, baudrate=args.baud, parity=args.parity)

    stop = threading.Event()

    def _on_signal(signum, _frame):
        stop.set()

    old = {sig: signal.signal(sig, _on_signal) for sig in (signal.SIGINT, signal.SIGTERM)}
    live = None
    try:
        try:
            service.start()
        except OSError as exc:
            raise CliError(f"cannot open an endpoint: {exc}") from exc
        # everything loaded so far (numba, numpy, pymodbus ...) is long-lived: keep it out of the garbage collector's
        # full collections, which would otherwise stall every thread for ~0.1 s now and then
        gc.collect()
        gc.freeze()
        desc = rig.describe()
        _announce(args, desc, seed, service, plan, slice_note.note)
        from shm_cli.live_args import start_live  # --live: the rig's page (docs/live.md)

        live = start_live(args)
        if live is not None:
            live.attach_rig(service, title=f"rig {desc['params']}, clock {args.clock}, "
                                           + ", ".join(srv.describe() for srv in service.servers))
        _serve_until_stopped(args, service, stop)
    finally:
        service.stop()
        for sig, handler in old.items():
            signal.signal(sig, handler)
        if live is not None:
            live.finish("interrupted" if stop.is_set() else "finished")
    _report(args, service, slice_note)
    return live.linger(0, interrupted=stop.is_set()) if live is not None else 0
