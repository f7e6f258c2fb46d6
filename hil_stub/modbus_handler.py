"""pymodbus' server classes with the stub's own front door: every request passes :class:`RigFrontDoor` first (the
stale requests skipped, malformed ones answered with the spec's exception, the hot function codes answered from the
tables, :mod:`hil_stub.modbus_hot_path`), and pymodbus sees what is left. The server owning the rig is
:class:`hil_stub.modbus_server.ModbusRigServer`."""

from __future__ import annotations

import asyncio
from typing import Protocol

from pymodbus.server import ModbusSerialServer, ModbusTcpServer
from pymodbus.server.requesthandler import ServerRequestHandler

from hil_stub import kernel_rx_time


class RigFrontDoor(Protocol):
    """What the handler asks of the server that owns the rig (``ModbusRigServer``)."""

    kind: str
    kernel_stamps: bool
    kernel_received_at: float | None

    def stale_request_bytes(self, data: bytes) -> int: ...

    def precheck(self, handler: ServerRequestHandler, data: bytes) -> int: ...

    def answer_hot(self, handler: ServerRequestHandler, data: bytes) -> int: ...


class CheckingHandler(ServerRequestHandler):
    """pymodbus' per-connection request handler, with the rig's front door in front (TCP MBAP or RTU)."""

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        super().connection_made(transport)
        rig: RigFrontDoor | None = getattr(self.server, "rig", None)
        if rig is not None and rig.kind == "tcp":
            rig.kernel_stamps = kernel_rx_time.install(transport)

    def callback_data(self, data: bytes, addr: tuple | None = None) -> int:
        rig: RigFrontDoor | None = getattr(self.server, "rig", None)
        if rig is not None:
            stamp = kernel_rx_time.take_rx(self.transport)
            if stamp is not None:
                rig.kernel_received_at = stamp
            stale = rig.stale_request_bytes(data)
            if stale:  # answer the newest request; the ones before it, its master has given up on
                return stale + self.callback_data(data[stale:], addr)
            used = rig.precheck(self, data) or rig.answer_hot(self, data)
            if used:
                return used
        return super().callback_data(data, addr)

    def handle_later(self) -> None:
        """The request's task, created on the loop's own thread (pymodbus: ``run_coroutine_threadsafe``, a write to
        the loop's self-pipe and one more trip through ``epoll`` per request)."""
        self.loop.create_task(self.handle_request())


class CheckingTcpServer(ModbusTcpServer):
    rig: RigFrontDoor | None = None  # the server whose front door runs first (read by CheckingHandler)

    def callback_new_connection(self):
        return CheckingHandler(self, self.trace_packet, self.trace_pdu, self.trace_connect)


class CheckingSerialServer(ModbusSerialServer):
    rig: RigFrontDoor | None = None

    def callback_new_connection(self):
        return CheckingHandler(self, self.trace_packet, self.trace_pdu, self.trace_connect)
