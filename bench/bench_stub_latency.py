"""The HIL stub alone: how fast `shm hil serve` answers one Modbus TCP transaction (issue 29, point 2).

`shm hil serve --modbus-tcp 127.0.0.1:0 --clock realtime` runs as its own process at normal priority; this process
sends it, 100 times a second, what a board sends: one FC 23 (write the command block, read the sample mirror) per
tick, and every 10th tick the FC 16 + FC 04 pair of a map version 1 board instead; then the same over Modbus RTU on
the stub's pty (no line time: what is measured is the stub and the pty, not a baud rate). A bare socket client (no
pymodbus on this side) times each transaction from the request's send to the reply's last byte: the stub's answer
time plus loopback and this process's own wake-up. Two phases of the same length: idle, then with one CPU-bound
process per core at normal priority beside it (the desk of issue 29). Reported per phase and function: p50, p99,
max (ms), the transactions and the lost ones (no reply within 50 ms); and the stub's own answer time (request bytes
in to reply bytes out, measured inside the stub: ``answer_time`` of its ``--summary``), which leaves out the
network and this process's scheduling. Each phase runs against a fresh stub. Target: p99 <= 1.5 ms per transaction
under load. On a shared machine other processes' CPU use shows up directly in p99 and max: the load average before each
phase is recorded with the result.

Every phase runs three times, back to back: with the kernel's default time slice (``shm hil serve --sched-slice-ms
0``, the client as it is), with the short slice for every thread of the stub (``--sched-slice-ms 0.2``; the client's
sending thread asks for the same, as ``shm run --link`` does for the board's link thread: :mod:`drivers.latency_slice`)
and with the short slice but the rig clock in a thread of its own (``--rig-clock thread``, the stub before the clock
moved onto the Modbus event loop: one more thread to wake and the GIL handed over between the two). All at normal
priority, as are the hogs; on a kernel without EEVDF custom slices the first two variants are the same code path (the
note says so). On TCP the stub also reports its answer time from the
kernel's receive timestamp of each request (``answer_time_from_kernel_rx``: its own wake-up included, which the
event loop's clock cannot see).

``--quick``: 3 s per phase (a smoke run, not for quoting); full: 12 s per phase (12 runs, ~5 min on a quiet machine).
``SHM_BENCH_STUB_PHASES=under_load,rtu_under_load`` runs only the phases named, ``SHM_BENCH_STUB_VARIANTS=short_slice,
short_slice_pymodbus_path`` only the variants named (the stub's hot Modbus path against pymodbus' request chain,
``--modbus-path pymodbus``, back to back; ``none``: only the side-by-side phase). The side-by-side phase (each phase)
serves both request paths at once from two stubs, one client alternating between them tick by tick: on a busy machine
the only fair comparison, since back-to-back runs meet different loads.
"""

from __future__ import annotations

import json
import math
import os
import socket
import struct
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import ClassVar

import numpy as np
from pymodbus.framer.rtu import FramerRTU

from drivers.latency_slice import request_slice
from drivers.link import ActuatorCommand
from drivers.modbus_registers import COMMAND_START, INPUT_COUNT, INPUT_START, MIRROR_START, encode_command_block

TICK_S = 0.01
_REPLY_TIMEOUT_S = 0.05


def _command(k: int) -> ActuatorCommand:
    v = 600.0 * math.sin(2 * math.pi * 0.1 * k * TICK_S)  # MBIT.a-like: 600 V differential sine at 0.1 Hz
    return ActuatorCommand(seq=k, v_ch1=100.0 + v, v_ch2=100.0 - v, board_current=0.003)


