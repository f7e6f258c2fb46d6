"""The rig as a Modbus server (pymodbus 3.16, ``SimDevice`` + async ``action`` hook), over TCP or RTU.

The register map is :mod:`drivers.modbus_registers`. The device is built with separate blocks per table
(coils, discrete inputs, holding, input registers). The ``action`` hook runs on the server's event loop for
every valid request and never blocks it:

* reads of input registers / discrete inputs / the coil are filled from the host's latest snapshot;
* writes of holding registers are checked with :func:`~drivers.modbus_registers.check_holding_write` (whole
  values only, writable entries only, set-points inside Table 1) and refused with exception 02 or 03 — a
  refused write changes nothing; an accepted write of the command block is posted to the host and answered on
  the loop's thread (in lockstep mode the plant step too, tens of microseconds; only a new board run's fresh rig
  is awaited from a worker thread). With the realtime clock on the same loop (:class:`~hil_stub.service.HilService`
  ``rig_clock="loop"``) a request costs the stub one wake-up: no thread hand-over, no GIL hand-over.

Behaviour the spec wants and pymodbus does not do by itself, added here: an unknown function code is answered
with exception 01 and a bad quantity / byte count with 03, echoing the function code (pymodbus answers both with
01 on function 0x80); a request for another unit id is ignored (silence, on RTU and TCP; TCP also answers unit 255
"not significant"); while the rig schedules a
link outage, or a wire fault drops the reply, nothing is sent. Wire faults act on the reply bytes
(``trace_packet``): a corrupted RTU reply fails its CRC; on TCP, which has no checksum of its own, the
corruption is put in the MBAP transaction id, so the master rejects the reply instead of using wrong data.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import struct
import time
from collections import Counter, deque

from pymodbus.constants import ExcCodes
from pymodbus.framer import FramerType
from pymodbus.server import ModbusSerialServer, ModbusTcpServer
from pymodbus.server.requesthandler import ServerRequestHandler
from pymodbus.simulator import DataType, SimData, SimDevice

from board_config.errors import InputError
from board_config.url_options import split_host_port
from drivers.modbus_registers import (
    BY_NAME,
    COMMAND_END,
    COMMAND_START,
    DISCRETE_COUNT,
    FC23_MAP_VERSION,
    HOLDING_COUNT,
    HOLDING_START,
    INPUT_COUNT,
    INPUT_START,
    MAP_VERSION,
    MIRROR_START,
    ModbusExceptionCode,
    check_holding_write,
    decode_command_block,
    encode_input_block,
    initial_holding_block,
)
from hil_stub import modbus_hot_path as hot
from hil_stub import protocol_ptymaster
from hil_stub.faults import LinkFaults, ReplyFaulter
from hil_stub.loop_thread import LoopThread
from hil_stub.modbus_handler import CheckingSerialServer, CheckingTcpServer
from hil_stub.modbus_requests import check_request_pdu
from hil_stub.pty_port import PtyPort
from hil_stub.rig_host import Delivery, RigHost

log = logging.getLogger("hil_stub.modbus_server")


def _bits(*values: bool) -> int:
    return sum(1 << i for i, v in enumerate(values) if v)


class ModbusRigServer:
    """Serve the host's rig over Modbus TCP (``kind="tcp"``, ``where="HOST:PORT"``, port 0 = any free one) or
    RTU (``kind="rtu"``, ``where`` = a serial device path, or ``"pty"`` for a built-in pty: the server serves
    its master side directly (:mod:`hil_stub.protocol_ptymaster`), the board opens its slave side by the printed
    path)."""

    def __init__(self, host: RigHost, kind: str, where: str, *, loop: LoopThread, unit: int = 1,
                 faults: LinkFaults | None = None, seed: int = 0, stream: int = 2, baudrate: int = 115200,
                 parity: str = "N", map_version: int = MAP_VERSION, hot_path: bool = True) -> None:
        if kind not in ("tcp", "rtu"):
            raise ValueError(f"Modbus server kind {kind!r}: allowed tcp, rtu")
        if not 1 <= unit <= 247:
            raise InputError(f"Modbus unit id {unit} outside 1..247")
        self.host = host
        self.kind = kind
        self.where = where
        self.loop = loop
        self.unit = unit
        self.faulter = ReplyFaulter(faults, seed, stream)
        self.baudrate = baudrate
        self.parity = parity
        self.stats: Counter[str] = Counter()
        self._server: ModbusTcpServer | ModbusSerialServer | None = None
        self._pty: PtyPort | None = None
        self._tcp_host = ""
        self.port = 0
        self.serial_path = ""
        self.board_path = ""
        #: 2 (default): the sample mirror and FC 23 are served; 1: the map without them (FC 23 -> exception 02 on
        #: the mirror), as a rig written for map version 1
        self.map_version = int(map_version)
        self._holding = initial_holding_block(host.limits.voltage_min, host.limits.voltage_max, host.dt,
                                              self.map_version)
        self._watch_task: asyncio.Task | None = None
        self.hot_path = hot_path  #: FC 03/04/16/23 answered by :mod:`.modbus_hot_path` (else by pymodbus)
        self._tables: hot.RegisterTables | None = None
        self._disconnect_done = False
        self._silence = False
        self._fc23_silence = False  # the write part of an FC 23 found the rig's link down: its reply is withheld
        #: seconds from a request's bytes arriving to its reply leaving, the last 100 000 (exchanges that send no
        #: reply are not counted): the stub's own answer time, without the network or the client's scheduling
        self.service_times: deque[float] = deque(maxlen=100_000)
        self._received_at: float | None = None
        #: TCP: seconds from the kernel receiving a request (its software receive timestamp) to the reply leaving, the
        #: last 100 000: the answer time with the stub's own wake-up in it (:mod:`hil_stub.kernel_rx_time`)
        self.kernel_service_times: deque[float] = deque(maxlen=100_000)
        self.kernel_received_at: float | None = None  #: CLOCK_REALTIME (s) of the request being answered
        self.kernel_stamps = False  #: whether the kernel stamps the served connection's requests
        self._wire = "send"
        if kind == "tcp":
            endpoint = split_host_port(where)
            if endpoint is None:
                raise InputError(f"--modbus-tcp {where!r}: expected HOST:PORT (PORT 0 picks a free port)")
            self._tcp_host, self.port = endpoint
        elif where == "pty":
            self._pty = PtyPort(name="modbus-rtu-board")
        else:
            self.serial_path = where

    # ------------------------------------------------------------------------------------------ endpoints
    @property
    def board_url(self) -> str:
        if self.kind == "tcp":
            return f"modbus-tcp://{self._tcp_host}:{self.port}?unit={self.unit}"
        path = self.board_path or self.serial_path
        return f"modbus-rtu:{path}?baud={self.baudrate}&parity={self.parity}&unit={self.unit}"

    def describe(self) -> str:
        if self.kind == "tcp":
            return f"Modbus TCP on {self._tcp_host}:{self.port} (unit {self.unit})"
        if self._pty is not None:
            return (f"Modbus RTU on a pty: board end {self._pty.link} ({self.baudrate} baud, parity {self.parity}, "
                    f"unit {self.unit})")
        return f"Modbus RTU on {self.serial_path} ({self.baudrate} baud, parity {self.parity}, unit {self.unit})"

    # ------------------------------------------------------------------------------------------ device
    def _device(self) -> SimDevice:
        lim_start = BY_NAME["map_version"].address
        holding_rw = self._holding[: lim_start - HOLDING_START]
        holding_ro = self._holding[lim_start - HOLDING_START:]
        return SimDevice(
            id=0,  # answers every unit id; the trace_pdu filter keeps only ours (silence for the others)
            simdata=(
                [SimData(0, values=[False], datatype=DataType.BITS, readonly=True)],
                [SimData(0, values=[False] * DISCRETE_COUNT, datatype=DataType.BITS, readonly=True)],
                [SimData(HOLDING_START, values=holding_rw, datatype=DataType.REGISTERS),
                 SimData(lim_start, values=holding_ro, datatype=DataType.REGISTERS, readonly=True)]
                + ([SimData(MIRROR_START, values=[0] * INPUT_COUNT, datatype=DataType.REGISTERS, readonly=True)]
                   if self.map_version >= FC23_MAP_VERSION else []),
                [SimData(INPUT_START, values=[0] * INPUT_COUNT, datatype=DataType.REGISTERS, readonly=True)],
            ),
            action=self._action,
        )

    async def _action(self, function_code: int, start_address: int, address: int, count: int,
                      registers: list[int], set_values: list[int] | list[bool] | None) -> ExcCodes | None:
        """pymodbus' hook for every valid request, in stages: reads filled from the snapshot, coil writes refused,
        holding writes checked and the command posted to the host, then the reply's silence and delay."""
        sample_read = self._fill_read(function_code, start_address, address, count, registers, set_values)
        silence = False
        if function_code in (0x05, 0x0F):  # pymodbus ignores readonly= on bit blocks: refuse coil writes here
            self.stats["exception_02"] += 1
            self.host.incident(f"{self.describe()}: coil write refused with exception 02 (read-only)")
            return ExcCodes.ILLEGAL_ADDRESS
        if function_code in (0x06, 0x10, 0x16, 0x17) and set_values is not None:
            # FC 22 (mask write) and the write part of FC 23 are checked like FC 06 / FC 16: whole values, writable
            # entries, finite demands inside Table 1
            code, silence = await self._take_write(start_address, address, registers, [int(v) for v in set_values])
            if code is not None:
                return code
        if self.host.mode == "realtime" and self.host.link_down():
            silence = True
        # --latency-ms delays the sample of each exchange (the FC04 reply), as on the serial link: the rig's
        # response time per board tick; acknowledgements of the command write are not delayed
        if function_code == 0x17:
            if set_values is not None:  # the write part of FC 23: its read part follows (delay, silence there)
                self._fc23_silence = silence
                return None
            silence, self._fc23_silence = silence or self._fc23_silence, False
        delay = self.faulter.faults.processing_s + (self.faulter.draw_delay() if sample_read else 0.0)
        if delay > 0:
            await asyncio.sleep(delay)
        # from here to the reply's trace_packet nothing awaits: the flag belongs to this reply
        self._silence = silence
        return None

    def _fill_read(self, function_code: int, start_address: int, address: int, count: int, registers: list[int],
                   set_values: list[int] | list[bool] | None) -> bool:
        """Fill a read's registers from the host's latest snapshot; whether it read the sample block."""
        host = self.host
        if function_code == 0x04 or (function_code in (0x03, 0x17) and set_values is None
                                     and address + count > MIRROR_START):
            # the input registers, or (map version 2) the sample mirror: FC 03, or the read part of FC 23 after its
            # write; the read part of FC 23 outside the mirror reads the holding block as it is
            snap = host.snapshot
            off = (INPUT_START if function_code == 0x04 else MIRROR_START) - start_address
            registers[off: off + INPUT_COUNT] = encode_input_block(snap.sample, snap.cmd_seq_applied,
                                                                   snap.refused_count)
            self.stats["reads"] += 1
            if function_code != 0x04:
                self.stats["fc23_exchanges" if function_code == 0x17 else "mirror_reads"] += 1
            return True
        if function_code == 0x02 and set_values is None:
            s = host.snapshot.sample
            registers[0] = _bits(s.hv_present, bool(s.flags & 1), bool(s.flags & 2), bool(s.flags & 4))
        elif function_code == 0x01 and set_values is None:
            registers[0] = _bits(host.snapshot.amplifier_active)
        return False

    async def _take_write(self, start_address: int, address: int, registers: list[int],
                          values: list[int]) -> tuple[ExcCodes | None, bool]:
        """Check a holding write and post a command it completes to the host: (the exception to answer or None,
        whether the reply is withheld because the rig's link is down)."""
        host = self.host
        off = HOLDING_START - start_address
        current = registers[off: off + HOLDING_COUNT]
        verdict = check_holding_write(address, values, current, host.limits.voltage_min, host.limits.voltage_max)
        touches_command = address < COMMAND_END and address + len(values) > COMMAND_START
        if not verdict.finite:  # NaN/Inf: refused here, before the rig (no count, no flag, no tick, no run)
            self.stats["nonfinite_refused"] += 1
        if verdict.code is not None and not (verdict.code == ModbusExceptionCode.ILLEGAL_VALUE
                                             and touches_command and verdict.finite):
            self.stats[f"exception_{int(verdict.code):02d}"] += 1
            host.incident(f"{self.describe()}: write refused with exception {int(verdict.code):02d}: {verdict.reason}")
            return ExcCodes(int(verdict.code)), False
        if not touches_command:
            return None, False
        # also an out-of-limit command goes to the host: it refuses it there (and, in lockstep, the rig still
        # advances one tick, as in-process); the registers keep the last accepted command
        new = list(current)
        new[address - HOLDING_START: address - HOLDING_START + len(values)] = values
        cmd = decode_command_block(new[COMMAND_START - HOLDING_START: COMMAND_END - HOLDING_START])
        self.stats["commands"] += 1
        if host.mode == "lockstep" and host.starts_again(cmd.seq):  # building a rig: in a worker thread, the loop free
            delivery = await asyncio.get_running_loop().run_in_executor(None, host.submit, cmd, self.kind)
        else:
            delivery = host.submit(cmd, self.kind)
        if delivery is Delivery.UNDELIVERED:
            if verdict.code is not None:  # the rig's link is down: no reply at all
                self._silence = True
                return ExcCodes.ILLEGAL_VALUE, True
            return None, True
        if delivery is Delivery.REFUSED or verdict.code is not None:
            self.stats["exception_03"] += 1
            return ExcCodes.ILLEGAL_VALUE, False
        return None, False

    def _trace_pdu(self, sending: bool, pdu):
        if sending:
            self._wire = self.faulter.draw_action()
            return pdu
        # a request: keep only our unit id (and 255 on TCP); others get silence, as on a shared RS-485 line
        if pdu.dev_id != self.unit and not (self.kind == "tcp" and pdu.dev_id == 255):
            self.stats["other_unit_ignored"] += 1
            return None
        self.stats["requests"] += 1
        return pdu

    def _trace_packet(self, sending: bool, data: bytes) -> bytes:
        if not sending:
            self._received_at = time.perf_counter()
            return data
        if self._received_at is not None:  # the stub's own answer time: request bytes in -> reply bytes out
            self.service_times.append(time.perf_counter() - self._received_at)
            self._received_at = None
        if self.kernel_received_at is not None:  # the same from the kernel's receive timestamp (wake-up included)
            self.kernel_service_times.append(time.time() - self.kernel_received_at)
            self.kernel_received_at = None
        silence, self._silence = self._silence, False
        wire, self._wire = self._wire, "send"
        if silence:
            self.stats["replies_withheld_link_down"] += 1
            return b""
        if wire == "drop":
            self.stats["replies_dropped"] += 1
            return b""
        if wire == "corrupt":
            self.stats["replies_corrupted"] += 1
            # RTU: anywhere (the CRC catches it); TCP: the MBAP transaction id (bytes 0-1)
            data = self.faulter.flip_bit(data, 0, 2 if self.kind == "tcp" else None)
        self.stats["replies"] += 1
        return data

    def stale_request_bytes(self, data: bytes) -> int:
        """TCP: the bytes of the complete requests that arrived together *before* the last complete one (0: one
        request or fewer). pymodbus would answer the first of them and drop the rest with its buffer; a board sends
        its next request only after giving up on the previous one (a reply too late for its tick), so the newest is
        the one worth answering — the others are counted (``stale_requests_skipped``) and not served."""
        if self.kind != "tcp":
            return 0
        frames = hot.frame_starts(data)
        if len(frames) < 2:
            return 0
        self.stats["stale_requests_skipped"] += len(frames) - 1
        return frames[-1]

    def answer_hot(self, handler: ServerRequestHandler, data: bytes) -> int:
        """Answer a well-formed FC 03/04/16/23 request for our unit from the register tables now (the same hook, faults
        and statistics as pymodbus' path, :mod:`hil_stub.modbus_hot_path`); the bytes used (0: left to pymodbus)."""
        tcp = self.kind == "tcp"
        req = (hot.parse_mbap(data) if tcp else hot.parse_rtu(data)) if self._tables is not None else None
        lf = self.faulter.faults
        if (req is None or req.fc not in hot.HOT_FUNCTIONS or not (req.unit == self.unit or (tcp and req.unit == 255))
                or lf.processing_s or lf.latency_s or lf.jitter_s):
            return 0
        assert self._tables is not None
        pdu = data[req.pdu_start:req.pdu_end]
        if self.host.mode == "lockstep" and (seq := self._tables.command_seq(pdu)) is not None \
                and self.host.starts_again(seq):  # a fresh rig is built in a worker thread: pymodbus awaits it
            return 0
        self._trace_packet(False, data)
        self.stats["requests"] += 1
        self.stats["hot_path_answers"] += 1
        try:
            reply = self._tables.answer(pdu)
        except Exception as exc:  # as pymodbus answers a failing datastore
            log.error("%s: request failed on the hot path: %r", self.describe(), exc)
            reply = hot.exception_pdu(req.fc, hot.DEVICE_FAILURE)
        self._wire = self.faulter.draw_action()
        reply = self._trace_packet(True, hot.reply_adu(req, reply))
        if reply:
            handler.send(reply)
        return req.end

    def precheck(self, handler: ServerRequestHandler, data: bytes) -> int:
        """Answer a malformed request (see :func:`check_request_pdu`) before pymodbus does; return the bytes used
        (0: not handled here). Requests for other unit ids are left to the unit filter (silence)."""
        tcp = self.kind == "tcp"
        req = self._whole_tcp_frame(data) if tcp else hot.parse_rtu(data)
        if req is None:
            return 0  # not one complete frame (on RTU: with a good CRC): pymodbus hunts / waits as usual
        code = check_request_pdu(data[req.pdu_start:req.pdu_end])
        if code is None:
            return 0
        if req.unit == self.unit or (tcp and req.unit == 255):
            handler.send(hot.reply_adu(req, hot.exception_pdu(req.fc, code)))
        self.stats[f"exception_{code:02d}"] += 1
        self.host.incident(f"{self.describe()}: malformed request (function {req.fc}) answered with exception "
                           f"{code:02d}")
        return req.end

    @staticmethod
    def _whole_tcp_frame(data: bytes) -> hot.Request | None:
        """The first MBAP frame of ``data`` when complete with protocol id 0 and a length of at least 2 (any length
        above: a too-long PDU is answered with its exception here, where :func:`hot.parse_mbap` leaves it)."""
        if len(data) < 8:
            return None
        tid, pid, length, unit, fc = struct.unpack_from(">HHHBB", data)
        if pid != 0 or length < 2 or len(data) < 6 + length:
            return None
        return hot.Request(tid, unit, fc, 7, 6 + length, 6 + length)

    def service_time_summary(self, from_kernel: bool = False) -> dict[str, float | int]:
        """p50 / p99 / max (ms) of :attr:`service_times` (``from_kernel``: :attr:`kernel_service_times`) and their
        count."""
        times = sorted(self.kernel_service_times if from_kernel else self.service_times)
        if not times:
            return {"n": 0}

        def pct(q: float) -> float:
            return 1e3 * times[min(len(times) - 1, int(q * len(times)))]

        return {"n": len(times), "p50_ms": pct(0.5), "p99_ms": pct(0.99), "max_ms": 1e3 * times[-1]}

    # ------------------------------------------------------------------------------------------ lifecycle
    async def _start(self) -> None:
        device = self._device()
        if self.kind == "tcp":
            tcp = CheckingTcpServer(device, address=(self._tcp_host, self.port), trace_pdu=self._trace_pdu,
                             trace_packet=self._trace_packet)
            tcp.rig = self
            self._server = tcp
            await tcp.serve_forever(background=True)
            listener = tcp.transport  # pymodbus keeps its listening asyncio.Server there (typed as a transport)
            if not isinstance(listener, asyncio.Server):
                raise OSError(f"{self.describe()}: cannot listen on {self._tcp_host}:{self.port}")
            self.port = listener.sockets[0].getsockname()[1]  # keep the same port across restarts
        else:
            if self._pty is not None:
                assert self._pty.master is not None
                protocol_ptymaster.register()
                path = protocol_ptymaster.url_for(self._pty.master)
            else:
                path = self.serial_path
            rtu = CheckingSerialServer(device, framer=FramerType.RTU, port=path, baudrate=self.baudrate,
                                parity=self.parity, trace_pdu=self._trace_pdu, trace_packet=self._trace_packet,
                                reconnect_delay=0.2)
            rtu.rig = self
            self._server = rtu
            await rtu.serve_forever(background=True)
        self._tables = hot.RegisterTables.of_server(self._server, self._action) if self.hot_path else None
        if self._watch_task is None and self.faulter.faults.disconnect_at_s is not None:  # else no wake-ups for it
            self._watch_task = asyncio.get_running_loop().create_task(self._watch())

    async def _stop_server(self) -> None:
        server, self._server = self._server, None
        if server is not None:
            with contextlib.suppress(Exception):
                await server.shutdown()

    async def _stop(self) -> None:
        if self._watch_task is not None:
            self._watch_task.cancel()
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await self._watch_task
            self._watch_task = None
        await self._stop_server()

    async def _watch(self) -> None:
        """Scheduled disconnects (rig time) and restarts."""
        lf = self.faulter.faults
        while True:
            await asyncio.sleep(0.005)
            if (lf.disconnect_at_s is not None and not self._disconnect_done
                    and self.host.snapshot.sample.t >= lf.disconnect_at_s):
                self._disconnect_done = True
                await self._outage(lf.disconnect_for_s, f"injected disconnect at rig t = {lf.disconnect_at_s:g} s")

    async def _outage(self, seconds: float, why: str) -> None:
        self.stats["disconnects"] += 1
        self.host.incident(f"{self.describe()}: {why}; server down for {seconds:.2f} s")
        await self._stop_server()
        await asyncio.sleep(seconds)
        await self._start()
        log.warning("%s: back up", self.describe())

    def start(self) -> None:
        """Start serving; ``OSError`` naming the endpoint if the port cannot be bound / the device opened."""
        if self._pty is not None and not self._pty.is_open:
            self.board_path = self._pty.open()
        try:
            self.loop.run(self._start())
        except (RuntimeError, OSError) as exc:  # pymodbus: "Could not start listen, please check address."
            raise OSError(f"{self.describe()}: cannot serve ({exc})") from exc

    def stop(self) -> None:
        if not self.loop.loop.is_closed():
            with contextlib.suppress(Exception):
                self.loop.run(self._stop())
        if self._pty is not None:
            self._pty.close()

    def restart(self) -> None:
        """Stop and start the server now (same port / path): a server restart seen from the board."""
        self.loop.run(self._stop_server())
        self.stats["restarts"] += 1
        self.loop.run(self._start())

    def go_down(self) -> None:
        """Shut the server down now (connections dropped, port/device closed) until :meth:`come_back`."""
        self.stats["disconnects"] += 1
        self.host.incident(f"{self.describe()}: server taken down")
        self.loop.run(self._stop_server())

    def come_back(self) -> None:
        """Start the server again after :meth:`go_down` (same port / path); returns once it listens."""
        self.loop.run(self._start())

    def disconnect(self, seconds: float) -> None:
        """Take the server down now for ``seconds`` (wall clock), then bring it back (does not wait)."""
        self.loop.submit(self._outage(seconds, "disconnect requested"))
