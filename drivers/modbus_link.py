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
import socket
import time
from collections.abc import Callable
from typing import Any

from pymodbus.client import ModbusTcpClient
from pymodbus.exceptions import ConnectionException, ModbusException
from pymodbus.framer import FramerType

from drivers.link import FLAG_LIMIT_REFUSED, ActuatorCommand, LinkError, RigSample
from drivers.modbus_fc23 import Fc23Exchange, Fc23Unserved, exchange_fc23, fc23_announced
from drivers.modbus_identity import ID_COUNT, ID_START, RigMismatchError, rig_identity_problem
from drivers.modbus_registers import (
    COMMAND_START,
    INPUT_COUNT,
    INPUT_START,
    MIRROR_START,
    InputBlock,
    ModbusExceptionCode,
    decode_input_block,
    encode_command_block,
)
from drivers.modbus_rtu_client import RtuClient
from drivers.modbus_url import parse_modbus_url
from drivers.reconnecting_link import ReconnectingLink

log = logging.getLogger("drivers.modbus_link")
_MIN_READ_S = 5e-4  # a read is not started with less than this left of the exchange budget
_RTU_RETRY_MIN_S = 1.5e-3  # RTU: the sample read is split into two attempts only if each gets at least this
#: an exchange that ends more than this after its budget is counted (``over_budget``) and logged with where its time
#: went: the budget is what keeps the board's tick, so an overrun needs explaining (a stalled process, a slow port)
_OVER_BUDGET_SLACK_S = 5e-4
_OPEN_BUDGET_S = 0.5  # reply budget of the start-up reads (the tick deadline does not apply yet)
#: what this module offers besides the link (parsed URLs and the identity check live in their own modules)
__all__ = ["ModbusLink", "RigMismatchError", "parse_modbus_url", "rig_identity_problem"]


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
    def _make_client(self) -> ModbusTcpClient | RtuClient:
        s = self.settings
        if s["kind"] == "tcp":
            return ModbusTcpClient(str(s["host"]), port=int(s["port"]), timeout=self.timeout,
                                   retries=0, name="shm-board")
        return RtuClient(str(s["port"]), framer=FramerType.RTU, baudrate=int(s["baud"]), parity=str(s["parity"]),
                         stopbits=int(s["stopbits"]), bytesize=8, timeout=self.timeout, retries=0, name="shm-board",
                         stats=self.stats)

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
                                ID_START, count=ID_COUNT, budget=budget)
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
        if rr.isError() or getattr(rr, "registers", None) is None or len(rr.registers) != ID_COUNT:
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

    def _call(self, what: str, fn: Callable[..., Any], *args: Any, budget: float | None = None, context: str = "",
              **kwargs: Any) -> Any:
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

    def _skip_stale(self, rr: Any, function_code: int, deadline: float) -> Any:
        """A reply that arrived after its timeout can be taken for the next request's (RTU has no transaction id;
        pymodbus' TCP client does not always check it). Skip
        such a stale reply (the other function code of the exchange) and wait for the real one while the exchange
        budget lasts, so a late reply costs one exchange, not a cascade."""
        while rr.function_code != function_code and not rr.isError():
            self.stats["stale_skipped"] += 1
            later = self._next_reply(deadline, f"past a stale reply, wait for FC{function_code:02d}")
            if later is None:
                return rr
            rr = later
        return rr

    def _next_reply(self, deadline: float, what: str = "past a stale reply, wait for FC23") -> Any:
        """The next reply on the connection before ``deadline`` (monotonic s); None when nothing came in time."""
        left = deadline - time.monotonic()
        if left <= 0:
            return None
        transaction = self._client.transaction
        tid = getattr(transaction, "request_transaction_id", 0) or 0
        self._set_timeout(left)
        t0 = time.monotonic()
        try:
            return transaction.sync_get_response(self.unit, tid)
        except Exception:  # asyncio.TimeoutError: nothing more within the budget
            return None
        finally:
            self._phase(what, t0, left)

    def _read_inputs(self, budget: float | None = None, context: str = "",
                     deadline: float | None = None) -> InputBlock:
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
        """One exchange as named stages: the request (words, stale input dropped), one FC 23 where the rig serves
        it, else the command write (FC 16) and the sample read (FC 04) within one budget for both."""
        words = self._begin_exchange(command)
        deadline = time.monotonic() + self.timeout  # one budget for both transactions
        if self.fc23:  # map version 2: one transaction per tick (drivers.modbus_fc23)
            sample = self._try_fc23(command, words, deadline)
            if sample is not None:
                return sample
        # RTU: the write waits for its acknowledgement at most its share of the budget (half); a lost (or late)
        # acknowledgement is not the end of the exchange — the sample read follows, and its cmd_seq_applied tells
        # whether the command was applied (a late acknowledgement is skipped by its function code)
        rtu = self.settings["kind"] == "rtu"
        refused, ack_lost = self._write_command(command, words, rtu, deadline)
        context = self._time_for_read(deadline)
        block = self._read_sample(command, rtu, refused or ack_lost, deadline, context)
        if ack_lost:
            if block.cmd_seq_applied != command.seq & 0xFFFFFFFF:
                raise LinkError(f"{self.url}: the command write was not acknowledged and the rig reports command seq "
                                f"{block.cmd_seq_applied} applied, not {command.seq}{context}")
            self.stats["ack_lost_but_applied"] += 1  # the sample shows the command applied: the exchange stands
        return self._finish(command, block, refused)

    def _begin_exchange(self, command: ActuatorCommand) -> list[int]:
        """The link up, the command's register words, and the remains of a timed-out reply dropped."""
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
        return words

    def fc23_exchange(self) -> Fc23Exchange:
        """What :func:`drivers.modbus_fc23.exchange_fc23` may use of this link, its operations bound here."""
        return Fc23Exchange(self.url, self.settings["kind"] == "rtu", self.timeout, self.stats, self._log,
                            self._send_fc23, lambda: self._down, self._skip_stale, self._next_reply,
                            lambda budget, deadline: self._read_inputs(budget=budget, deadline=deadline),
                            self._keep_exception_code)

    def _send_fc23(self, words: list[int], budget: float) -> Any:
        return self._call("write command, read sample (FC23)", self._client.readwrite_registers,
                          read_address=MIRROR_START, read_count=INPUT_COUNT, write_address=COMMAND_START,
                          values=words, budget=budget)

    def _keep_exception_code(self, code: int | None) -> None:
        self.last_exception_code = code

    def _try_fc23(self, command: ActuatorCommand, words: list[int], deadline: float) -> RigSample | None:
        """The exchange as one FC 23; None when the rig turns out not to serve it (then FC 16 + FC 04 from now on)."""
        try:
            block, refused = exchange_fc23(self, words, command.seq, deadline)
            return self._finish(command, block, refused)
        except Fc23Unserved as exc:
            self.fc23 = False
            self.stats["fc23_fallback"] += 1
            self._log.warn("fc23_fallback", "%s", exc)
            if deadline - time.monotonic() < 2 * _MIN_READ_S:
                raise LinkError(f"{exc}; no time left in this tick") from None
        return None

    def _write_command(self, command: ActuatorCommand, words: list[int], rtu: bool,
                       deadline: float) -> tuple[bool, bool]:
        """FC 16 with the command block: (refused with exception 03, acknowledgement lost on RTU)."""
        try:
            rr = self._call("write command (FC16)", self._client.write_registers, COMMAND_START, words,
                            budget=self.processing_budget if rtu else None)
        except LinkError:
            if not rtu or self._down:
                raise
            return False, True
        rr = self._skip_stale(rr, 0x10, deadline)
        if rr.isError():
            code = getattr(rr, "exception_code", None)
            self.last_exception_code = code
            self.stats["exception_replies"] += 1
            if code != ModbusExceptionCode.ILLEGAL_VALUE:
                self._log.warn("exception_reply", "%s: command write refused with exception %s", self.url, code)
                raise LinkError(f"{self.url}: command write refused with Modbus exception {code}")
            self.stats["refused"] += 1
            self._log.warn("refused", "%s: rig refused command seq %d (v_ch1=%g V, v_ch2=%g V): exception 03",
                           self.url, command.seq, command.v_ch1, command.v_ch2)
            return True, False
        if rr.function_code != 0x10:
            self.stats["bad_reply"] += 1
            raise LinkError(f"{self.url}: unexpected reply to the command write (function {rr.function_code})")
        return False, False

    def _time_for_read(self, deadline: float) -> str:
        """What the write left of the budget, said for the messages; ``LinkError`` when no read fits any more."""
        left = deadline - time.monotonic()
        spent = self.timeout - left
        context = f" (the command write took {1e3 * spent:.1f} ms of the {1e3 * self.timeout:.1f} ms exchange budget)"
        if left < _MIN_READ_S:  # never stretch the exchange past its budget: the tick must not collapse
            self.stats["timeouts"] += 1
            self._log.warn("no_time_for_read", "%s: no time left to read the sample%s", self.url, context)
            raise LinkError(f"{self.url}: no time left to read the sample{context}; the rig answers slower than "
                            f"its processing budget of {1e3 * self.processing_budget:.1f} ms per transaction")
        return context

    def _read_sample(self, command: ActuatorCommand, rtu: bool, unchecked: bool, deadline: float,
                     context: str) -> InputBlock:
        """FC 04 within the budget; on RTU one retry of a lost read and one more read of a sample a tick old
        (``unchecked``: the command was refused or its acknowledgement lost, so its seq says nothing)."""
        left = deadline - time.monotonic()
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
        if (rtu and not unchecked and block.cmd_seq_applied != command.seq & 0xFFFFFFFF
                and deadline - time.monotonic() >= _MIN_READ_S):
            # RTU has no transaction id: a sample that does not show the acknowledged command applied is the late
            # reply to an earlier read (a tick old); read once more within the budget
            self.stats["stale_sample_skipped"] += 1
            with contextlib.suppress(LinkError):
                block = self._read_inputs(budget=deadline - time.monotonic(), context=context, deadline=deadline)
        return block

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
