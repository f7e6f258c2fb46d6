"""The ``ptymaster://FD`` pyserial handler: the stub's Modbus RTU server on the master of one pty (no relay)."""

from __future__ import annotations

import os
import select

import pytest
import serial

from hil_stub import protocol_ptymaster
from hil_stub.pty_port import PtyPort


@pytest.fixture
def pty(tmp_path):
    port = PtyPort(tmp_path / "board")
    port.open()
    yield port
    port.close()


def _read(fd: int, n: int, timeout: float = 2.0) -> bytes:
    out = b""
    while len(out) < n and select.select([fd], [], [], timeout)[0]:
        out += os.read(fd, n - len(out))
    return out


def test_bytes_cross_between_the_board_side_and_the_master(pty):
    protocol_ptymaster.register()
    protocol_ptymaster.register()  # idempotent
    assert serial.protocol_handler_packages.count("hil_stub") == 1
    ser = serial.serial_for_url(protocol_ptymaster.url_for(pty.master), baudrate=115200, timeout=1.0)
    board = os.open(str(pty.link), os.O_RDWR | os.O_NOCTTY)
    try:
        os.write(board, b"\x01\x04\x00\x00\x00\x16")
        assert ser.read(6) == b"\x01\x04\x00\x00\x00\x16"
        ser.write(b"reply")
        assert _read(board, 5) == b"reply"
        ser.baudrate = 19200  # line settings are accepted and mean nothing on a pty
        ser.timeout = 0
        assert ser.read(10) == b""
    finally:
        os.close(board)
        ser.close()
    # closing the port closes its duplicate only: the pty is still there for the next server
    assert pty.is_open
    os.fstat(pty.master)


def test_what_the_board_sent_while_nobody_served_is_dropped_at_open(pty):
    protocol_ptymaster.register()
    board = os.open(str(pty.link), os.O_RDWR | os.O_NOCTTY)
    try:
        os.write(board, b"stale request")
        assert select.select([pty.master], [], [], 2.0)[0]
        ser = serial.serial_for_url(protocol_ptymaster.url_for(pty.master), timeout=0)
        try:
            assert ser.read(100) == b""
        finally:
            ser.close()
    finally:
        os.close(board)


@pytest.mark.parametrize("url", ["ptymaster://x", "ptymaster://99999", "ptymaster://"])
def test_a_bad_descriptor_is_a_serial_exception(url):
    protocol_ptymaster.register()
    with pytest.raises(serial.SerialException, match="could not open port"):
        serial.serial_for_url(url)
