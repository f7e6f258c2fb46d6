"""A non-finite demand (NaN, ±Inf) written to the rig's Modbus map is refused with exception 03 *before it touches the
rig* (issue 33): no refused-command count, no limit-refused flag, no board-run count, no lock-step tick — so a second
client writing NaN never disturbs the board that is running (docs/registers.md, "Errors and what the rig answers").
Real pymodbus clients (and mbpoll) over loopback TCP, and a raw RTU master on the stub's pty."""

from __future__ import annotations

import os
import struct
import subprocess
import termios
import tty

import pytest
from links_support import FakeRig, cmd, missing_tools, rtu_crc
from pymodbus.client import ModbusTcpClient

from drivers import open_link
from drivers.link import FLAG_LIMIT_REFUSED
from drivers.modbus_registers import COMMAND_START, INPUT_COUNT, MIRROR_START, encode_command_block
from hil_stub.service import HilService

pytestmark = pytest.mark.integration

NAN = [0x7FC0, 0x0000]  # float32 NaN, high word first (encode_value would write 0)
INF = [0x7F80, 0x0000]
NEG_INF = [0xFF80, 0x0000]


def _block(v1: list[int], v2: list[int] | None = None, seq: int = 1) -> list[int]:
    words = encode_command_block(cmd(seq))
    words[0:2] = v1
    if v2 is not None:
        words[2:4] = v2
    return words


def _host_state(hil: HilService) -> tuple:
    h = hil.host
    return (h.refused_count, h.board_runs, h.commands, h.accepted_seq, h.snapshot.tick,
            bool(h.snapshot.sample.flags & FLAG_LIMIT_REFUSED))


@pytest.mark.parametrize("mode", ["lockstep", "realtime"])
def test_a_second_client_writing_nan_never_disturbs_a_running_board(mode: str) -> None:
    with HilService(FakeRig(), mode=mode, start="now") as hil:
        srv = hil.add_modbus_tcp("127.0.0.1:0")
        other = ModbusTcpClient("127.0.0.1", port=srv.port, timeout=0.5, retries=0)
        assert other.connect()
        with open_link(srv.board_url + "&timeout=0.5") as link:
            samples = [link.exchange(cmd(k)) for k in range(100, 110)]
            before = _host_state(hil) if mode == "lockstep" else None
            refused_before = hil.host.refused_count
            # the second client: FC 16 and FC 23 with a NaN / Inf demand, a command counter far below the board's
            for bad in (_block(NAN, seq=1), _block(INF, seq=2), _block([0, 0], NEG_INF, seq=3),
                        _block(NAN, NAN, seq=0)):
                assert other.write_registers(COMMAND_START, bad, device_id=1).exception_code == 3
                rr = other.readwrite_registers(read_address=MIRROR_START, read_count=INPUT_COUNT,
                                               write_address=COMMAND_START, values=bad, device_id=1)
                assert rr.exception_code == 3
            assert other.write_registers(COMMAND_START, NAN, device_id=1).exception_code == 3  # v_ch1 alone
            if before is not None:  # lock-step: nothing moved at all, not even the rig's clock
                assert _host_state(hil) == before
            samples += [link.exchange(cmd(k)) for k in range(110, 120)]
        other.close()
    assert hil.host.refused_count == refused_before == 0
    assert hil.host.board_runs == 1  # the second client's low counters were never taken for a new board run
    assert not any(s.flags & FLAG_LIMIT_REFUSED for s in samples)
    assert link.stats["refused"] == 0 and link.stats["seq_mismatch"] == 0
    assert srv.stats["nonfinite_refused"] == 9
    if mode == "lockstep":
        assert [s.seq for s in samples] == list(range(1, 21))  # one rig tick per board command, none for the NaNs


def test_an_out_of_range_finite_demand_still_reaches_the_rig_as_documented() -> None:
    """The other row of the table: a finite demand outside Table 1 is refused by the rig itself (counted, flagged)."""
    with HilService(FakeRig(), mode="lockstep") as hil:
        srv = hil.add_modbus_tcp("127.0.0.1:0")
        c = ModbusTcpClient("127.0.0.1", port=srv.port, timeout=0.5, retries=0)
        assert c.connect()
        words = encode_command_block(cmd(5, v1=1600.0))
        assert c.write_registers(COMMAND_START, words, device_id=1).exception_code == 3
        c.close()
    assert hil.host.refused_count == 1 and srv.stats["nonfinite_refused"] == 0


def _rtu(fd: int, pdu: bytes) -> bytes:
    import select

    frame = bytes([1]) + pdu
    os.write(fd, frame + rtu_crc(frame))
    buf = b""
    while select.select([fd], [], [], 1.0)[0]:
        buf += os.read(fd, 256)
        if len(buf) >= 5 and buf[1] & 0x80:
            break
        if len(buf) >= 8 and not buf[1] & 0x80:
            break
    return buf


def test_rtu_refuses_a_nan_write_before_the_rig() -> None:
    with HilService(FakeRig(), mode="lockstep") as hil:
        srv = hil.add_modbus_rtu("pty")
        fd = os.open(srv.board_path, os.O_RDWR | os.O_NOCTTY)
        try:
            tty.setraw(fd)
            termios.tcflush(fd, termios.TCIOFLUSH)
            before = _host_state(hil)
            words = _block(NAN)
            pdu = struct.pack(">BHHB", 16, COMMAND_START, len(words), 2 * len(words)) + \
                b"".join(struct.pack(">H", w) for w in words)
            reply = _rtu(fd, pdu)
            assert reply[:3] == bytes([1, 16 | 0x80, 3]) and reply[3:5] == rtu_crc(reply[:3])
            pdu23 = struct.pack(">BHHHHB", 23, MIRROR_START, INPUT_COUNT, COMMAND_START, len(words), 2 * len(words)) \
                + b"".join(struct.pack(">H", w) for w in words)
            reply = _rtu(fd, pdu23)
            assert reply[:3] == bytes([1, 23 | 0x80, 3])
            assert _host_state(hil) == before
        finally:
            os.close(fd)


@pytest.mark.skipif(missing_tools("mbpoll") is not None, reason=str(missing_tools("mbpoll")))
def test_mbpoll_writing_nan_gets_exception_03_and_changes_nothing() -> None:
    with HilService(FakeRig(), mode="lockstep") as hil:
        srv = hil.add_modbus_tcp("127.0.0.1:0")
        before = _host_state(hil)
        r = subprocess.run(["mbpoll", "-m", "tcp", "-p", str(srv.port), "-a", "1", "-1", "-o", "0.5", "-t", "4:float",
                            "-B", "-r", "1", "127.0.0.1", "--", "nan", "100"], capture_output=True, text=True,
                           timeout=20)
        out = r.stdout + r.stderr
        assert r.returncode != 0 and "Illegal data value" in out, out
        assert _host_state(hil) == before
