"""``ModbusLink``: the board as a Modbus master (pymodbus 3.16 sync clients), TCP or RTU.

URLs (registered in :mod:`drivers.hardware_links`)::

    modbus-tcp://HOST:PORT?unit=1&timeout=0.008
    modbus-rtu:/dev/ttyUSB0?baud=115200&parity=N&unit=1&timeout=0.03

Options (URL query):

    unit      Modbus unit (slave) id, 1..247 (default 1)
    timeout   reply budget of one exchange (both transactions) in seconds: the write may use all of it, the read
              what the write left, never less than 0.5 ms and never past the budget (default 0.008 for TCP; for
              RTU the line time of the exchange's 90 bytes + the rig's 2 ms per transaction, between 8 and 8.5 ms,
              so that an exchange given up at its budget leaves the board 1.5 ms of its 10 ms tick — a line too
              slow for a 10 ms tick, below 115200 baud, keeps 8 ms + twice its line time)
    handshake 1 (default) reads the rig's identity (holding 8-13) at open and refuses a mismatch; 0 skips it
    fc23      1 (default): one FC 23 per tick when the rig announces map version 2 at the handshake; 0: always
              FC 16 + FC 04
    baud, parity, stopbits   RTU line settings (default 115200, N, 1)
    reopen    consecutive timeouts after which the connection is closed and reopened (default 25)

One :meth:`ModbusLink.exchange` per tick is one FC 23 (write holding 0–7, read the sample mirror holding 100–121;
:mod:`drivers.modbus_fc23`) when the rig announced map version 2 at the handshake, else two transactions: FC 16
writes the command block (holding registers 0–7), FC 04 reads the sample block (input registers 0–21); the map is
:mod:`drivers.modbus_registers`.
On RTU the write waits at most half the budget for its acknowledgement; a lost or late acknowledgement is forgiven
when the sample shows the command applied (``cmd_seq_applied``); the sample read is tried twice within the budget, and
a sample showing an older command (the late reply to an earlier read: RTU has no transaction id) is read again once —
so a lost reply costs at most one exchange, mostly none, and every exchange ends within its budget (an exchange
that does not — the board's own process not running, a machine stall — is counted as ``over_budget`` and logged
with its transactions' times).
A command refused with exception 03 (outside the rig's limits) still returns the sample, with
``FLAG_LIMIT_REFUSED`` set, as the in-process link does; every other exception reply, a timeout, a reply of
the wrong kind or a lost connection is a ``LinkError``. A lost connection is reopened with a back-off counted
in exchange calls (1, 2, 4 … 64; :class:`~drivers.reconnecting_link.ReconnectingLink`). Incidents go to the
``drivers.modbus_link`` logger (the first three of a kind, then every 10th, 100th …) and are all counted in
:attr:`ModbusLink.stats`. pymodbus' own per-request error messages
are silenced unless the application has configured the ``pymodbus`` logger itself.

On a slow RTU line (19200 baud needs ~22 ms for this poll) one exchange does not fit a 10 ms tick: use
115200 baud or faster, or a Modbus TCP gateway.
"""

from __future__ import annotations

import contextlib
import logging
import select
import socket
import time
from collections import Counter
from typing import Any
from urllib.parse import urlsplit

from pymodbus.client import ModbusSerialClient, ModbusTcpClient
from pymodbus.exceptions import ConnectionException, ModbusException
from pymodbus.framer import FramerType
from pymodbus.framer.rtu import FramerRTU
from pymodbus.transaction import TransactionManager

from board_config.errors import InputError
from board_config.url_options import UrlOptions, split_url_query
from drivers.link import FLAG_LIMIT_REFUSED, ActuatorCommand, LinkError, RigSample
from drivers.modbus_fc23 import Fc23Unserved, exchange_fc23, fc23_announced
from drivers.modbus_registers import (
    BY_NAME,
    COMMAND_START,
    INPUT_COUNT,
    INPUT_START,
    SUPPORTED_MAP_VERSIONS,
    InputBlock,
    ModbusExceptionCode,
    decode_input_block,
    decode_value,
    encode_command_block,
)
from drivers.reconnecting_link import ReconnectingLink

