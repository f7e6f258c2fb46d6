"""The stub's hot Modbus path: FC 03, 04, 16 and 23 (over TCP and RTU) answered in the connection's data callback,
straight from the register tables pymodbus' server holds (issue 29, point 2).

Why hand-written (measured, docs/real-rig.md "The stub's answer time"): pymodbus 3.16 answers a request in steps —
framer, request PDU object, ``call_soon`` for the handler, a task for ``handle_request``, the ``SimCore`` /
``SimRuntime`` awaits, a response PDU object, the framer again — so every request costs two more turns of the event
loop and some hundred microseconds of Python; under a CPU hog per core each extra turn is a chance to lose the CPU.
Here the request is parsed from its MBAP header (TCP) or taken as the one whole frame with a good CRC (RTU), checked
and answered before the data callback returns: one wake-up, no task, no PDU objects. pymodbus stays the Modbus library
of the links and of every other function code and malformed, partial or foreign frame: the tables are pymodbus' own
(the same lists, the same address / read-only checks of ``SimRuntime``), and the same ``action`` hook of
:class:`hil_stub.modbus_server.ModbusRigServer` runs for every access, so the register map, exception codes, fault
injection and statistics are those of the pymodbus path. What may wait (a ``--processing-ms`` / ``--latency-ms``
delay, building a fresh lockstep rig) is left to pymodbus: the hook never awaits on this path.

The frame helpers are pure (bytes in, bytes or offsets out).
"""

from __future__ import annotations

import struct
from collections.abc import Awaitable, Callable, Coroutine
from typing import Any, NamedTuple

from pymodbus.framer.rtu import FramerRTU

from drivers.modbus_registers import (
    COMMAND_END,
    COMMAND_START,
    HOLDING_COUNT,
    HOLDING_START,
    ModbusExceptionCode,
    decode_command_block,
)

#: the function codes answered here (a board's exchange: FC 23, or FC 16 + FC 04; FC 03 reads the holding block)
HOT_FUNCTIONS = frozenset({3, 4, 16, 23})
_HEADER = struct.Struct(">HHHBB")  # transaction id, protocol id, length, unit id, function code
_READ = struct.Struct(">HH")  # FC 03/04: address, quantity (after the function code)
_WRITE = struct.Struct(">HHB")  # FC 16: address, quantity, byte count
_READ_WRITE = struct.Struct(">HHHHB")  # FC 23: read address, read quantity, write address, write quantity, bytes
_FLAG_TYPE = 2**4 - 1  # pymodbus.simulator.simutils.SimUtils.RunTimeFlag_TYPE
_FLAG_INVALID = 1  # DataType.INVALID
_FLAG_READONLY = 2**4  # SimUtils.RunTimeFlag_READONLY
ILLEGAL_ADDRESS = ModbusExceptionCode.ILLEGAL_ADDRESS
DEVICE_FAILURE = ModbusExceptionCode.DEVICE_FAILURE

#: one pymodbus ``SimRuntime`` block: (first address, register count, the registers, their flags)
Block = tuple[int, int, list[int], list[int]]
#: the server's action hook: (function code, block start, address, count, the block's registers, values written or
#: None) -> a Modbus exception code (truthy) or None
Action = Callable[[int, int, int, int, list[int], Any], Awaitable[Any]]


class Request(NamedTuple):
    """Where one complete request frame's parts are."""

    tid: int | None  #: the MBAP transaction id (echoed); None on RTU
    unit: int  #: unit id (echoed)
    fc: int  #: function code
    pdu_start: int  #: the PDU (function code + data) is ``data[pdu_start:pdu_end]``
    pdu_end: int
    end: int  #: the frame's length in bytes


def parse_mbap(data: bytes) -> Request | None:
    """The first MBAP frame of ``data`` if it is complete and well formed (protocol id 0, length 2..254), else None
    (a partial frame waits for more bytes; a malformed one is pymodbus' to handle). Pure."""
    if len(data) < 8:
        return None
    tid, pid, length, unit, fc = _HEADER.unpack_from(data)
    if pid != 0 or not 2 <= length <= 254 or len(data) < 6 + length:
        return None
    return Request(tid, unit, fc, 7, 6 + length, 6 + length)


def parse_rtu(data: bytes) -> Request | None:
    """``data`` as one whole Modbus RTU frame (unit id, PDU, CRC low byte first) if its CRC is good, else None (a
    partial frame, several frames or line noise: pymodbus' framer hunts through them). Pure."""
    if len(data) < 4 or FramerRTU.compute_CRC(data[:-2]) != int.from_bytes(data[-2:], "big"):
        return None
    return Request(None, data[0], data[1], 1, len(data) - 2, len(data))


def frame_starts(data: bytes) -> list[int]:
    """The start offsets of the complete, well-formed MBAP frames at the head of ``data``, in order. Pure."""
    starts: list[int] = []
    off = 0
    while (req := parse_mbap(data[off:off + 261])) is not None:
        starts.append(off)
        off += req.end
    return starts


def exception_pdu(fc: int, code: int) -> bytes:
    """An exception reply: the function code with its high bit set, then the exception code. Pure."""
    return bytes(((fc | 0x80) & 0xFF, code))


def registers_pdu(fc: int, registers: list[int]) -> bytes:
    """A reply carrying registers (FC 03, 04, 23): byte count, then the 16-bit words. Pure."""
    n = len(registers)
    return struct.pack(f">BB{n}H", fc, 2 * n, *registers)


