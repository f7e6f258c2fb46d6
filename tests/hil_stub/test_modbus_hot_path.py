"""The stub's hot Modbus path (issue 29, point 2; hil_stub/modbus_hot_path.py): its MBAP and RTU parsers on partial,
concatenated, corrupted and malformed frames, its replies as pymodbus' own framers read them, and the served stub
answering byte for byte as pymodbus' request chain does over TCP and RTU (the same register map, exception codes,
unit-id echo, transaction-id echo, stale-request skipping and seeded drop/corrupt faults), with pymodbus' client and
mbpoll over loopback."""

from __future__ import annotations

import os
import select
import shutil
import socket
import struct
import subprocess
import termios
import time
import tty
from collections.abc import Iterator
from contextlib import contextmanager

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from pymodbus.client import ModbusTcpClient
from pymodbus.framer import FramerRTU, FramerSocket
from pymodbus.pdu import DecodePDU

from drivers.link import ActuatorCommand
from drivers.modbus_registers import (
    COMMAND_START,
    HOLDING_START,
    INPUT_COUNT,
    INPUT_START,
    MIRROR_START,
    decode_input_block,
    encode_command_block,
)
from hil_stub.faults import FaultPlan, LinkFaults
from hil_stub.modbus_hot_path import (
    exception_pdu,
    frame_starts,
    mbap_adu,
    parse_mbap,
    parse_rtu,
    registers_pdu,
    rtu_adu,
    write_pdu,
)
from hil_stub.modbus_server import ModbusRigServer
from hil_stub.service import HilService
from tests.links_support import FakeRig

_PDU = st.binary(min_size=1, max_size=60)
_WORDS = st.lists(st.integers(0, 0xFFFF), min_size=1, max_size=40)


_adu = mbap_adu


# ------------------------------------------------------------------------------------------ the parser (pure)
@given(st.integers(0, 0xFFFF), st.integers(0, 255), _PDU)
def test_a_partial_frame_waits_and_the_whole_one_is_read(tid, unit, pdu):
    frame = _adu(tid, unit, pdu)
    assert all(parse_mbap(frame[:k]) is None for k in range(len(frame)))
    req = parse_mbap(frame + b"\x00\x01\x02")  # bytes of the next frame do not change this one
    assert req is not None and (req.tid, req.unit, req.fc, req.end) == (tid, unit, pdu[0], len(frame))


@given(st.lists(st.tuples(st.integers(0, 0xFFFF), _PDU), min_size=1, max_size=6), st.integers(0, 7))
def test_concatenated_frames_are_found_in_order_and_a_trailing_partial_one_is_not(frames, cut):
    adus = [_adu(tid, 1, pdu) for tid, pdu in frames]
    data = b"".join(adus)
    starts = [sum(len(a) for a in adus[:i]) for i in range(len(adus))]
    assert frame_starts(data) == starts
    assert frame_starts(data + adus[0][:cut]) == starts  # fewer than a whole frame more


@given(st.integers(0, 0xFFFF), st.one_of(st.integers(0, 1), st.integers(255, 0xFFFF)), st.binary(max_size=300))
def test_a_bad_length_is_not_a_frame(tid, length, rest):
    data = struct.pack(">HHH", tid, 0, length) + rest
    assert parse_mbap(data) is None and frame_starts(data) == []