log = logging.getLogger("drivers.modbus_link")
_KNOWN = {"tcp": {"unit", "timeout", "reopen", "handshake", "fc23"},
          "rtu": {"unit", "timeout", "reopen", "baud", "parity", "stopbits", "handshake", "fc23"}}
# RTU bytes on the line per exchange: FC16 request 1+1+2+2+1+16+2 = 25, its reply 8, FC04 request 8, its reply 49
_RTU_EXCHANGE_BYTES = 90
_TICK_S = 0.01  # the board's tick ([tick] rate = 100 Hz)
#: the board's own work in a tick besides the exchange (monitor, supervisor, records; ~0.3-0.7 ms measured, with a
#: margin for a loaded machine): an exchange given up at its budget still leaves the tick on time
_BOARD_RESERVE_S = 0.0015
_RTU_MAX_TIMEOUT_S = _TICK_S - _BOARD_RESERVE_S  # default RTU exchange budget never exceeds this: 8.5 ms
_RTU_RIG_BUDGET_S = 0.002  # the rig's documented processing budget per RTU transaction (docs/real-rig.md)
_RTU_MIN_RIG_S = 0.0005  # a line leaving the rig less than this (both transactions) does not fit a tick
_MIN_READ_S = 5e-4  # a read is not started with less than this left of the exchange budget
_RTU_RETRY_MIN_S = 1.5e-3  # RTU: the sample read is split into two attempts only if each gets at least this
#: an exchange that ends more than this after its budget is counted (``over_budget``) and logged with where its time
#: went: the budget is what keeps the board's tick, so an overrun needs explaining (a stalled process, a slow port)
_OVER_BUDGET_SLACK_S = 5e-4


