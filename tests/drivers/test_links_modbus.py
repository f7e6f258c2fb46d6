"""ModbusLink and the rig's Modbus server (pymodbus 3.16) over loopback TCP and a pty (RTU): round trips,
exception replies, unit-id silence, refused set-points, faults, a restarting server. Ports are always 0."""

from __future__ import annotations

import pytest
from links_support import FakeRig, cmd, exchange_errors, first_reply, lockstep_stub, outcomes_through_injected_outage
from pymodbus.client import ModbusSerialClient, ModbusTcpClient
from pymodbus.exceptions import ModbusIOException
from pymodbus.framer import FramerType

from drivers import LinkError, open_link
from drivers.link import FLAG_LIMIT_REFUSED
from drivers.modbus_link import ModbusLink, parse_modbus_url
from drivers.modbus_registers import BY_NAME as R
from drivers.modbus_registers import (
    INPUT_COUNT,
    decode_input_block,
    decode_value,
    encode_command_block,
    float32_to_registers,
    registers_to_float32,
)
from hil_stub.faults import FaultPlan, LinkFaults
from hil_stub.service import HilService

pytestmark = pytest.mark.integration


def test_url_parsing_and_errors():
    s = parse_modbus_url("modbus-tcp://127.0.0.1:5020?unit=3&timeout=0.1")
    assert (s["kind"], s["host"], s["port"], s["unit"], s["timeout"]) == ("tcp", "127.0.0.1", 5020, 3, 0.1)
    s = parse_modbus_url("modbus-rtu:/dev/ttyUSB1?baud=19200&parity=E")
    assert (s["port"], s["baud"], s["parity"]) == ("/dev/ttyUSB1", 19200, "E")
    assert s["timeout"] == pytest.approx(0.008 + 2 * 90 * 11 / 19200)  # a line too slow for the tick: 8 ms + 2x line
    # fits one tick with the board's own work: a give-up at 8.5 ms leaves the tick on time
    assert parse_modbus_url("modbus-rtu:/dev/x?baud=115200")["timeout"] == pytest.approx(0.0085)
    assert parse_modbus_url("modbus-rtu:/dev/x?baud=230400")["timeout"] == pytest.approx(0.008)
    assert parse_modbus_url("modbus-tcp://h:1")["timeout"] == 0.008  # one exchange fits a 10 ms tick
    assert isinstance(open_link("modbus-tcp://127.0.0.1:1"), ModbusLink)
    assert isinstance(open_link("modbus-rtu:/dev/null"), ModbusLink)
    for bad, msg in [("modbus-tcp://:502", "HOST:PORT"), ("modbus-tcp://h:5?unit=300", "unit=300"),
                     ("modbus-tcp://h:5?speed=1", "unknown option"), ("modbus-rtu:", "PATH"),
                     ("modbus-rtu:/dev/x?parity=Q", "parity")]:
        with pytest.raises(ValueError, match=msg):
            parse_modbus_url(bad)


def test_open_without_a_server_is_a_link_error():
    with pytest.raises(LinkError, match="cannot connect"):
        ModbusLink("modbus-tcp://127.0.0.1:1?timeout=0.1").open()


@pytest.fixture
def tcp_lockstep():
    yield from lockstep_stub("modbus-tcp")


@pytest.fixture
def raw_client(tcp_lockstep):
    _, srv, _ = tcp_lockstep
    c = ModbusTcpClient("127.0.0.1", port=srv.port, timeout=0.3, retries=0)
    assert c.connect()
    yield c
    c.close()


def test_lockstep_round_trip(tcp_lockstep):
    _hil, srv, rig = tcp_lockstep
    assert srv.port != 0
    with open_link(srv.board_url + "&timeout=0.5") as link:
        samples = [link.exchange(cmd(k)) for k in range(1, 41)]
    assert [s.seq for s in samples] == list(range(1, 41))  # one tick per command (reads do not advance)
    assert samples[-1].v_patch == pytest.approx(100.0) and samples[-1].hv_present
    assert [c.seq for c in rig.applied] == list(range(1, 41))
    assert link.stats["seq_mismatch"] == 0