def start_stub(extra: tuple[str, ...] = (), rtu: bool = False) -> tuple[subprocess.Popen, int | str]:
    """`shm hil serve` (realtime clock, HV present) on a free loopback port, or with ``rtu`` on a pty; its process
    and the port (TCP) or the board end's path (RTU)."""
    endpoint = ["--modbus-rtu", "pty"] if rtu else ["--modbus-tcp", "127.0.0.1:0"]
    cmd = [sys.executable, "-m", "shm_cli.main", "hil", "serve", *endpoint, "--clock", "realtime", "--hv", "present",
           "--status-every", "0", *extra]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True,
                            env={**os.environ, "MFC_SHM_THREADS": "1"})
    assert proc.stdout is not None
    deadline = time.monotonic() + 120.0  # a first run may compile the plant kernels
    while time.monotonic() < deadline:
        line = proc.stdout.readline()
        if not line:
            break
        if "board: --link modbus-tcp://" in line:
            return proc, int(line.split("modbus-tcp://", 1)[1].split("?", 1)[0].rsplit(":", 1)[1])
        if "board: --link modbus-rtu:" in line:
            return proc, line.split("modbus-rtu:", 1)[1].split("?", 1)[0].strip()
    proc.kill()
    raise RuntimeError("the HIL stub did not come up")


class RawModbusTcp:
    """A minimal blocking Modbus TCP client (unit 1) that times each transaction."""

    def __init__(self, port: int) -> None:
        self.sock = socket.create_connection(("127.0.0.1", port), timeout=2.0)
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.sock.settimeout(_REPLY_TIMEOUT_S)
        self.tid = 0
        self.buf = b""

    def transact(self, pdu: bytes) -> tuple[float, bytes | None]:
        """(request-to-reply seconds, reply PDU or None when lost); stale replies (other tids) are skipped."""
        self.tid = (self.tid + 1) & 0xFFFF
        t0 = time.perf_counter()
        self.sock.sendall(struct.pack(">HHHB", self.tid, 0, len(pdu) + 1, 1) + pdu)
        try:
            while True:
                while len(self.buf) < 7 or len(self.buf) < 6 + struct.unpack(">H", self.buf[4:6])[0]:
                    chunk = self.sock.recv(4096)
                    if not chunk:
                        raise ConnectionError("the stub closed the connection")
                    self.buf += chunk
                length = struct.unpack(">H", self.buf[4:6])[0]
                frame, self.buf = self.buf[:6 + length], self.buf[6 + length:]
                if struct.unpack(">H", frame[:2])[0] == self.tid:
                    return time.perf_counter() - t0, frame[7:]
        except TimeoutError:
            self.buf = b""
            return time.perf_counter() - t0, None

    def close(self) -> None:
        self.sock.close()


class RawModbusRtu:
    """A minimal Modbus RTU master (unit 1) on a pty's board end that times each transaction (no line time: a pty
    moves bytes at once)."""

    _REPLY_LEN: ClassVar[dict[int, int]] = {4: 5 + 2 * INPUT_COUNT, 23: 5 + 2 * INPUT_COUNT, 16: 8}

    def __init__(self, path: str) -> None:
        import termios
        import tty

        self.fd = os.open(path, os.O_RDWR | os.O_NOCTTY)
        tty.setraw(self.fd)
        termios.tcflush(self.fd, termios.TCIOFLUSH)

    def transact(self, pdu: bytes) -> tuple[float, bytes | None]:
        import select

        frame = bytes([1]) + pdu
        frame += FramerRTU.compute_CRC(frame).to_bytes(2, "big")  # the Modbus RTU CRC, low byte first
        want = self._REPLY_LEN.get(pdu[0], 5)
        t0 = time.perf_counter()
        os.write(self.fd, frame)
        buf = b""
        deadline = t0 + _REPLY_TIMEOUT_S
        while True:
            if len(buf) >= 2 and buf[1] & 0x80:
                want = 5  # an exception reply
            if len(buf) >= want:
                took = time.perf_counter() - t0
                ok = FramerRTU.check_CRC(buf[: want - 2], int.from_bytes(buf[want - 2: want], "big"))
                return took, (buf[1:want - 2] if ok else None)
            left = deadline - time.perf_counter()
            if left <= 0 or not select.select([self.fd], [], [], left)[0]:
                return time.perf_counter() - t0, None
            buf += os.read(self.fd, 256)

    def close(self) -> None:
        os.close(self.fd)


def _fc23(words: list[int]) -> bytes:
    return struct.pack(">BHHHHB", 23, MIRROR_START, INPUT_COUNT, COMMAND_START, len(words), 2 * len(words)) + \
        b"".join(struct.pack(">H", w) for w in words)