@given(st.integers(0, 247), _PDU, st.data())
def test_an_rtu_frame_is_read_whole_and_a_flipped_bit_is_not_a_frame(unit, pdu, data):
    frame = rtu_adu(unit, pdu)
    req = parse_rtu(frame)
    assert req is not None and (req.tid, req.unit, req.fc, req.end) == (None, unit, pdu[0], len(frame))
    assert frame[req.pdu_start:req.pdu_end] == pdu
    bit = data.draw(st.integers(0, 8 * len(frame) - 1))
    broken = bytearray(frame)
    broken[bit // 8] ^= 1 << (bit % 8)
    assert parse_rtu(bytes(broken)) is None  # CRC-16 catches every single-bit error
    assert parse_rtu(frame + frame) is None  # two frames at once: pymodbus' framer hunts through them


@given(st.integers(1, 0xFFFF), _PDU)
def test_a_protocol_id_other_than_modbus_is_not_a_frame(pid, pdu):
    frame = bytearray(_adu(1, 1, pdu))
    frame[2:4] = pid.to_bytes(2, "big")
    assert parse_mbap(bytes(frame)) is None


def _decoded(adu: bytes, rtu: bool):
    framer = FramerRTU(DecodePDU(False)) if rtu else FramerSocket(DecodePDU(False))
    used, pdu = framer.handleFrame(adu, 0, 0)
    assert used == len(adu)
    return pdu


def _framed(tid: int, unit: int, pdu: bytes, rtu: bool) -> bytes:
    return rtu_adu(unit, pdu) if rtu else mbap_adu(tid, unit, pdu)


@given(st.integers(0, 0xFFFF), st.integers(1, 247), st.sampled_from([3, 4, 23]), _WORDS, st.booleans())
def test_register_replies_read_back_with_pymodbus_framers(tid, unit, fc, words, rtu):
    pdu = _decoded(_framed(tid, unit, registers_pdu(fc, words), rtu), rtu)
    assert (pdu.function_code, pdu.dev_id, pdu.registers) == (fc, unit, words)
    assert rtu or pdu.transaction_id == tid


@given(st.integers(0, 0xFFFF), st.integers(1, 247), st.integers(0, 0xFFFF), st.integers(1, 123), st.booleans())
def test_write_replies_read_back_with_pymodbus_framers(tid, unit, address, count, rtu):
    pdu = _decoded(_framed(tid, unit, write_pdu(address, count), rtu), rtu)
    assert (pdu.function_code, pdu.dev_id, pdu.address, pdu.count) == (16, unit, address, count)
    assert rtu or pdu.transaction_id == tid


@given(st.integers(0, 0xFFFF), st.integers(1, 247), st.sampled_from([3, 4, 16, 23]), st.integers(1, 4),
       st.booleans())
def test_exception_replies_read_back_with_pymodbus_framers(tid, unit, fc, code, rtu):
    pdu = _decoded(_framed(tid, unit, exception_pdu(fc, code), rtu), rtu)
    assert (pdu.function_code, pdu.exception_code, pdu.dev_id) == (fc | 0x80, code, unit)
    assert rtu or pdu.transaction_id == tid


# ------------------------------------------------------------------------------------------ served: hot == pymodbus
class _Raw:
    """A bare Modbus TCP socket: send bytes, read what comes back within a short wait."""

    def __init__(self, port: int) -> None:
        self.sock = socket.create_connection(("127.0.0.1", port), timeout=2.0)
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)

    def ask(self, *chunks: bytes, wait_s: float = 0.15) -> bytes:
        """What comes back within ``wait_s`` (s) of the last chunk: a whole reply (its MBAP length met), or what
        arrived by then (nothing for a dropped reply)."""
        for i, chunk in enumerate(chunks):
            if i:
                time.sleep(0.01)  # a frame split across reads
            self.sock.sendall(chunk)
        self.sock.settimeout(wait_s)
        out = b""
        try:
            while len(out) < 7 or len(out) < 6 + struct.unpack(">H", out[4:6])[0]:
                got = self.sock.recv(4096)
                if not got:
                    break
                out += got
        except TimeoutError:
            pass
        return out


def _whole(reply: bytes) -> bool:
    """A Modbus TCP reply that is complete by its MBAP header's length field."""
    return len(reply) >= 7 and len(reply) >= 6 + struct.unpack(">H", reply[4:6])[0]


def _same_answer(hot: _Raw, old: _Raw, chunks: tuple[bytes, ...]) -> bool:
    """The hot path and pymodbus answer ``chunks`` with the same bytes. The lockstep twins drop and corrupt the same
    replies, so a whole reply from the hot path means pymodbus owes one too: it gets a long wait (under a loaded suite
    pymodbus took > 0.15 s, and its late reply read as a dropped one and then as the next request's answer)."""
    answer = hot.ask(*chunks, wait_s=0.5)
    return old.ask(*chunks, wait_s=3.0 if _whole(answer) else 0.5) == answer


@contextmanager
def _twins(rtu: bool) -> Iterator[tuple[ModbusRigServer, ModbusRigServer]]:
    """Two lockstep stubs, the same rig and seeded faults (drop and corrupt 10 % each), serving Modbus TCP on loopback
    or RTU on a pty: one answering FC 03/04/16/23 on the hot path, one through pymodbus."""
    plan = FaultPlan(link=LinkFaults(drop=0.1, corrupt=0.1), seed=5)
    with HilService(FakeRig(), mode="lockstep", plan=plan) as hot, \
            HilService(FakeRig(), mode="lockstep", plan=plan, hot_path=False) as old:
        yield tuple(hil.add_modbus_rtu("pty") if rtu else hil.add_modbus_tcp("127.0.0.1:0")  # type: ignore[misc]
                    for hil in (hot, old))