def test_exception_replies_and_no_partial_writes(tcp_lockstep, raw_client):
    hil, _srv, rig = tcp_lockstep
    c = raw_client
    assert not c.read_input_registers(0, count=INPUT_COUNT, device_id=1).isError()
    # out of the map
    rr = c.read_input_registers(20, count=5, device_id=1)
    assert rr.isError() and rr.exception_code == 2
    assert c.read_holding_registers(14, count=1, device_id=1).exception_code == 2
    # read-only holding registers and the read-only coil
    assert c.write_register(8, 7, device_id=1).exception_code == 2
    assert c.write_registers(10, float32_to_registers(-2000.0), device_id=1).exception_code == 2
    assert c.write_coil(0, True, device_id=1).exception_code == 2
    # a write that splits a float
    assert c.write_register(1, 0, device_id=1).exception_code == 2
    # a good command, then an out-of-limit one: refused with 03, nothing changes
    assert not c.write_registers(0, encode_command_block(cmd(5, 300.0, 0.0)), device_id=1).isError()
    rr = c.write_registers(0, encode_command_block(cmd(6, 1500.5, 0.0)), device_id=1)
    assert rr.exception_code == 3
    hold = c.read_holding_registers(0, count=14, device_id=1).registers
    assert registers_to_float32(hold[0:2]) == 300.0 and decode_value(R["cmd_seq"], hold[6:8]) == 5
    assert decode_value(R["map_version"], hold[8:9]) == 2 and decode_value(R["rig_tick"], hold[9:10]) == 0.01
    assert [a.seq for a in rig.applied] == [5]
    blk = decode_input_block(c.read_input_registers(0, count=INPUT_COUNT, device_id=1).registers)
    assert blk.sample.flags & FLAG_LIMIT_REFUSED and blk.refused_count == 1 and blk.cmd_seq_applied == 5
    assert blk.sample.v_patch == pytest.approx(150.0)  # (300 - 0) / 2: the last accepted command
    bits = c.read_discrete_inputs(0, count=4, device_id=1).bits[:4]
    assert bits == [True, False, True, False]  # hv present, limit refused
    assert c.read_coils(0, count=1, device_id=1).bits[0] is True  # amplifier active
    # NaN set-point: refused before it reaches the rig (not counted, issue 33)
    assert c.write_registers(2, [0x7FC0, 0], device_id=1).exception_code == 3
    assert hil.host.refused_count == 1


def test_other_unit_ids_get_silence(tcp_lockstep, raw_client):
    c = raw_client
    with pytest.raises(ModbusIOException):
        c.read_input_registers(0, count=2, device_id=7)
    # after the silence the connection still serves our unit; 255 ("not significant") is answered on TCP
    c.close()
    assert c.connect()
    assert not c.read_input_registers(0, count=2, device_id=1).isError()
    assert not c.read_input_registers(0, count=2, device_id=255).isError()
    assert tcp_lockstep[1].stats["other_unit_ignored"] == 1


def test_refused_set_point_reaches_the_board_as_a_flag_not_an_error(tcp_lockstep):
    _hil, srv, rig = tcp_lockstep
    with open_link(srv.board_url + "&timeout=0.5") as link:
        link.exchange(cmd(1, 200.0, 0.0))
        s = link.exchange(cmd(2, -600.0, 0.0))
        assert s.flags & FLAG_LIMIT_REFUSED and s.v_patch == pytest.approx(100.0)
        assert not link.exchange(cmd(3, 0.0, 0.0)).flags & FLAG_LIMIT_REFUSED
    assert link.stats["refused"] == 1 and [a.seq for a in rig.applied] == [1, 3]


def test_server_restart_and_outage_are_survived(tcp_lockstep):
    _hil, srv, _ = tcp_lockstep
    link = open_link(srv.board_url + "&timeout=0.2")
    link.open()
    try:
        link.exchange(cmd(1))
        srv.restart()
        assert first_reply(link, range(2, 300)) is not None  # bounded; the back-off is at most 64 calls
        srv.loop.run(srv._stop_server())  # down for good: every exchange a LinkError, quickly
        errors = len(exchange_errors(link, range(300, 340)))
        assert errors == 40 and link.stats["down_exchanges"] > 10  # most calls never touch the socket
        srv.loop.run(srv._start())
        assert first_reply(link, range(340, 700)) is not None
    finally:
        link.close()
    assert link.stats["link_down"] >= 2 and link.stats["reconnected"] >= 2


def test_wire_faults_give_only_link_errors():
    plan = FaultPlan(link=LinkFaults(drop=0.2, corrupt=0.2), seed=11)
    with HilService(FakeRig(), mode="lockstep", plan=plan) as hil:
        srv = hil.add_modbus_tcp("127.0.0.1:0")
        link = ModbusLink(srv.board_url + "&timeout=0.05&reopen=100000")
        ok = fail = 0
        for _ in range(20):  # open() itself may hit a dropped reply
            try:
                link.open()
                break
            except LinkError:
                pass
        try:
            fail = len(exchange_errors(link, range(1, 101)))  # nothing but LinkErrors escapes
            ok = 100 - fail
        finally:
            link.close()
    # two transactions per exchange, each lost with probability 0.4: about 64 % of exchanges fail
    assert ok + fail == 100 and 35 <= fail <= 90
    assert srv.stats["replies_dropped"] >= 5 and srv.stats["replies_corrupted"] >= 5


