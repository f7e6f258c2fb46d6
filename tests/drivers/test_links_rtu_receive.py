"""The board's RTU receive (drivers.modbus_rtu_client.RtuTransaction) at its deadline, on a real pty."""

from __future__ import annotations

import os
import time
from collections import Counter

import pytest
from pymodbus.framer import FramerType
from pymodbus.framer.rtu import FramerRTU

from drivers.modbus_rtu_client import RtuClient
from hil_stub.pty_port import PtyPort


def _fc04_reply(unit: int, registers: list[int]) -> bytes:
    body = bytes([unit, 0x04, 2 * len(registers)]) + b"".join(r.to_bytes(2, "big") for r in registers)
    return body + FramerRTU.compute_CRC(body).to_bytes(2, "big")


@pytest.fixture
def client(tmp_path):
    pty = PtyPort(tmp_path / "board")
    pty.open()
    c = RtuClient(str(pty.link), framer=FramerType.RTU, baudrate=115200, timeout=0.5, retries=0, stats=Counter())
    assert c.connect()
    yield c, pty
    c.close()
    pty.close()


def _arrived(c, n: int) -> None:
    end = time.monotonic() + 2.0
    while c.socket.in_waiting < n and time.monotonic() < end:
        time.sleep(0.001)
    assert c.socket.in_waiting == n


def test_a_reply_already_waiting_is_taken_even_past_the_deadline(client):
    """A board process that was not running (a machine stall) wakes after its deadline with the reply waiting in the
    port: taking it costs nothing, giving up on it costs the exchange."""
    c, pty = client
    tr = c.transaction
    tr._expected_fc = 0x04
    frame = _fc04_reply(1, [7, 8, 9])
    os.write(pty.master, frame)
    _arrived(c, len(frame))
    tr.comm_params.timeout_connect = 0.0  # the deadline has passed before the receive starts
    pdu = tr.sync_get_response(1, 5)
    assert pdu.function_code == 0x04 and list(pdu.registers) == [7, 8, 9] and pdu.transaction_id == 5


def test_past_the_deadline_nothing_more_is_waited_for(client):
    c, pty = client
    tr = c.transaction
    tr._expected_fc = 0x04
    frame = _fc04_reply(1, [1, 2])
    os.write(pty.master, frame[:4])  # only the start of the reply is here
    _arrived(c, 4)
    tr.comm_params.timeout_connect = 0.0
    t0 = time.monotonic()
    with pytest.raises(TimeoutError):
        tr.sync_get_response(1, 1)
    assert time.monotonic() - t0 < 0.05
    tr.comm_params.timeout_connect = 0.003  # within a deadline the rest is waited for
    with pytest.raises(TimeoutError):
        tr.sync_get_response(1, 2)
    os.write(pty.master, frame)
    _arrived(c, len(frame))
    tr.comm_params.timeout_connect = 0.0
    assert list(tr.sync_get_response(1, 3).registers) == [1, 2]