@pytest.fixture(scope="module")
def twin_stubs() -> Iterator[tuple[_Raw, _Raw, dict, dict]]:
    """:func:`_twins` over TCP: a raw client on each, and their counters."""
    with _twins(rtu=False) as (hot_srv, old_srv):
        a, b = _Raw(hot_srv.port), _Raw(old_srv.port)
        yield a, b, hot_srv.stats, old_srv.stats
        a.sock.close()
        b.sock.close()


def _request(fc: int, address: int, count: int, words: list[int], read_address: int) -> bytes:
    if fc in (3, 4):
        return struct.pack(">BHH", fc, address, count)
    data = b"".join(struct.pack(">H", w) for w in words)
    if fc == 16:
        return struct.pack(">BHHB", 16, address, len(words), 2 * len(words)) + data
    return struct.pack(">BHHHHB", 23, read_address, count, address, len(words), 2 * len(words)) + data


_ADDRESSES = st.one_of(st.sampled_from([HOLDING_START, COMMAND_START, INPUT_START, MIRROR_START, 4, 20, 40, 130]),
                       st.integers(0, 300))
_COMMANDS = st.builds(lambda k, v: encode_command_block(ActuatorCommand(seq=k, v_ch1=v, v_ch2=-v,
                                                                        board_current=0.002)),
                      st.integers(1, 10_000), st.floats(-1500.0, 1500.0))


@pytest.mark.integration
@pytest.mark.slow  # ~5 s: 120 requests to two stubs, the dropped replies waited out
@settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(fc=st.sampled_from([3, 4, 16, 23]), address=_ADDRESSES, count=st.integers(1, 125),
       words=st.one_of(_COMMANDS, _WORDS), read_address=_ADDRESSES, tid=st.integers(0, 0xFFFF),
       unit=st.sampled_from([1, 255]), split=st.integers(0, 20))
def test_the_hot_path_answers_byte_for_byte_as_pymodbus(twin_stubs, fc, address, count, words, read_address, tid,
                                                        unit, split):
    hot, old, hot_stats, old_stats = twin_stubs
    adu = _adu(tid, unit, _request(fc, address, count, words, read_address))
    chunks = (adu[:split], adu[split:]) if 0 < split < len(adu) else (adu,)
    assert _same_answer(hot, old, chunks)
    assert {k: v for k, v in hot_stats.items() if k != "hot_path_answers"} == dict(old_stats)


class _RawRtu:
    """A bare Modbus RTU master on a stub's pty: send a frame, read the reply (or nothing within a short wait)."""

    def __init__(self, path: str) -> None:
        self.fd = os.open(path, os.O_RDWR | os.O_NOCTTY)
        tty.setraw(self.fd)
        termios.tcflush(self.fd, termios.TCIOFLUSH)

    def ask(self, frame: bytes, wait_s: float = 0.15) -> bytes:
        os.write(self.fd, frame)
        out = b""
        deadline = time.monotonic() + wait_s
        while True:
            want = 5 if len(out) < 3 or out[1] & 0x80 else (8 if out[1] in (6, 16) else 5 + out[2])
            left = deadline - time.monotonic()
            if len(out) >= want or left <= 0 or not select.select([self.fd], [], [], left)[0]:
                return out
            out += os.read(self.fd, 512)


@pytest.fixture(scope="module")
def twin_rtu_stubs() -> Iterator[tuple[_RawRtu, _RawRtu, dict, dict]]:
    """:func:`_twins` over RTU on two ptys: a raw master on each, and their counters."""
    with _twins(rtu=True) as (hot_srv, old_srv):
        a, b = _RawRtu(hot_srv.board_path), _RawRtu(old_srv.board_path)
        yield a, b, hot_srv.stats, old_srv.stats
        os.close(a.fd)
        os.close(b.fd)


@pytest.mark.integration
@pytest.mark.slow  # ~4 s: 40 requests to two stubs on ptys, the dropped replies waited out
@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(fc=st.sampled_from([3, 4, 16, 23]), address=_ADDRESSES, count=st.integers(1, 125),
       words=st.one_of(_COMMANDS, _WORDS), read_address=_ADDRESSES)
def test_the_hot_path_answers_rtu_byte_for_byte_as_pymodbus(twin_rtu_stubs, fc, address, count, words, read_address):
    hot, old, hot_stats, old_stats = twin_rtu_stubs
    frame = rtu_adu(1, _request(fc, address, count, words, read_address))
    assert hot.ask(frame) == old.ask(frame)
    assert {k: v for k, v in hot_stats.items() if k != "hot_path_answers"} == dict(old_stats)
    assert hot_stats["hot_path_answers"] == hot_stats["requests"]