def test_rtu_over_a_pty():
    rig = FakeRig()
    with HilService(rig, mode="lockstep", plan=FaultPlan(link=LinkFaults(corrupt=0.0))) as hil:
        srv = hil.add_modbus_rtu("pty")
        assert srv.board_url.startswith("modbus-rtu:") and "baud=115200" in srv.board_url
        with open_link(srv.board_url + "&timeout=0.5") as link:
            samples = [link.exchange(cmd(k)) for k in range(1, 21)]
        assert [s.seq for s in samples] == list(range(1, 21))
        c = ModbusSerialClient(srv.board_path, framer=FramerType.RTU, baudrate=115200, timeout=0.3, retries=0)
        assert c.connect()
        try:
            assert c.read_input_registers(21, count=2, device_id=1).exception_code == 2
            assert c.write_registers(0, encode_command_block(cmd(99, 1501.0, 0.0)), device_id=1).exception_code == 3
            with pytest.raises(ModbusIOException):  # another unit on the line: silence
                c.read_input_registers(0, count=2, device_id=9)
            assert not c.read_input_registers(0, count=2, device_id=1).isError()
        finally:
            c.close()
    assert [a.seq for a in rig.applied] == list(range(1, 21))


def test_rtu_corrupted_replies_fail_the_crc():
    with HilService(FakeRig(), mode="lockstep", plan=FaultPlan(link=LinkFaults(corrupt=1.0), seed=2)) as hil:
        srv = hil.add_modbus_rtu("pty")
        link = ModbusLink(srv.board_url + "&timeout=0.05")
        with pytest.raises(LinkError, match="no valid reply"):
            link.open()
        link.close()
        assert srv.stats["replies_corrupted"] >= 1


def test_rtu_late_reply_arriving_with_the_real_one_costs_nothing():
    """A late FC 04 reply (of an exchange that gave up) and the FC 16 reply to the current write arrive in one read:
    the late frame is skipped and the real one taken (pymodbus' framer took the first and threw the second away, so
    one late reply cost two exchanges); a reply split over two reads is joined within the one deadline."""
    import os
    import threading
    from collections import Counter

    from pymodbus.framer.rtu import FramerRTU

    from drivers.modbus_rtu_client import RtuClient

    def frame(*body: int) -> bytes:
        b = bytes(body)
        return b + FramerRTU.compute_CRC(b).to_bytes(2, "big")

    master, slave = os.openpty()
    stats: Counter[str] = Counter()
    c = RtuClient(os.ttyname(slave), framer=FramerType.RTU, baudrate=115200, timeout=0.5, retries=0, stats=stats)
    late = frame(1, 0x04, 44, *([0] * 44))
    ack = frame(1, 0x10, 0, 0, 0, 8)

    def rig(replies: list[list[bytes]]) -> None:
        for chunks in replies:
            os.read(master, 256)  # the request
            for chunk in chunks:
                os.write(master, chunk)
                threading.Event().wait(0.01)

    try:
        assert c.connect()
        t = threading.Thread(target=rig, args=([[late + ack], [ack[:3], ack[3:]]],), daemon=True)
        t.start()
        for _ in range(2):
            rr = c.write_registers(0, [0] * 8, device_id=1)
            assert not rr.isError() and rr.function_code == 0x10 and rr.count == 8
        t.join(1.0)
        assert stats["stale_skipped"] == 1
    finally:
        c.close()
        os.close(master)
        os.close(slave)


def test_injected_disconnect_at_a_rig_time_then_back():
    outcomes, stats = outcomes_through_injected_outage("modbus-tcp", "&timeout=0.05")
    assert False in outcomes and outcomes[-1] is True and outcomes.index(False) >= 9
    assert stats["disconnects"] == 1


def _mbap(tid: int, unit: int, pdu: bytes) -> bytes:
    import struct

    return struct.pack(">HHHB", tid, 0, len(pdu) + 1, unit) + pdu


