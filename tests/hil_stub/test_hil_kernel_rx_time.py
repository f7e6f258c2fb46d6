"""The stub's answer time from the kernel's receive timestamp (issue 29.2, ``hil_stub.kernel_rx_time``): a served TCP
connection's socket keeps the software receive timestamp of what it reads, and `shm hil serve --summary` reports
``answer_time_from_kernel_rx`` (wake-up included) beside ``answer_time`` (from the event loop's read)."""

from __future__ import annotations

import socket
import struct
import sys
import time
from typing import Any

import pytest
from links_support import FakeRig

from hil_stub import kernel_rx_time
from hil_stub.service import HilService

linux_only = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="SO_TIMESTAMPING is Linux's")


class _Transport:
    def __init__(self, sock: socket.socket) -> None:
        self._sock = sock


def test_the_timestamp_is_read_from_the_ancillary_data() -> None:
    stamp = struct.pack("qq", 1_700_000_000, 250_000_000) + bytes(32)
    level, kind = socket.SOL_SOCKET, kernel_rx_time.SO_TIMESTAMPING
    assert kernel_rx_time.stamp_from_ancillary([(level, kind, stamp)]) == pytest.approx(1_700_000_000.25)
    assert kernel_rx_time.stamp_from_ancillary([]) is None
    assert kernel_rx_time.stamp_from_ancillary([(level, kind, bytes(48))]) is None  # no software stamp in it
    assert kernel_rx_time.stamp_from_ancillary([(level, kind + 1, stamp)]) is None


@linux_only
def test_a_served_socket_keeps_the_kernels_receive_time_of_what_it_reads() -> None:
    with socket.create_server(("127.0.0.1", 0)) as listener:
        client = socket.create_connection(listener.getsockname())
        served, _ = listener.accept()
        with client, served:
            transport = _Transport(served)
            assert kernel_rx_time.install(transport)
            time.sleep(0.05)  # the kernel switches stamping on a moment after the first socket asks
            sent_at = time.time()
            client.sendall(b"request")
            time.sleep(0.02)
            assert served.recv(64) == b"request"
            read_at = time.time()
            stamp = kernel_rx_time.take_rx(transport)
            assert stamp is not None and sent_at - 1e-3 <= stamp <= read_at - 0.015  # when it arrived, not read
            assert kernel_rx_time.take_rx(transport) is None  # taken once


def test_where_it_cannot_apply_it_says_so() -> None:
    assert not kernel_rx_time.install(object())
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as udp:
        assert not kernel_rx_time.install(_Transport(udp))
    assert kernel_rx_time.take_rx(object()) is None


@linux_only
def test_the_stub_reports_its_answer_time_from_the_kernels_receive_time() -> None:
    from pymodbus.client import ModbusTcpClient

    with HilService(FakeRig(), mode="realtime") as hil:
        srv = hil.add_modbus_tcp("127.0.0.1:0")
        client = ModbusTcpClient("127.0.0.1", port=srv.port, timeout=1.0, retries=0)
        assert client.connect()
        try:
            time.sleep(0.05)
            for _ in range(40):
                assert not client.read_input_registers(0, count=22, device_id=1).isError()
                time.sleep(0.002)
        finally:
            client.close()
        servers: dict[str, Any] = hil.summary()["servers"]
    (answers,) = servers.values()
    from_loop, from_kernel = answers["answer_time"], answers["answer_time_from_kernel_rx"]
    assert from_loop["n"] == 40 and 38 <= from_kernel["n"] <= 40
    # the kernel's span holds the loop's (it starts earlier, ends at the same reply): so do its order statistics
    assert from_kernel["p50_ms"] >= from_loop["p50_ms"] and from_kernel["max_ms"] >= from_loop["max_ms"] - 0.05