@pytest.mark.integration
def test_the_hot_path_answers_the_board_exchanges_and_leaves_the_rest_to_pymodbus(twin_stubs):
    hot, old, hot_stats, old_stats = twin_stubs
    before = hot_stats["hot_path_answers"]
    fc23 = _request(23, COMMAND_START, INPUT_COUNT, encode_command_block(ActuatorCommand(seq=20_000, v_ch1=5.0)),
                    MIRROR_START)
    cases = [
        (_adu(7, 1, fc23),),  # the board's exchange
        (_adu(8, 1, b"\x06\x00\x00\x00\x01"),),  # FC 06: pymodbus
        (_adu(9, 1, b"\x2b\x0e\x01\x00"),),  # an unknown function code: exception 01, echoing it
        (_adu(10, 1, b"\x03\x00\x00\x00\x00"),),  # a bad quantity: exception 03
        (_adu(11, 1, b"\x04\x00\x0a\x00\x01") + _adu(12, 1, b"\x04\x00\x0a\x00\x02"),),  # two at once: the newest
        (_adu(13, 7, b"\x04\x00\x0a\x00\x01"),),  # another unit: silence
    ]
    for chunks in cases:
        assert _same_answer(hot, old, chunks)
    assert {k: v for k, v in hot_stats.items() if k != "hot_path_answers"} == dict(old_stats)
    assert hot_stats["hot_path_answers"] == before + 2  # the FC 23 and the newest FC 04
    assert hot_stats["other_unit_ignored"] >= 1 and hot_stats["stale_requests_skipped"] >= 1


@pytest.mark.integration
def test_a_delay_leaves_the_request_to_pymodbus():
    """--processing-ms makes the action hook wait: such a stub answers through pymodbus, not the hot path."""
    plan = FaultPlan(link=LinkFaults(processing_s=0.001))
    with HilService(FakeRig(), mode="lockstep", plan=plan) as hil:
        srv = hil.add_modbus_tcp("127.0.0.1:0")
        raw = _Raw(srv.port)
        reply = raw.ask(_adu(1, 1, b"\x04\x00\x0a\x00\x01"))
        raw.sock.close()
    assert reply[7] == 4 and srv.stats["requests"] == 1 and srv.stats["hot_path_answers"] == 0


# ------------------------------------------------------------------------------------------ real clients
@pytest.fixture()
def realtime_stub() -> Iterator[tuple[HilService, int, dict]]:
    with HilService(FakeRig(), mode="realtime") as hil:
        srv = hil.add_modbus_tcp("127.0.0.1:0")
        yield hil, srv.port, srv.stats


@pytest.mark.integration
def test_pymodbus_client_exchanges_with_the_hot_path(realtime_stub):
    _hil, port, stats = realtime_stub
    client = ModbusTcpClient("127.0.0.1", port=port, timeout=2.0)
    assert client.connect()
    try:
        for k in range(1, 6):
            words = encode_command_block(ActuatorCommand(seq=k, v_ch1=10.0 * k, v_ch2=0.0, board_current=0.001))
            if k % 2:
                rr = client.readwrite_registers(read_address=MIRROR_START, read_count=INPUT_COUNT,
                                                write_address=COMMAND_START, values=words, device_id=1)
            else:
                assert not client.write_registers(COMMAND_START, words, device_id=1).isError()
                rr = client.read_input_registers(INPUT_START, count=INPUT_COUNT, device_id=1)
            assert not rr.isError() and len(rr.registers) == INPUT_COUNT
            assert decode_input_block(rr.registers).sample.t >= 0.0
        refused = client.read_holding_registers(200, count=2, device_id=1)  # outside the map
        assert refused.isError() and refused.exception_code == 2
        held = client.read_holding_registers(COMMAND_START, count=len(words), device_id=1)
        assert held.registers == words  # the last command block written, read back
    finally:
        client.close()
    assert stats["hot_path_answers"] == 3 + 2 * 2 + 2 and stats["commands"] == 5  # FC 23 x3, FC 16+04 x2, 2 reads


@pytest.mark.integration
@pytest.mark.skipif(shutil.which("mbpoll") is None, reason="mbpoll is not installed")
def test_mbpoll_reads_the_input_registers(realtime_stub):
    _hil, port, stats = realtime_stub
    # input registers (-t 3), 0-based references (-0), 4 from INPUT_START, one poll (-1)
    out = subprocess.run(["mbpoll", "-m", "tcp", "-p", str(port), "-a", "1", "-t", "3", "-0", "-r", str(INPUT_START),
                          "-c", "4", "-1", "127.0.0.1"], capture_output=True, text=True, timeout=20)
    assert out.returncode == 0, out.stdout + out.stderr
    assert all(f"[{INPUT_START + i}]:" in out.stdout for i in range(4)), out.stdout
    assert stats["hot_path_answers"] >= 1