@pytest.mark.parametrize(("pdu", "reply"), [
    (bytes([0x04, 0, 0, 0, 200]), bytes([0x84, 0x03])),  # quantity above 125
    (bytes([0x03, 0, 0, 0, 0]), bytes([0x83, 0x03])),  # quantity 0
    (bytes([0x10, 0, 0, 0, 2, 3, 1, 2, 3]), bytes([0x90, 0x03])),  # byte count does not match the quantity
    (bytes([0x41, 0, 0]), bytes([0xC1, 0x01])),  # unknown function code
])
def test_malformed_requests_get_the_matching_exception_over_tcp(tcp_lockstep, pdu, reply):
    import socket

    _, srv, rig = tcp_lockstep
    with socket.create_connection(("127.0.0.1", srv.port), timeout=1.0) as s:
        s.sendall(_mbap(7, 1, pdu))
        assert s.recv(64) == _mbap(7, 1, reply)[:6] + bytes([1]) + reply
        s.sendall(_mbap(8, 1, bytes([0x04, 0, 0, 0, 2])))  # the connection still serves good requests
        assert s.recv(64)[7:9] == bytes([0x04, 4])
    assert rig.applied == []


def test_malformed_requests_get_the_matching_exception_over_rtu():
    import serial as pyserial
    from pymodbus.framer.rtu import FramerRTU

    def frame(b: bytes) -> bytes:
        return b + FramerRTU.compute_CRC(b).to_bytes(2, "big")

    with HilService(FakeRig(), mode="lockstep") as hil:
        srv = hil.add_modbus_rtu("pty")
        port = pyserial.serial_for_url(srv.board_path, baudrate=115200, timeout=0.5)
        try:
            for req, want in [(bytes([1, 0x04, 0, 0, 0, 200]), bytes([1, 0x84, 0x03])),
                              (bytes([1, 0x41, 0, 0]), bytes([1, 0xC1, 0x01]))]:
                port.reset_input_buffer()
                port.write(frame(req))
                assert port.read(5) == frame(want)
            port.write(frame(bytes([9, 0x41, 0, 0])))  # another unit: silence
            assert port.read(5) == b""
        finally:
            port.close()


def test_one_budget_covers_both_transactions():
    """A slow write leaves the read only what is left of the exchange's budget."""
    import re

    plan = FaultPlan(link=LinkFaults(processing_s=0.1), seed=1)  # every transaction takes 100 ms
    with HilService(FakeRig(), mode="lockstep", plan=plan) as hil:
        srv = hil.add_modbus_tcp("127.0.0.1:0")
        ok = ModbusLink(srv.board_url + "&timeout=1.0")
        ok.open()
        try:
            assert ok.exchange(cmd(1)).seq == 1  # 2 x 100 ms within 1 s
        finally:
            ok.close()
        # 150 ms: the write (100 ms plus whatever the machine adds, up to 50 ms) fits, the read cannot
        tight = ModbusLink(srv.board_url + "&timeout=0.15")
        tight._bring_up()  # connect without the start-up checks
        try:
            with pytest.raises(LinkError, match="read sample") as err:
                tight.exchange(cmd(2))
            # the message quotes the read's real budget and what the write used, not a bare leftover
            said = str(err.value)
            assert "of the 150.0 ms exchange budget" in said
            took = re.search(r"the command write took ([0-9.]+) ms", said)
            assert took is not None and 100.0 <= float(took.group(1)) < 150.0, said
        finally:
            tight.close()


def test_an_exchange_past_its_budget_is_counted_and_says_where_its_time_went(tcp_lockstep, caplog):
    """The budget is what keeps the board's tick: an exchange that overruns it (here a read call stalled in the board's
    own process, as a descheduled process would be) is counted and logged with its transactions."""
    import time

    _hil, srv, _rig = tcp_lockstep
    link = ModbusLink(srv.board_url + "&timeout=0.05&fc23=0")  # the two transactions of a rig without FC 23
    link.open()
    try:
        link.exchange(cmd(1))
        assert link.stats["over_budget"] == 0
        assert [p[0] for p in link.last_phases] == ["write command (FC16)", "read sample (FC04)"]
        assert all(0 <= start and 0 <= took <= budget for _, start, took, budget in link.last_phases)
        real = link._client.read_input_registers

        def stalled(*args, **kwargs):
            time.sleep(0.08)
            return real(*args, **kwargs)

        link._client.read_input_registers = stalled
        with caplog.at_level("WARNING", logger="drivers.modbus_link"):
            link.exchange(cmd(2))
        assert link.stats["over_budget"] == 1
        (what, start, took, budget) = link.last_phases[-1]
        assert start > 0
        assert what == "read sample (FC04)" and took >= 0.08 and budget < 0.05
        msg = next(r.getMessage() for r in caplog.records if "over its" in r.getMessage())
        assert "over its 50.00 ms budget" in msg and "read sample (FC04) at" in msg and "write command (FC16)" in msg
    finally:
        link.close()
