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

from collections import Counter
from collections.abc import Callable
from typing import Any, Protocol

from drivers.link import LinkError
from drivers.modbus_registers import (
    COMMAND_START,
    INPUT_COUNT,
    MIRROR_START,
    InputBlock,
    ModbusExceptionCode,
    decode_input_block,
)


class Fc23Link(Protocol):
    """What an FC 23 exchange uses of :class:`drivers.modbus_link.ModbusLink` (a protocol, so that this module does
    not import the link that imports it)."""

    settings: dict[str, Any]
    stats: Counter[str]
    url: str
    timeout: float
    unit: int
    last_exception_code: int | None
    _client: Any
    _down: bool
    _log: Any

    def _call(self, what: str, fn: Callable[..., Any], *args: Any, budget: float | None = None, context: str = "",
              **kwargs: Any) -> Any: ...

    def _skip_stale(self, rr: Any, function_code: int, deadline: float) -> Any: ...

    def _set_timeout(self, seconds: float) -> None: ...

    def _phase(self, what: str, t0: float, budget: float) -> None: ...

    def _read_inputs(self, budget: float | None = None, context: str = "",
                     deadline: float | None = None) -> InputBlock: ...

FC23 = 0x17
_MIN_READ_S = 5e-4  # as drivers.modbus_link: no read is started with less than this left


class Fc23Unserved(LinkError):
    """The rig refused FC 23 (exception 01 or 02): the board falls back to FC 16 + FC 04."""


def exchange_fc23(link: Fc23Link, words: list[int], seq: int, deadline: float) -> tuple[InputBlock, bool]:
    """Write the command block ``words`` and read the sample in one FC 23 within ``deadline`` (monotonic s).

    Returns ``(block, refused)``: the decoded sample block and whether the rig refused the command (exception 03).
    Raises :class:`Fc23Unserved` when the rig does not serve FC 23 (the caller falls back), ``LinkError`` otherwise.
    """
    import time

    rtu = link.settings["kind"] == "rtu"
    left = deadline - time.monotonic()
    if left < _MIN_READ_S:  # the process was descheduled past its budget before the request went out
        link.stats["timeouts"] += 1
        raise LinkError(f"{link.url}: no time left for the FC23 transaction ({1e3 * left:.1f} ms of the "
                        f"{1e3 * link.timeout:.1f} ms exchange budget)")
    try:
        rr = link._call("write command, read sample (FC23)", link._client.readwrite_registers,
                        read_address=MIRROR_START, read_count=INPUT_COUNT, write_address=COMMAND_START, values=words,
                        budget=left)
    except LinkError:
        if not rtu or link._down or deadline - time.monotonic() < _MIN_READ_S:
            raise
        # RTU: the reply is lost or late; a read has no side effect — does the rig show the command applied?
        block = _read_after(link, deadline)
        if block.cmd_seq_applied != seq & 0xFFFFFFFF:
            raise LinkError(f"{link.url}: the FC23 reply was lost and the rig reports command seq "
                            f"{block.cmd_seq_applied} applied, not {seq}") from None
        link.stats["ack_lost_but_applied"] += 1
        return block, False
    rr = link._skip_stale(rr, FC23, deadline)
    if rr.isError():
        code = getattr(rr, "exception_code", None)
        link.last_exception_code = code
        link.stats["exception_replies"] += 1
        if code == ModbusExceptionCode.ILLEGAL_VALUE:
            link.stats["refused"] += 1
            link._log.warn("refused", "%s: rig refused command seq %d: exception 03", link.url, seq)
            if deadline - time.monotonic() < _MIN_READ_S:
                raise LinkError(f"{link.url}: command seq {seq} refused (exception 03) and no time left to read "
                                "the sample")
            return _read_after(link, deadline), True
        if code in (ModbusExceptionCode.ILLEGAL_FUNCTION, ModbusExceptionCode.ILLEGAL_ADDRESS):
            raise Fc23Unserved(f"{link.url}: the rig refused FC 23 with exception {code:02d}; using FC 16 + FC 04")
        raise LinkError(f"{link.url}: FC23 refused with Modbus exception {code}")
    block = _block_of(link, rr)
    if block.cmd_seq_applied != seq & 0xFFFFFFFF and deadline - time.monotonic() >= _MIN_READ_S:
        # the late reply to the previous tick's FC 23 (same function code; its sample shows the older command):
        # the real reply is on its way — wait for it within the budget, once
        link.stats["stale_skipped"] += 1
        later = _next_reply(link, deadline)
        if later is not None and not later.isError():
            block = _block_of(link, later)
    return block, False


def _block_of(link: Fc23Link, rr: Any) -> InputBlock:
    regs = getattr(rr, "registers", None)
    if rr.function_code != FC23 or regs is None or len(regs) != INPUT_COUNT:
        link.stats["bad_reply"] += 1
        raise LinkError(f"{link.url}: unexpected reply to FC23 (function {rr.function_code}, "
                        f"{0 if regs is None else len(regs)} registers)")
    return decode_input_block(regs)


def _next_reply(link: Fc23Link, deadline: float) -> Any:
    """The next reply on the connection within ``deadline`` (None: nothing came)."""
    import time

    transaction = link._client.transaction
    tid = getattr(transaction, "request_transaction_id", 0) or 0
    left = deadline - time.monotonic()
    link._set_timeout(left)
    t0 = time.monotonic()
    try:
        return transaction.sync_get_response(link.unit, tid)
    except Exception:  # nothing more within the budget
        return None
    finally:
        link._phase("past a stale reply, wait for FC23", t0, left)


def _read_after(link: Fc23Link, deadline: float) -> InputBlock:
    import time

    return link._read_inputs(budget=max(deadline - time.monotonic(), _MIN_READ_S), deadline=deadline)


def fc23_announced(words: list[int] | Any) -> bool:
    """Whether the identity block (holding 8–13) announces map version 2 or later (the sample mirror and FC 23)."""
    from drivers.modbus_registers import FC23_MAP_VERSION

    return int(words[0]) >= FC23_MAP_VERSION