def _fc16(words: list[int]) -> bytes:
    return struct.pack(">BHHB", 16, COMMAND_START, len(words), 2 * len(words)) + \
        b"".join(struct.pack(">H", w) for w in words)


_FC04 = struct.pack(">BHH", 4, INPUT_START, INPUT_COUNT)


def paced_transactions(where: int | str, seconds: float, first_seq: int = 1) -> dict[str, list[float]]:
    """At 100 Hz for ``seconds``: FC 23 per tick, FC 16 + FC 04 every 10th tick, over TCP (``where`` a port) or RTU
    (a pty path). Times (s) per function; a lost reply is recorded as NaN."""
    return paced_side_by_side([where], seconds, first_seq)[0]


def paced_side_by_side(wheres: list[int | str], seconds: float, first_seq: int = 1) -> list[dict[str, list[float]]]:
    """:func:`paced_transactions` against several stubs at once: each tick, one board tick's transactions with each
    (the order turned round every tick), so every stub meets the same machine at the same moments."""
    clients: list[RawModbusTcp | RawModbusRtu] = [RawModbusTcp(w) if isinstance(w, int) else RawModbusRtu(w)
                                                  for w in wheres]
    times: list[dict[str, list[float]]] = [{"fc23": [], "fc16": [], "fc04": []} for _ in clients]
    n = round(seconds / TICK_S)
    t_next = time.perf_counter()
    try:
        for i in range(n):
            k = first_seq + i
            words = encode_command_block(_command(k))
            pdus = (("fc16", _fc16(words)), ("fc04", _FC04)) if i % 10 == 9 else (("fc23", _fc23(words)),)
            for j in (range(len(clients)) if i % 2 == 0 else reversed(range(len(clients)))):
                for name, pdu in pdus:
                    took, reply = clients[j].transact(pdu)
                    times[j][name].append(took if reply is not None and reply[0] & 0x80 == 0 else math.nan)
            t_next += TICK_S
            delay = t_next - time.perf_counter()
            if delay > 0:
                time.sleep(delay)
            elif delay < -0.1:  # this process was stalled: do not race to catch up
                t_next = time.perf_counter()
    finally:
        for client in clients:
            client.close()
    return times


def latency_stats(times: list[float]) -> dict[str, float | int]:
    """p50 / p99 / max (ms) of the answered transactions, their count and the lost ones."""
    a = np.asarray(times, float)
    ok = a[np.isfinite(a)]
    if ok.size == 0:
        return {"n": int(a.size), "lost": int(a.size)}
    return {"n": int(a.size), "lost": int(a.size - ok.size), "p50_ms": float(np.percentile(ok, 50) * 1e3),
            "p99_ms": float(np.percentile(ok, 99) * 1e3), "max_ms": float(ok.max() * 1e3)}


def _cpu_hogs(n: int) -> list[subprocess.Popen]:
    return [subprocess.Popen([sys.executable, "-c", "while True: pass"], stdout=subprocess.DEVNULL,
                             stderr=subprocess.DEVNULL) for _ in range(n)]


def _phase(ports: list[int | str], seconds: float, first_seq: int, client_slice_s: float) -> list[dict]:
    """``seconds`` of paced transactions (side by side with several stubs) from a thread of their own, which asks for
    ``client_slice_s`` (0: the kernel's default slice) as the board's link thread does; one result per stub."""
    load = os.getloadavg()[0]
    out: dict = {}

    def client() -> None:
        out["slice"] = request_slice(client_slice_s).note
        out["times"] = paced_side_by_side(ports, seconds, first_seq)

    worker = threading.Thread(target=client, name="bench-client")
    worker.start()
    worker.join()
    return [{"load_avg_1min_before": load, "client_slice": out["slice"],
             **{name: latency_stats(t) for name, t in times.items()}} for times in out["times"]]


def _stub_phase(seconds: float, summary: Path, n_hogs: int, rtu: bool = False, slice_s: float = 2e-4,
                clock_slice_s: float | None = None, extra: tuple[str, ...] = ()) -> dict:
    """A fresh stub (``--sched-slice-ms`` from ``slice_s``, ``--clock-slice-ms`` from ``clock_slice_s`` unless
    None), warmed up, then ``seconds`` of paced transactions with ``n_hogs`` CPU hogs beside it; the client's times
    and the stub's own answer times (request bytes in -> reply out, and on TCP from the kernel's receive timestamp
    -> reply out; from its --summary)."""
    return _stubs_phase(seconds, [(summary, extra)], n_hogs, rtu, slice_s, clock_slice_s)[0]


