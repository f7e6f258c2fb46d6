"""One transaction per tick: the board's exchange as a single Modbus FC 23 (read/write multiple registers).

A rig that announces register map version 2 at the handshake (holding 8, ``map_version``; docs/registers.md) serves
the sample block again as holding registers 100–121 (the *sample mirror*). One FC 23 then writes the command
(holding 0–7) and reads the sample (holding 100–121) in one round trip: the rig performs the write before the read,
so the sample shows the command accepted (``cmd_seq_applied``). The transaction gets the whole exchange budget.

* A command refused with exception 03 (outside Table 1) returns no registers (FC 23 stops at its write): the sample
  is then read with FC 04 in what is left of the budget and carries ``FLAG_LIMIT_REFUSED``, as with FC 16.
* Exception 01 (the rig does not serve FC 23 after all) or 02 (no sample mirror) turns FC 23 off for the rest of
  the connection; the tick is read with FC 16 + FC 04 in what is left of the budget, or given up.
* A lost or late reply on RTU: the sample is read with FC 04 in what is left (no side effect) and the exchange
  stands when it shows the command applied; on TCP the tick is given up (a late reply is skipped by its
  transaction id within the next exchange). Either way a lost reply costs at most one exchange.
"""

from __future__ import annotations

import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

from drivers.incident_log import IncidentLog
from drivers.link import LinkError
from drivers.modbus_registers import INPUT_COUNT, InputBlock, ModbusExceptionCode, decode_input_block

FC23 = 0x17
_MIN_READ_S = 5e-4  # as drivers.modbus_link: no read is started with less than this left


@dataclass(frozen=True)
class Fc23Exchange:
    """What one FC 23 exchange may use of its link (:meth:`drivers.modbus_link.ModbusLink.fc23_exchange` hands it
    over, each operation bound to the link; this module reaches nothing else of it). Times in s (monotonic)."""

    url: str
    rtu: bool  # Modbus RTU: a lost reply is checked by reading the sample (no side effect)
    budget_s: float  # the link's exchange budget (for the messages)
    stats: Counter[str]  # the link's counters
    log: IncidentLog  # the link's rate-limited warnings
    #: one FC 23 request (write the words to holding 0-7, read the sample mirror) within a budget: the reply;
    #: ``LinkError`` when none came (the link has counted it, and closed the connection if it broke)
    send: Callable[[list[int], float], Any]
    is_down: Callable[[], bool]  # the last failure closed the connection
    #: a reply with another function code (a late one) skipped while the deadline lasts: the reply to keep
    skip_stale: Callable[[Any, int, float], Any]
    next_reply: Callable[[float], Any]  # the next reply on the connection before the deadline (None: nothing came)
    read_sample: Callable[[float, float], InputBlock]  # the sample by FC 04 within (budget, deadline)
    record_exception: Callable[[int | None], None]  # a Modbus exception reply's code, kept by the link


class Fc23Link(Protocol):
    """A link that can run FC 23 exchanges (:class:`drivers.modbus_link.ModbusLink`; a protocol, so that this module
    does not import the link that imports it)."""

    def fc23_exchange(self) -> Fc23Exchange: ...


class Fc23Unserved(LinkError):
    """The rig refused FC 23 (exception 01 or 02): the board falls back to FC 16 + FC 04."""


def exchange_fc23(link: Fc23Link, words: list[int], seq: int, deadline: float) -> tuple[InputBlock, bool]:
    """Write the command block ``words`` and read the sample in one FC 23 within ``deadline`` (monotonic s).

    Returns ``(block, refused)``: the decoded sample block and whether the rig refused the command (exception 03).
    Raises :class:`Fc23Unserved` when the rig does not serve FC 23 (the caller falls back), ``LinkError`` otherwise.
    """
    x = link.fc23_exchange()
    left = deadline - time.monotonic()
    if left < _MIN_READ_S:  # the process was descheduled past its budget before the request went out
        x.stats["timeouts"] += 1
        raise LinkError(f"{x.url}: no time left for the FC23 transaction ({1e3 * left:.1f} ms of the "
                        f"{1e3 * x.budget_s:.1f} ms exchange budget)")
    try:
        rr = x.send(words, left)
    except LinkError:
        if not x.rtu or x.is_down() or deadline - time.monotonic() < _MIN_READ_S:
            raise
        # RTU: the reply is lost or late; a read has no side effect — does the rig show the command applied?
        block = _read_after(x, deadline)
        if block.cmd_seq_applied != seq & 0xFFFFFFFF:
            raise LinkError(f"{x.url}: the FC23 reply was lost and the rig reports command seq "
                            f"{block.cmd_seq_applied} applied, not {seq}") from None
        x.stats["ack_lost_but_applied"] += 1
        return block, False
    rr = x.skip_stale(rr, FC23, deadline)
    if rr.isError():
        return _refused(x, rr, seq, deadline)
    block = _block_of(x, rr)
    if block.cmd_seq_applied != seq & 0xFFFFFFFF and deadline - time.monotonic() >= _MIN_READ_S:
        # the late reply to the previous tick's FC 23 (same function code; its sample shows the older command):
        # the real reply is on its way — wait for it within the budget, once
        x.stats["stale_skipped"] += 1
        later = x.next_reply(deadline)
        if later is not None and not later.isError():
            block = _block_of(x, later)
    return block, False


def _refused(x: Fc23Exchange, rr: Any, seq: int, deadline: float) -> tuple[InputBlock, bool]:
    """An exception reply: exception 03 (command refused) reads the sample; 01 or 02 raise
    :class:`Fc23Unserved`; any other is a ``LinkError``."""
    code = getattr(rr, "exception_code", None)
    x.record_exception(code)
    x.stats["exception_replies"] += 1
    if code == ModbusExceptionCode.ILLEGAL_VALUE:
        x.stats["refused"] += 1
        x.log.warn("refused", "%s: rig refused command seq %d: exception 03", x.url, seq)
        if deadline - time.monotonic() < _MIN_READ_S:
            raise LinkError(f"{x.url}: command seq {seq} refused (exception 03) and no time left to read "
                            "the sample")
        return _read_after(x, deadline), True
    if code in (ModbusExceptionCode.ILLEGAL_FUNCTION, ModbusExceptionCode.ILLEGAL_ADDRESS):
        raise Fc23Unserved(f"{x.url}: the rig refused FC 23 with exception {code:02d}; using FC 16 + FC 04")
    raise LinkError(f"{x.url}: FC23 refused with Modbus exception {code}")


def _block_of(x: Fc23Exchange, rr: Any) -> InputBlock:
    regs = getattr(rr, "registers", None)
    if rr.function_code != FC23 or regs is None or len(regs) != INPUT_COUNT:
        x.stats["bad_reply"] += 1
        raise LinkError(f"{x.url}: unexpected reply to FC23 (function {rr.function_code}, "
                        f"{0 if regs is None else len(regs)} registers)")
    return decode_input_block(regs)


def _read_after(x: Fc23Exchange, deadline: float) -> InputBlock:
    return x.read_sample(max(deadline - time.monotonic(), _MIN_READ_S), deadline)


def fc23_announced(words: list[int] | Any) -> bool:
    """Whether the identity block (holding 8–13) announces map version 2 or later (the sample mirror and FC 23)."""
    from drivers.modbus_registers import FC23_MAP_VERSION

    return int(words[0]) >= FC23_MAP_VERSION
