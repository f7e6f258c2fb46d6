"""The board's Modbus RTU client: pymodbus' sync serial client with a receive that keeps to the exchange's deadline
and to frame boundaries (:class:`RtuClient`, used by :class:`drivers.modbus_link.ModbusLink` on ``modbus-rtu:``)."""

from __future__ import annotations

import select
import time
from collections import Counter
from typing import Any

from pymodbus.client import ModbusSerialClient
from pymodbus.exceptions import ConnectionException
from pymodbus.framer.rtu import FramerRTU
from pymodbus.transaction import TransactionManager


class RtuTransaction(TransactionManager):
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

    def pdu_send(self, pdu: Any, addr: tuple[Any, ...] | None = None) -> None:
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


class RtuClient(ModbusSerialClient):
    """pymodbus' sync RTU client with an event-driven receive that keeps to the exchange deadline and to frame
    boundaries (:class:`RtuTransaction`).

    The stock ``recv(None)`` polls ``in_waiting`` with ``time.sleep`` and waits until the byte count stops
    growing (≥ 2 ms per reply, 4 ms per exchange). Here ``recv(None)`` blocks in ``select`` until bytes are
    there and returns them at once (used by pymodbus outside the transaction's receive).
    """

    def __init__(self, *args: Any, stats: Counter[str], **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        old = self.transaction
        self.transaction = RtuTransaction(self.comm_params, self.framer, self.retries, False, old.trace_packet,
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
            data: bytes = sock.read(max(1, sock.in_waiting))
            return data
        except (OSError, ValueError) as exc:
            self.close()  # type: ignore[no-untyped-call]  # pymodbus leaves close() unannotated
            raise ConnectionException(f"serial port lost: {exc}") from None