def _stubs_phase(seconds: float, stubs: list[tuple[Path, tuple[str, ...]]], n_hogs: int, rtu: bool = False,
                 slice_s: float = 2e-4, clock_slice_s: float | None = None) -> list[dict]:
    """:func:`_stub_phase` for several fresh stubs at once (each: its --summary file and further options), served
    side by side by one client (:func:`paced_side_by_side`); one result per stub."""
    clock = () if clock_slice_s is None else ("--clock-slice-ms", f"{1e3 * clock_slice_s:g}")
    started = [start_stub(("--summary", str(summary), "--sched-slice-ms", f"{1e3 * slice_s:g}", *clock, *extra),
                          rtu=rtu) for summary, extra in stubs]
    ports = [port for _stub, port in started]
    hogs: list[subprocess.Popen] = []
    try:
        paced_side_by_side(ports, 0.5)  # warm-up: connection, first ticks, kernels
        hogs = _cpu_hogs(n_hogs)
        if hogs:
            time.sleep(1.0)
        results = _phase(ports, seconds, 1000, slice_s)
    finally:
        for h in hogs:
            h.kill()
        for h in hogs:
            h.wait(timeout=10)
        for stub, _port in started:
            stub.terminate()
        for stub, _port in started:
            try:
                stub.wait(timeout=20)
            except subprocess.TimeoutExpired:
                stub.kill()
    for res, (summary, _extra) in zip(results, stubs, strict=True):
        _add_stub_summary(res, summary)
    return results


def _add_stub_summary(res: dict, summary: Path) -> None:
    """The stub's own answer times and time slice, from its --summary file, into ``res``."""
    try:
        stub_summary = json.loads(summary.read_text())
        server = next(iter(stub_summary["servers"].values()))
        res["stub_answer_time"] = server.get("answer_time", {})
        res["stub_answer_time_from_kernel_rx"] = server.get("answer_time_from_kernel_rx", {})
        res["stub_slice"] = stub_summary.get("sched_slice", {})
        res["stub_hot_path_answers"] = server.get("hot_path_answers", 0)
    except (OSError, ValueError, StopIteration, KeyError):
        res["stub_answer_time"] = {}


#: the variants measured side by side, (serving threads' slice, rig clock thread's slice; None: the same) in s: the
#: kernel's default slice everywhere, the short one for every thread of the stub (the rig clock on the Modbus event
#: loop, the stub's default), and the short one with the rig clock in a thread of its own (``--rig-clock thread``, the
#: stub before: a second thread to wake, the GIL handed over between it and the loop; see :data:`VARIANT_ARGS`);
#: ``SHM_BENCH_SLICES_MS="0,0.2,0.5"`` measures those slices for every thread instead (named ``slice_0.5ms``)
VARIANTS: dict[str, tuple[float, float | None]] = {"default_slice": (0.0, None), "short_slice": (2e-4, None),
                                                   "short_slice_clock_thread": (2e-4, None),
                                                   "short_slice_pymodbus_path": (2e-4, None)}
#: further `shm hil serve` options of a variant; ``short_slice_pymodbus_path``: every Modbus request through
#: pymodbus' request chain, the stub before its hot path (:mod:`hil_stub.modbus_hot_path`)
VARIANT_ARGS: dict[str, tuple[str, ...]] = {"short_slice_clock_thread": ("--rig-clock", "thread"),
                                            "short_slice_pymodbus_path": ("--modbus-path", "pymodbus")}


def _named(variable: str, table: dict) -> dict:
    """The entries of ``table`` named in the environment ``variable`` (comma-separated; {} when unset); a
    ``ValueError`` naming the unknown ones."""
    names = [n for n in os.environ.get(variable, "").split(",") if n]
    unknown = sorted(set(names) - set(table))
    if unknown:
        raise ValueError(f"{variable}: unknown name(s) {', '.join(unknown)}; allowed {', '.join(table)}")
    return {n: table[n] for n in names}