class _RtuTransaction(TransactionManager):
    """pymodbus' sync transaction manager with an RTU receive that keeps to the exchange's deadline and the frame
    boundaries.

    pymodbus' own RTU receive takes the first frame that decodes and throws away whatever else arrived with it (its
    framer consumes the whole buffer), and restarts the full timeout on every partial read. On a line where a reply
    can come late, that turns one late reply into two failed exchanges: the late reply of the previous transaction
    and the real reply arrive in one read, the late one is taken (or skipped) and the real one is thrown away. Here
    the bytes are cut into frames by their own length (function code and byte count) and CRC; a frame for another
    unit or another function code (a late reply to an earlier request) is skipped and counted, and the parsing goes
    on with the bytes after it; every wait ends at the request's deadline (``timeout_connect`` from the send).
    """

    def __init__(self, *args: Any, stats: Counter[str], **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.stats = stats
        self._expected_fc = 0

    def pdu_send(self, pdu: Any, addr: tuple | None = None) -> None:
        self._expected_fc = int(pdu.function_code) & 0x7F
        super().pdu_send(pdu, addr)

    def _next_frame(self, buf: bytearray) -> tuple[int, bytes] | None:
        """(device id, PDU bytes) of the first whole frame with a good CRC in ``buf`` (consumed, with any garbage
        before it); ``None`` when ``buf`` holds only the start of a frame (kept) or nothing usable (cleared)."""
        decoder = self.framer.decoder
        while len(buf) >= 4:
            pdu_class = decoder.lookupPduClass(bytes(buf[:8]))
            size = pdu_class.calculateRtuFrameSize(bytes(buf)) if pdu_class is not None else 0
            if pdu_class is not None and not size:
                return None  # the byte count has not arrived yet
            if pdu_class is not None and len(buf) < size:
                return None  # the rest of the frame is on its way
            if pdu_class is not None and FramerRTU.check_CRC(bytes(buf[: size - 2]),
                                                             int.from_bytes(buf[size - 2: size], "big")):
                frame = bytes(buf[:size])
                del buf[:size]
                return frame[0], frame[1:-2]
            del buf[:1]  # not a frame start (garbage, a corrupted reply): hunt on
            self.stats["rtu_garbage_bytes"] += 1
        return None

    def sync_get_response(self, dev_id: int, tid: int) -> Any:
        client = self.sync_client
        sock = client.socket
        if sock is None:
            raise ConnectionException(str(client))
        deadline = time.monotonic() + self.comm_params.timeout_connect
        buf = bytearray()
        late = False
        while True:
            while (found := self._next_frame(buf)) is not None:
                unit, pdu_bytes = found
                pdu = self.framer.decoder.decode(pdu_bytes)
                if pdu is None or (dev_id and unit != dev_id) or (int(pdu.function_code) & 0x7F) != self._expected_fc:
                    self.stats["stale_skipped"] += 1  # a late reply to an earlier request (or another unit's)
                    continue
                if buf:
                    self.stats["flushed_reads"] += 1  # bytes after the reply: not ours, dropped like pymodbus does
                pdu.dev_id = unit
                pdu.transaction_id = tid
                return self.trace_pdu(False, pdu)
            left = deadline - time.monotonic()
            if left <= 0:
                # past the deadline only what is already here counts, taken once: a process that was not running
                # (a machine stall) may wake after its deadline with the reply waiting, which costs nothing to take
                if late:
                    raise TimeoutError()
                late = True
            try:
                ready = sock.in_waiting or (left > 0 and select.select([sock.fileno()], [], [], left)[0])
                data = sock.read(max(1, sock.in_waiting)) if ready else b""
            except (OSError, ValueError) as exc:
                client.close()
                raise ConnectionException(f"serial port lost: {exc}") from None
            if not data:
                raise TimeoutError()  # pymodbus' transaction manager: no (valid) reply within the timeout
            buf += self.trace_packet(False, data)


class _RtuClient(ModbusSerialClient):
    """pymodbus' sync RTU client with an event-driven receive that keeps to the exchange deadline and to frame
    boundaries (:class:`_RtuTransaction`).

    The stock ``recv(None)`` polls ``in_waiting`` with ``time.sleep`` and waits until the byte count stops
    growing (≥ 2 ms per reply, 4 ms per exchange). Here ``recv(None)`` blocks in ``select`` until bytes are
    there and returns them at once (used by pymodbus outside the transaction's receive).
    """

    def __init__(self, *args: Any, stats: Counter[str], **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        old = self.transaction
        self.transaction = _RtuTransaction(self.comm_params, self.framer, self.retries, False, old.trace_packet,
                                           old.trace_pdu, old.trace_connect, sync_client=self, stats=stats)

    def recv(self, size: int | None) -> bytes:
        sock = self.socket
        if size is not None or sock is None or not hasattr(sock, "fileno"):
            return super().recv(size)
        try:
            if not sock.in_waiting:
                ready, _, _ = select.select([sock.fileno()], [], [], self.comm_params.timeout_connect or 0)
                if not ready:
                    return b""
            return sock.read(max(1, sock.in_waiting))
        except (OSError, ValueError) as exc:
            self.close()
            raise ConnectionException(f"serial port lost: {exc}") from None


def parse_modbus_url(url: str) -> dict[str, Any]:
    """Parse a ``modbus-tcp://`` or ``modbus-rtu:`` URL into client settings; ``ValueError`` names the problem."""
    if url.startswith("modbus-tcp://"):
        kind = "tcp"
        parts = urlsplit(url.replace("modbus-tcp://", "tcp://", 1))
        if not parts.hostname:
            raise InputError(f"link URL '{url}': expected modbus-tcp://HOST:PORT")
        try:
            port = parts.port or 502
        except ValueError:
            raise InputError(f"link URL '{url}': bad port") from None
        target: dict[str, Any] = {"host": parts.hostname, "port": port}
        opts = UrlOptions.from_query(url, parts.query)
    elif url.startswith("modbus-rtu:"):
        kind = "rtu"
        path, _ = split_url_query(url.removeprefix("modbus-rtu:"))
        if not path:
            raise InputError(f"link URL '{url}': expected modbus-rtu:PATH (a serial device or pty)")
        target = {"port": path}
        opts = UrlOptions.of(url)
    else:
        raise InputError(f"link URL '{url}': not a modbus-tcp:// or modbus-rtu: URL")
    opts.check_known(_KNOWN[kind])
    settings: dict[str, Any] = {"kind": kind, **target,
                                   "unit": opts.integer("unit", 1, 1, 247),
                                   "reopen": opts.integer("reopen", 25, 1, 1e9),
                                   "handshake": opts.flag("handshake", True),
                                   "fc23": opts.flag("fc23", True)}
    if kind == "rtu":
        baud = opts.integer("baud", 115200, 300, 4_000_000)
        parity = opts.choice("parity", "N", ("N", "E", "O"))
        stopbits = opts.integer("stopbits", 1, 1, 2)
        wire = _RTU_EXCHANGE_BYTES * (1 + 8 + stopbits + (parity != "N")) / baud
        # the exchange must fit one 10 ms tick with the board's own work: the line time + the rig's budget of 2 ms
        # per transaction, at least 8 ms, at most 8.5 ms (a give-up then leaves the tick on time); a line too slow
        # for the tick at all (below 115200 baud) keeps 8 ms plus twice its line time and misses deadlines
        fits = wire + _RTU_MIN_RIG_S <= _RTU_MAX_TIMEOUT_S
        default = (max(0.008, min(wire + 2 * _RTU_RIG_BUDGET_S, _RTU_MAX_TIMEOUT_S)) if fits
                   else 0.008 + 2 * wire)
        settings.update(baud=baud, parity=parity, stopbits=stopbits, line_time=wire,
                        timeout=opts.number("timeout", default, 1e-4, 60.0))
    else:
        settings["timeout"] = opts.number("timeout", 0.008, 1e-4, 60.0)
        settings["line_time"] = 0.0
    return settings


class RigMismatchError(LinkError):
    """The peer answers but is not a rig this board can drive (another map version, word order, limits or tick)."""


_ID_START = 8  # holding map_version .. v_limit_max
_ID_COUNT = 6
_OPEN_BUDGET_S = 0.5  # reply budget of the start-up reads (the tick deadline does not apply yet)


def rig_identity_problem(words: list[int], tick: float = 0.01) -> str:
    """Why the rig whose holding registers 8–13 are ``words`` cannot be driven ('' if it can). Pure.

    Checks the map version, the rig's tick and the Table 1 limits, and tells a wrong float word order (CDAB) by
    the limits decoding correctly only with the words swapped.
    """
    from board_config import load_mfc_limits

    limits = load_mfc_limits()
    version = words[0]
    if version not in SUPPORTED_MAP_VERSIONS:
        return (f"map_version is {version}, this board speaks register map versions "
                f"{', '.join(map(str, SUPPORTED_MAP_VERSIONS))}")
    lo = decode_value(BY_NAME["v_limit_min"], words[2:4])
    hi = decode_value(BY_NAME["v_limit_max"], words[4:6])
    if (lo, hi) != (limits.voltage_min, limits.voltage_max):
        swapped = (decode_value(BY_NAME["v_limit_min"], [words[3], words[2]]),
                   decode_value(BY_NAME["v_limit_max"], [words[5], words[4]]))
        if swapped == (limits.voltage_min, limits.voltage_max):
            return ("float word order is low word first (CDAB); the map needs the high word first (ABCD): "
                    f"v_limit_min reads {lo:g} V instead of {limits.voltage_min:g} V")
        return (f"its channel limits are [{lo:g}, {hi:g}] V, the board's Table 1 limits are "
                f"[{limits.voltage_min:g}, {limits.voltage_max:g}] V")
    rig_tick = decode_value(BY_NAME["rig_tick"], words[1:2])
    if abs(rig_tick - tick) > 0.5e-4:
        return f"rig_tick is {1e3 * rig_tick:g} ms, the board ticks every {1e3 * tick:g} ms"
    return ""


class ModbusLink(ReconnectingLink):
    """The board side over Modbus TCP or RTU (see the module docstring)."""

    verb = "reconnect"
    reconnected_note = "reconnected"

    def __init__(self, url: str) -> None:
        self.settings = parse_modbus_url(url)
        super().__init__(url, log, timeout=float(self.settings["timeout"]), reopen_after=int(self.settings["reopen"]))
        pm = logging.getLogger("pymodbus")
        if pm.level == logging.NOTSET:  # pymodbus logs every timeout itself; this link logs them rate-limited
            pm.setLevel(logging.CRITICAL)
        self.unit = int(self.settings["unit"])
        #: one FC 23 per tick (the rig announced map version 2 at the handshake; ``fc23=0`` in the URL: never)
        self.fc23 = False
        self.line_time = float(self.settings["line_time"])
        self.last_transaction_s = 0.0
        #: the transactions of the last exchange: (what, start after the exchange's start, duration, budget), s
        self.last_phases: list[tuple[str, float, float, float]] = []
        self._exchange_t0 = 0.0
        self._check_due = False
        self._client: Any = None  # the pymodbus client, made at the first open and kept across reconnects
        self._down = True
        self.last_exception_code: int | None = None
        self.map_version = 0  #: the map version the rig announced at the handshake (0: not read)

    @property
    def processing_budget(self) -> float:
        """Request-to-reply time one transaction may take (s): the whole exchange budget with FC 23 (one transaction
        per tick), half of it with FC 16 + FC 04."""
        return self.timeout if self.fc23 else self.timeout / 2

    # ------------------------------------------------------------------------------------------ lifecycle
    def _make_client(self):
        s = self.settings
        if s["kind"] == "tcp":
            return ModbusTcpClient(str(s["host"]), port=int(s["port"]), timeout=self.timeout,
                                   retries=0, name="shm-board")
        return _RtuClient(str(s["port"]), framer=FramerType.RTU, baudrate=int(s["baud"]),
                                  parity=str(s["parity"]), stopbits=int(s["stopbits"]),
                                  bytesize=8, timeout=self.timeout, retries=0, name="shm-board", stats=self.stats)

    def open(self) -> None:
        """Connect, check the rig (unless ``handshake=0``: map version, tick, Table 1 limits, float word order) and
        read the sample block once. Raises ``LinkError`` (:class:`RigMismatchError` for a rig serving another map)."""
        self._bring_up()
        with self._silenced():  # one error below, not a warning per attempt
            try:
                if self.settings["handshake"]:
                    self.check_rig()
                self._read_inputs(budget=max(self.timeout, _OPEN_BUDGET_S))
            except LinkError:
                self.close()
                raise

    def check_rig(self, attempts: int = 3, budget: float | None = None) -> None:
        """Read the rig's identity block (holding 8–13) and refuse a rig this board cannot drive."""
        budget = max(self.timeout, _OPEN_BUDGET_S) if budget is None else budget
        last: LinkError | None = None
        for _ in range(attempts):  # a slow peer at start-up gets three chances
            try:
                rr = self._call("read the rig's identity (FC03, holding 8-13)", self._client.read_holding_registers,
                                _ID_START, count=_ID_COUNT, budget=budget)
                break
            except LinkError as exc:
                last = exc
                if self._down:
                    raise
        else:
            assert last is not None
            raise LinkError(f"{self.url}: the rig does not answer at start-up (3 attempts of {1e3 * budget:.0f} ms; "
                            f"is it a Modbus server serving docs/registers.md as unit {self.unit}? last: "
                            f"{str(last).removeprefix(self.url + ': ')})")
        if rr.isError() or getattr(rr, "registers", None) is None or len(rr.registers) != _ID_COUNT:
            raise RigMismatchError(f"{self.url}: the rig refused to read holding registers 8-13 (map_version, "
                                   f"rig_tick, v_limit_min, v_limit_max; docs/registers.md): "
                                   f"{getattr(rr, 'exception_code', rr)}")
        problem = rig_identity_problem(list(rr.registers))
        if problem:
            raise RigMismatchError(f"{self.url}: rig refused: {problem} (docs/registers.md)")
        self.fc23 = bool(self.settings["fc23"]) and fc23_announced(list(rr.registers))
        self.map_version = int(rr.registers[0])  # the version the rig announced (1 or 2)

    def close(self) -> None:
        client, self._client = self._client, None
        self._down = True
        if client is not None:
            try:
                client.close()
            except Exception:
                pass

    @property
    def is_open(self) -> bool:
        return not self._down

    def _open_transport(self) -> None:
        if self._client is None:
            self._client = self._make_client()
        self._set_timeout(self.timeout)  # the connect's own budget, whatever the last transaction left there
        try:
            ok = self._client.connect()
        except Exception as exc:
            ok = False
            log.debug("%s: connect raised %r", self.url, exc)
        if not ok:
            self._client.close()
            raise LinkError(f"{self.url}: cannot connect")
        sock = getattr(self._client, "socket", None)
        if isinstance(sock, socket.socket):
            # no Nagle: after a lost reply the next request would otherwise wait for the server's delayed ACK
            # (up to 40 ms), turning one lost reply into five failed exchanges
            with contextlib.suppress(OSError):
                sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self._down = False

    def _drop_transport(self) -> None:
        if self._client is not None:  # the client object stays: it reconnects
            try:
                self._client.close()
            except Exception:
                pass
        self._down = True

    def _after_reconnect(self) -> None:
        self._check_due = bool(self.settings["handshake"])  # the server behind the port may have changed

    # ------------------------------------------------------------------------------------------ exchange
    def _set_timeout(self, seconds: float) -> None:
        # pymodbus 3.16 reads the reply timeout from two copies of its settings (client and transaction manager).
        # Never below 0.1 ms: a budget computed as "what is left" is negative when the process was descheduled past
        # its deadline, and pymodbus then reports a negative select() timeout as "connection unexpectedly closed"
        # and cannot connect again (its connect uses the same setting) — a lost link for the rest of the run
        seconds = max(float(seconds), 1e-4)
        c = self._client
        c.comm_params.timeout_connect = seconds
        c.transaction.comm_params.timeout_connect = seconds

    def _phase(self, what: str, t0: float, budget: float) -> None:
        """Note one step of the exchange in :attr:`last_phases`: started at ``t0`` (monotonic s), ended now."""
        self.last_phases.append((what, t0 - self._exchange_t0, time.monotonic() - t0, budget))

    def _call(self, what: str, fn, *args, budget: float | None = None, context: str = "", **kwargs):
        budget = self.timeout if budget is None else budget
        self._set_timeout(budget)
        t0 = time.monotonic()
        try:
            rr = fn(*args, device_id=self.unit, **kwargs)
        except ConnectionException as exc:
            raise self._link_down(f"{what}: connection lost ({exc})") from exc
        except ModbusException as exc:  # ModbusIOException: no (valid) reply within the timeout
            raise self._timed_out(f"{what}: no valid reply within {1e3 * budget:.1f} ms{context}") from exc
        except (OSError, ValueError) as exc:  # serial port vanished under pyserial, etc.
            raise self._link_down(f"{what}: {exc}") from exc
        finally:
            self._phase(what, t0, budget)
        if rr is None:
            raise LinkError(f"{self.url}: {what}: no reply")
        self._timeouts_in_row = 0
        took = time.monotonic() - t0
        self.last_transaction_s = took
        if took > self.processing_budget:
            self.stats["slow_replies"] += 1
            self._log.warn("slow_reply", "%s: %s answered in %.1f ms, over the rig's processing budget of %.1f ms "
                           "per transaction (docs/real-rig.md): the rig is too slow for this tick", self.url, what,
                           1e3 * took, 1e3 * self.processing_budget)
        return rr

    def _flush_input(self) -> None:
        """Discard whatever is waiting on the line or socket (the late or broken remains of an earlier reply)."""
        sock = getattr(self._client, "socket", None)
        try:
            if isinstance(sock, socket.socket):
                sock.setblocking(False)
                while sock.recv(4096):
                    self.stats["flushed_reads"] += 1
            elif sock is not None and hasattr(sock, "reset_input_buffer"):
                if sock.in_waiting:
                    self.stats["flushed_reads"] += 1
                sock.reset_input_buffer()
        except (BlockingIOError, InterruptedError):
            pass
        except (OSError, ValueError):  # a vanished port: the next transaction reports it
            pass

    def _skip_stale(self, rr, function_code: int, deadline: float):
        """A reply that arrived after its timeout can be taken for the next request's (RTU has no transaction id;
        pymodbus' TCP client does not always check it). Skip
        such a stale reply (the other function code of the exchange) and wait for the real one while the exchange
        budget lasts, so a late reply costs one exchange, not a cascade."""
        if rr.isError() or rr.function_code == function_code:
            return rr
        transaction = self._client.transaction
        tid = getattr(transaction, "request_transaction_id", 0) or 0
        while rr.function_code != function_code and not rr.isError():
            self.stats["stale_skipped"] += 1
            left = deadline - time.monotonic()
            if left <= 0:
                return rr
            self._set_timeout(left)
            t0 = time.monotonic()
            try:
                rr = transaction.sync_get_response(self.unit, tid)
            except Exception:  # asyncio.TimeoutError: nothing more within the budget
                return rr
            finally:
                self._phase(f"past a stale reply, wait for FC{function_code:02d}", t0, left)
        return rr

    def _read_inputs(self, budget: float | None = None, context: str = "", deadline: float | None = None):
        rr = self._call("read sample (FC04)", self._client.read_input_registers, INPUT_START, count=INPUT_COUNT,
                        budget=budget, context=context)
        if deadline is not None:
            rr = self._skip_stale(rr, 0x04, deadline)
        if rr.isError():
            self.stats["exception_replies"] += 1
            code = getattr(rr, "exception_code", None)
            self.last_exception_code = code
            self._log.warn("exception_reply", "%s: sample read refused with exception %s", self.url, code)
            raise LinkError(f"{self.url}: sample read refused with Modbus exception {code}")
        regs = getattr(rr, "registers", None)
        if rr.function_code != 0x04 or regs is None or len(regs) != INPUT_COUNT:
            self.stats["bad_reply"] += 1
            raise LinkError(f"{self.url}: unexpected reply to the sample read (function {rr.function_code}, "
                            f"{0 if regs is None else len(regs)} registers)")
        return decode_input_block(regs)

    def exchange(self, command: ActuatorCommand) -> RigSample:
        """Write ``command``, read the sample. Raises ``LinkError`` on any failure (see the module docstring).

        An exchange that ends more than 0.5 ms past its budget is counted (``stats["over_budget"]``) and logged with
        its transactions (:attr:`last_phases`): when did each start, what did it take, what was it given."""
        self._exchange_t0 = t0 = time.monotonic()
        self.last_phases = []
        try:
            return self._exchange(command)
        finally:
            took = time.monotonic() - t0
            if took > self.timeout + _OVER_BUDGET_SLACK_S:
                self.stats["over_budget"] += 1
                phases = "; ".join(f"{what} at {1e3 * start:.2f} ms took {1e3 * dur:.2f} of {1e3 * budget:.2f} ms"
                                   for what, start, dur, budget in self.last_phases)
                self._log.warn("over_budget", "%s: exchange took %.2f ms, over its %.2f ms budget: %s", self.url,
                               1e3 * took, 1e3 * self.timeout, phases or "no transaction (reconnect)")

    def _exchange(self, command: ActuatorCommand) -> RigSample:
        self._ensure_up()
        try:
            words = encode_command_block(command)
        except ValueError as exc:
            self.stats["bad_command"] += 1
            raise LinkError(f"{self.url}: command not sendable: {exc}") from exc
        self.stats["requests"] += 1
        if self._timeouts_in_row:  # the reply that timed out may still arrive: drop its bytes, not the next reply
            t0 = time.monotonic()
            self._flush_input()
            self._phase("flush input", t0, 0.0)
        deadline = time.monotonic() + self.timeout  # one budget for both transactions
        # RTU: the write waits for its acknowledgement at most its share of the budget (half); a lost (or late)
        # acknowledgement is not the end of the exchange — the sample read follows, and its cmd_seq_applied tells
        # whether the command was applied (a late acknowledgement is skipped by its function code)
        rtu = self.settings["kind"] == "rtu"
        if self.fc23:  # map version 2: one transaction per tick (drivers.modbus_fc23)
            try:
                block, refused = exchange_fc23(self, words, command.seq, deadline)
                return self._finish(command, block, refused)
            except Fc23Unserved as exc:
                self.fc23 = False
                self.stats["fc23_fallback"] += 1
                self._log.warn("fc23_fallback", "%s", exc)
                if deadline - time.monotonic() < 2 * _MIN_READ_S:
                    raise LinkError(f"{exc}; no time left in this tick") from None
        ack_lost = False
        try:
            rr = self._call("write command (FC16)", self._client.write_registers, COMMAND_START, words,
                            budget=self.processing_budget if rtu else None)
        except LinkError:
            if not rtu or self._down:
                raise
            ack_lost = True
            rr = None
        if rr is not None:
            rr = self._skip_stale(rr, 0x10, deadline)
        refused = False
        if rr is None:
            pass
        elif rr.isError():
            code = getattr(rr, "exception_code", None)
            self.last_exception_code = code
            self.stats["exception_replies"] += 1
            if code == ModbusExceptionCode.ILLEGAL_VALUE:
                refused = True
                self.stats["refused"] += 1
                self._log.warn("refused", "%s: rig refused command seq %d (v_ch1=%g V, v_ch2=%g V): exception 03",
                               self.url, command.seq, command.v_ch1, command.v_ch2)
            else:
                self._log.warn("exception_reply", "%s: command write refused with exception %s", self.url, code)
                raise LinkError(f"{self.url}: command write refused with Modbus exception {code}")
        elif rr.function_code != 0x10:
            self.stats["bad_reply"] += 1
            raise LinkError(f"{self.url}: unexpected reply to the command write (function {rr.function_code})")
        left = deadline - time.monotonic()
        spent = self.timeout - left
        context = f" (the command write took {1e3 * spent:.1f} ms of the {1e3 * self.timeout:.1f} ms exchange budget)"
        if left < _MIN_READ_S:  # never stretch the exchange past its budget: the tick must not collapse
            self.stats["timeouts"] += 1
            self._log.warn("no_time_for_read", "%s: no time left to read the sample%s", self.url, context)
            raise LinkError(f"{self.url}: no time left to read the sample{context}; the rig answers slower than "
                            f"its processing budget of {1e3 * self.processing_budget:.1f} ms per transaction")
        if rtu and left >= 2 * _RTU_RETRY_MIN_S:
            # RTU: a read has no side effect — one retry within the budget when its reply is lost or late (a late
            # reply to the first request is taken if it comes during the retry: the same request, the same sample)
            try:
                block = self._read_inputs(budget=left / 2, context=context, deadline=deadline)
            except LinkError:
                if self._down:
                    raise
                self.stats["read_retries"] += 1
                block = self._read_inputs(budget=max(deadline - time.monotonic(), _MIN_READ_S), context=context,
                                          deadline=deadline)
        else:
            block = self._read_inputs(budget=left, context=context, deadline=deadline)
        if (rtu and not refused and not ack_lost and block.cmd_seq_applied != command.seq & 0xFFFFFFFF
                and deadline - time.monotonic() >= _MIN_READ_S):
            # RTU has no transaction id: a sample that does not show the acknowledged command applied is the late
            # reply to an earlier read (a tick old); read once more within the budget
            self.stats["stale_sample_skipped"] += 1
            with contextlib.suppress(LinkError):
                block = self._read_inputs(budget=deadline - time.monotonic(), context=context, deadline=deadline)
        if ack_lost:
            if block.cmd_seq_applied != command.seq & 0xFFFFFFFF:
                raise LinkError(f"{self.url}: the command write was not acknowledged and the rig reports command seq "
                                f"{block.cmd_seq_applied} applied, not {command.seq}{context}")
            self.stats["ack_lost_but_applied"] += 1  # the sample shows the command applied: the exchange stands
        return self._finish(command, block, refused)

    def _finish(self, command: ActuatorCommand, block: InputBlock, refused: bool) -> RigSample:
        """The sample of an answered exchange (after a reconnect: then the identity check)."""
        self.stats["replies"] += 1
        sample = block.sample
        if self._check_due:  # after a reconnect: the first good exchange is followed by the identity check
            try:
                self.check_rig(attempts=1, budget=self.timeout)
                self._check_due = False
                self.stats["identity_after_reconnect"] += 1
            except RigMismatchError:
                self.close()
                raise
            except LinkError:
                self.stats["identity_after_reconnect_failed"] += 1  # tried again after the next exchange
        if refused:
            sample = RigSample(seq=sample.seq, t=sample.t, z3=sample.z3, v_patch=sample.v_patch, z0dd=sample.z0dd,
                               v_battery=sample.v_battery, hv_present=sample.hv_present,
                               flags=sample.flags | FLAG_LIMIT_REFUSED)
        elif block.cmd_seq_applied != command.seq & 0xFFFFFFFF:
            self.stats["seq_mismatch"] += 1
            self._log.warn("seq_mismatch", "%s: rig reports command seq %d applied, sent %d (another master?)",
                           self.url, block.cmd_seq_applied, command.seq)
        return sample