def write_pdu(address: int, count: int) -> bytes:
    """The reply to FC 16: the address and quantity written. Pure."""
    return struct.pack(">BHH", 16, address, count)


def mbap_adu(tid: int, unit: int, pdu: bytes) -> bytes:
    """A Modbus TCP frame: MBAP header (transaction id, protocol 0, length, unit id), then the PDU. Pure."""
    return struct.pack(">HHHB", tid, 0, len(pdu) + 1, unit) + pdu


def rtu_adu(unit: int, pdu: bytes) -> bytes:
    """A Modbus RTU frame: unit id, PDU, CRC (low byte first). Pure."""
    frame = bytes((unit,)) + pdu
    return frame + FramerRTU.compute_CRC(frame).to_bytes(2, "big")


def reply_adu(req: Request, pdu: bytes) -> bytes:
    """The reply frame to ``req`` carrying ``pdu`` (its transaction id and unit id echoed). Pure."""
    return rtu_adu(req.unit, pdu) if req.tid is None else mbap_adu(req.tid, req.unit, pdu)


def run_now(coro: Coroutine[Any, Any, Any]) -> Any:
    """The result of a coroutine that finishes without suspending (``RuntimeError`` if it would suspend)."""
    try:
        coro.send(None)
    except StopIteration as done:
        return done.value
    coro.close()
    raise RuntimeError("the Modbus action hook awaited on the hot path")


class RegisterTables:
    """The holding (``h``: command, limits, sample mirror) and input (``i``) register blocks of pymodbus' server,
    read and written with the checks of ``SimRuntime.get_reg_block`` and the server's action hook, synchronously."""

    def __init__(self, holding: Block, inputs: Block, action: Action) -> None:
        self.holding = holding
        self.inputs = inputs
        self.action = action

    @classmethod
    def of_server(cls, server: Any, action: Action) -> RegisterTables | None:
        """The tables of a started pymodbus server built from one ``SimDevice`` (None: not laid out as pymodbus 3.16
        does; then everything goes through pymodbus)."""
        devices = getattr(getattr(server, "context", None), "devices", None)
        blocks = getattr(devices.get(0), "block", None) if isinstance(devices, dict) else None
        if not isinstance(blocks, dict) or "h" not in blocks or "i" not in blocks:
            return None
        return cls(blocks["h"], blocks["i"], action)

    def _access(self, fc: int, block: Block, address: int, count: int, values: list[int] | None) -> int | None:
        start, size, registers, flags = block
        off = address - start
        if off < 0 or off + count > size:
            return ILLEGAL_ADDRESS
        for flag in flags[off:off + count]:
            if flag & _FLAG_TYPE == _FLAG_INVALID or (values is not None and flag & _FLAG_READONLY):
                return ILLEGAL_ADDRESS
        code = run_now(self.action(fc, start, address, count, registers, values))  # type: ignore[arg-type]
        if code:
            return int(code)
        if values is not None:
            registers[off:off + count] = values
        return None

    def read(self, fc: int, address: int, count: int) -> list[int] | int:
        """The registers read (FC 03 / 23 from the holding block, FC 04 from the input block) or an exception code."""
        block = self.inputs if fc == 4 else self.holding
        code = self._access(fc, block, address, count, None)
        if code is not None:
            return code
        off = address - block[0]
        return block[2][off:off + count]

    def write(self, fc: int, address: int, values: list[int]) -> int | None:
        """Write holding registers (FC 16 / 23); None, or the exception code (nothing written)."""
        return self._access(fc, self.holding, address, len(values), values)

    def command_seq(self, pdu: bytes) -> int | None:
        """The board tick (``seq``) of the command block a write request (its PDU) would leave, if it writes into the
        command block (None otherwise, or if it cannot be decoded: the write is then refused on the way)."""
        if pdu[0] == 16:
            address, count, _ = _WRITE.unpack_from(pdu, 1)
            first = 6
        elif pdu[0] == 23:
            _ra, _rq, address, count, _ = _READ_WRITE.unpack_from(pdu, 1)
            first = 10
        else:
            return None
        if not (address < COMMAND_END and address + count > COMMAND_START):
            return None
        start, _, registers, _ = self.holding
        block = registers[HOLDING_START - start: HOLDING_START - start + HOLDING_COUNT]  # as the action hook merges
        block[address - HOLDING_START: address - HOLDING_START + count] = struct.unpack_from(f">{count}H", pdu, first)
        try:
            return decode_command_block(block[COMMAND_START - HOLDING_START: COMMAND_END - HOLDING_START]).seq
        except (ValueError, struct.error):
            return None

    def answer(self, pdu: bytes) -> bytes:
        """The reply PDU to a hot request PDU that :func:`hil_stub.modbus_requests.check_request_pdu` accepted."""
        fc = pdu[0]
        if fc in (3, 4):
            address, count = _READ.unpack_from(pdu, 1)
            got = self.read(fc, address, count)
        elif fc == 16:
            address, count, _ = _WRITE.unpack_from(pdu, 1)
            code = self.write(16, address, list(struct.unpack_from(f">{count}H", pdu, 6)))
            return exception_pdu(fc, code) if code is not None else write_pdu(address, count)
        else:  # 23: the write, then the read
            r_addr, r_count, w_addr, w_count, _ = _READ_WRITE.unpack_from(pdu, 1)
            code = self.write(23, w_addr, list(struct.unpack_from(f">{w_count}H", pdu, 10)))
            got = code if code is not None else self.read(23, r_addr, r_count)
        return exception_pdu(fc, got) if isinstance(got, int) else registers_pdu(fc, got)