def _variants() -> dict[str, tuple[float, float | None]]:
    if os.environ.get("SHM_BENCH_STUB_VARIANTS") == "none":  # the side-by-side comparison alone
        return {}
    named = _named("SHM_BENCH_STUB_VARIANTS", VARIANTS)
    if named:
        return named
    extra = os.environ.get("SHM_BENCH_SLICES_MS", "")
    if not extra:
        return VARIANTS
    out: dict[str, tuple[float, float | None]] = {}
    for text in extra.split(","):
        ms = float(text)
        name = {0.0: "default_slice", 0.2: "short_slice"}.get(ms, f"slice_{ms:g}ms")
        out[name] = (ms / 1e3, None)
    return out


PHASES = {"idle": (False, False), "under_load": (False, True), "rtu_idle": (True, False),
          "rtu_under_load": (True, True)}


def _phases() -> dict[str, tuple[bool, bool]]:
    """:data:`PHASES`, or those named in ``SHM_BENCH_STUB_PHASES`` (comma-separated; e.g. ``under_load``)."""
    return _named("SHM_BENCH_STUB_PHASES", PHASES) or PHASES


#: the side-by-side comparison of the two Modbus request paths (short slice, rig clock on the loop): two stubs at
#: once, one client alternating between them tick by tick, so both meet the same busy machine at the same moments
SIDE_BY_SIDE: dict[str, tuple[str, ...]] = {"hot_path": (), "pymodbus_path": ("--modbus-path", "pymodbus")}


def run(out_dir: Path, quick: bool) -> dict:
    seconds = 3.0 if quick else 12.0
    n_hogs = os.cpu_count() or 1
    res: dict = {"seconds_per_phase": seconds, "cpu_hogs": n_hogs, "nice": os.nice(0)}
    variants = _variants()
    phases = _phases()
    names: list[str] = []
    for phase, (rtu, loaded) in phases.items():
        for variant, (slice_s, clock_slice_s) in variants.items():  # back to back: the same machine state for all
            names.append(f"{variant}_{phase}")
            res[names[-1]] = _stub_phase(seconds, out_dir / f"stub_latency_{variant}_{phase}.json",
                                         n_hogs if loaded else 0, rtu=rtu, slice_s=slice_s,
                                         clock_slice_s=clock_slice_s, extra=VARIANT_ARGS.get(variant, ()))
        both = _stubs_phase(seconds, [(out_dir / f"stub_latency_side_by_side_{phase}_{name}.json", extra)
                                      for name, extra in SIDE_BY_SIDE.items()], n_hogs if loaded else 0, rtu=rtu)
        for name, r in zip(SIDE_BY_SIDE, both, strict=True):
            names.append(f"side_by_side_{phase}_{name}")
            res[names[-1]] = r
    for key in names:
        _flatten(res, key)
    res["target_p99_ms"] = 1.5
    if "under_load" in phases:
        for key in names:
            if key.endswith("under_load") or key.startswith("side_by_side_under_load"):
                res[f"{key}_fc23_p99_within_target"] = bool(res[f"{key}_fc23_p99_ms"] <= 1.5)
    return res


def _flatten(res: dict, key: str) -> None:
    """The headline numbers of one measured stub (``res[key]``) as flat ``{key}_...`` entries of ``res``."""
    r = res[key]
    for name in ("fc23", "fc16", "fc04"):
        res[f"{key}_{name}_p50_ms"] = round(r[name].get("p50_ms", math.nan), 3)
        res[f"{key}_{name}_p99_ms"] = round(r[name].get("p99_ms", math.nan), 3)
    st = r["stub_answer_time"]
    res[f"{key}_stub_answer_p50_ms"] = round(st.get("p50_ms", math.nan), 3)
    res[f"{key}_stub_answer_p99_ms"] = round(st.get("p99_ms", math.nan), 3)
    kt = r.get("stub_answer_time_from_kernel_rx", {})
    if kt:
        res[f"{key}_stub_answer_from_kernel_rx_p50_ms"] = round(kt.get("p50_ms", math.nan), 3)
        res[f"{key}_stub_answer_from_kernel_rx_p99_ms"] = round(kt.get("p99_ms", math.nan), 3)
