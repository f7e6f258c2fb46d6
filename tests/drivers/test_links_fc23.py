"""One transaction per tick where the rig allows it (issue 29, point 3), over a real loopback socket.

A rig announcing register map version 2 at the handshake serves the sample mirror (holding 100–121) and FC 23: the
board writes the command and reads the sample in one round trip, and that transaction gets the whole exchange
budget. A rig announcing version 1 gets FC 16 + FC 04, as before. The stub refuses what the map does not allow: an
FC 23 or FC 22 write of a non-finite demand or of part of a value, a write to the mirror, an unmapped function
code (FC 21 -> exception 01).
"""

from __future__ import annotations

import socket
import struct

import pytest
from links_support import FakeRig, cmd, exchange_errors
from pymodbus.client import ModbusTcpClient

from drivers import open_link
from drivers.link import FLAG_LIMIT_REFUSED
from drivers.modbus_registers import (
    INPUT_COUNT,
    MIRROR_START,
    decode_input_block,
    encode_command_block,
    encode_input_block,
)
from hil_stub.faults import FaultPlan, LinkFaults
from hil_stub.service import HilService


@pytest.fixture(params=[2, 1], ids=["map-v2", "map-v1"])
def served(request):
    rig = FakeRig()
    with HilService(rig, mode="lockstep") as hil:
        srv = hil.add_modbus_tcp("127.0.0.1:0", map_version=request.param)
        yield hil, srv, rig, request.param


def test_the_board_uses_fc23_when_the_rig_announces_it_and_falls_back_otherwise(served):
    _hil, srv, rig, version = served
    with open_link(srv.board_url + "&timeout=0.5") as link:
        samples = [link.exchange(cmd(k, 100.0 + k, -100.0)) for k in range(1, 31)]
        phases = [p[0] for p in link.last_phases]
        assert link.map_version == version and link.fc23 is (version == 2)
        assert link.processing_budget == pytest.approx(0.5 if version == 2 else 0.25)
    if version == 2:
        assert phases == ["write command, read sample (FC23)"]
        assert srv.stats["fc23_exchanges"] == 30 and srv.stats["reads"] == 31  # + the sample read at open
    else:
        assert phases == ["write command (FC16)", "read sample (FC04)"] and srv.stats["fc23_exchanges"] == 0
    # lock-step: each exchange's sample is the rig one tick after that exchange's command, whichever way
    assert [c.seq for c in rig.applied] == list(range(1, 31))
    assert [s.t for s in samples] == pytest.approx([0.01 * k for k in range(1, 31)])
    assert [s.v_patch for s in samples] == pytest.approx([100.0 + k / 2 for k in range(1, 31)])


def test_a_refused_command_over_fc23_still_returns_the_sample_with_the_flag():
    with HilService(FakeRig(), mode="lockstep") as hil:
        srv = hil.add_modbus_tcp("127.0.0.1:0")
        with open_link(srv.board_url + "&timeout=0.5") as link:
            ok = link.exchange(cmd(1, 200.0, 0.0))
            refused = link.exchange(cmd(2, 1500.5, 0.0))
            assert link.fc23 and not ok.flags & FLAG_LIMIT_REFUSED and refused.flags & FLAG_LIMIT_REFUSED
            assert link.stats["refused"] == 1 and link.last_phases[0][0].endswith("(FC23)")


def test_fc23_gives_one_transaction_the_whole_exchange_budget():
    """A rig taking 4.5 ms per transaction: two of them do not fit the 8 ms exchange (see test_links_startup), one
    FC 23 does."""
    plan = FaultPlan(link=LinkFaults(processing_s=0.0045), seed=1)
    with HilService(FakeRig(), mode="realtime", plan=plan) as hil:
        srv = hil.add_modbus_tcp("127.0.0.1:0")
        link = open_link(srv.board_url)
        link.open()
        try:
            errors = exchange_errors(link, range(1, 31))
            assert link.fc23 and link.processing_budget == pytest.approx(0.008)
        finally:
            link.close()
    assert len(errors) <= 10, errors[:3]  # timeouts only from a loaded machine's scheduling


def _raw(port: int, pdu: bytes, tid: int = 7) -> bytes:
    """Send one Modbus TCP request (unit 1) and return the reply PDU."""
    with socket.create_connection(("127.0.0.1", port), timeout=1.0) as s:
        s.sendall(struct.pack(">HHHB", tid, 0, len(pdu) + 1, 1) + pdu)
        head = s.recv(7)
        (_tid, _pid, length, _unit) = struct.unpack(">HHHB", head)
        body = b""
        while len(body) < length - 1:
            body += s.recv(length - 1 - len(body))
        return body


def _fc23(read_addr: int, read_n: int, write_addr: int, words: list[int]) -> bytes:
    return struct.pack(">BHHHHB", 23, read_addr, read_n, write_addr, len(words), 2 * len(words)) + \
        b"".join(struct.pack(">H", w) for w in words)


def test_the_stub_refuses_what_the_map_does_not_allow():
    rig = FakeRig()
    with HilService(rig, mode="lockstep") as hil:
        srv = hil.add_modbus_tcp("127.0.0.1:0")
        good = encode_command_block(cmd(5, 300.0, 0.0))
        reply = _raw(srv.port, _fc23(MIRROR_START, INPUT_COUNT, 0, good))
        assert reply[:2] == bytes([23, 2 * INPUT_COUNT])
        block = decode_input_block(list(struct.unpack(f">{INPUT_COUNT}H", reply[2:])))
        assert block.cmd_seq_applied == 5 and block.sample.v_patch == 150.0
        snap = hil.host.snapshot
        assert list(struct.unpack(f">{INPUT_COUNT}H", reply[2:])) == encode_input_block(
            snap.sample, snap.cmd_seq_applied, snap.refused_count)
        nan = list(good)
        nan[0:2] = [0x7FC0, 0x0000]  # a float32 NaN (encode_value would write 0)
        assert _raw(srv.port, _fc23(MIRROR_START, INPUT_COUNT, 0, nan)) == bytes([23 | 0x80, 3])
        assert _raw(srv.port, _fc23(MIRROR_START, INPUT_COUNT, 1, good[1:3])) == bytes([23 | 0x80, 2])  # splits
        assert _raw(srv.port, _fc23(MIRROR_START, INPUT_COUNT, MIRROR_START, [0, 0])) == bytes([23 | 0x80, 2])
        assert _raw(srv.port, _fc23(MIRROR_START, 0, 0, good)) == bytes([23 | 0x80, 3])  # read quantity 0
        # FC 22 (mask write) on one register of a float always splits it; on a read-only register: 02
        assert _raw(srv.port, struct.pack(">BHHH", 22, 0, 0x0000, 0x7FC0)) == bytes([22 | 0x80, 2])
        assert _raw(srv.port, struct.pack(">BHHH", 22, 8, 0xFFFF, 0x0000)) == bytes([22 | 0x80, 2])
        # unmapped function codes: 01 (FC 21 write file record, FC 43 device identification, FC 8 diagnostics)
        assert _raw(srv.port, bytes([21, 7, 6, 0, 4, 0, 0, 0, 1, 0, 0])) == bytes([21 | 0x80, 1])
        assert _raw(srv.port, bytes([43, 14, 1, 0])) == bytes([43 | 0x80, 1])
        assert _raw(srv.port, bytes([8, 0, 0, 0x12, 0x34])) == bytes([8 | 0x80, 1])
        assert [c.seq for c in rig.applied] == [5]  # nothing refused reached the rig
        c = ModbusTcpClient("127.0.0.1", port=srv.port, timeout=0.5, retries=0)
        assert c.connect()
        try:  # the mirror reads with FC 03 too (the NaN command never reached the rig: not counted, no tick)
            rr = c.read_holding_registers(MIRROR_START, count=INPUT_COUNT, device_id=1)
            snap = hil.host.snapshot
            assert rr.registers == encode_input_block(snap.sample, snap.cmd_seq_applied, snap.refused_count)
            assert snap.refused_count == 0 and snap.tick == 1
        finally:
            c.close()


def test_a_version_1_rig_has_no_mirror():
    with HilService(FakeRig(), mode="lockstep") as hil:
        srv = hil.add_modbus_tcp("127.0.0.1:0", map_version=1)
        good = encode_command_block(cmd(5, 300.0, 0.0))
        assert _raw(srv.port, _fc23(MIRROR_START, INPUT_COUNT, 0, good)) == bytes([23 | 0x80, 2])


def test_of_requests_arriving_together_the_stub_answers_the_newest():
    """A board that gave up on a late reply sends its next request; when the stub, descheduled, reads both at once,
    it answers the newest (pymodbus alone answered the first — which the board had given up on — and dropped the
    other, costing a second exchange)."""
    rig = FakeRig()
    with HilService(rig, mode="realtime") as hil:
        srv = hil.add_modbus_tcp("127.0.0.1:0")

        def mbap(tid: int, k: int) -> bytes:
            pdu = _fc23(MIRROR_START, INPUT_COUNT, 0, encode_command_block(cmd(k)))
            return struct.pack(">HHHB", tid, 0, len(pdu) + 1, 1) + pdu

        with socket.create_connection(("127.0.0.1", srv.port), timeout=1.0) as s:
            s.sendall(mbap(11, 1) + mbap(12, 2))
            head = s.recv(7)
            assert struct.unpack(">H", head[:2])[0] == 12
            body = s.recv(256)
            block = decode_input_block(list(struct.unpack(f">{INPUT_COUNT}H", body[2:2 + 2 * INPUT_COUNT])))
            assert block.cmd_seq_applied == 2
            s.sendall(mbap(13, 3))  # and the next one is answered as usual
            assert struct.unpack(">H", s.recv(7)[:2])[0] == 13
        assert srv.stats["stale_requests_skipped"] == 1


def test_a_deadline_already_past_never_loses_the_link():
    """Under load the board's process can be descheduled past an exchange's deadline before its request goes out;
    the budget left is then negative. pymodbus took a negative timeout for a closed connection and could not connect
    again (its connect uses the same setting): the link was lost for the rest of the run. Now that exchange fails
    alone and the next one works; a reconnect always gets the link's own budget."""
    import time

    from drivers.link import LinkError
    from drivers.modbus_fc23 import exchange_fc23

    with HilService(FakeRig(), mode="lockstep") as hil:
        srv = hil.add_modbus_tcp("127.0.0.1:0")
        with open_link(srv.board_url + "&timeout=0.5") as link:
            assert link.exchange(cmd(1)).t == pytest.approx(0.01)
            with pytest.raises(LinkError, match="no time left"):
                exchange_fc23(link, encode_command_block(cmd(2)), 2, time.monotonic() - 0.003)
            link._set_timeout(-0.003)  # what a late "what is left" budget used to leave in pymodbus' settings
            assert link.exchange(cmd(3)).t == pytest.approx(0.02)
            assert link.stats["link_down"] == 0
            link._drop_transport()
            link._set_timeout(-0.003)
            link._open_transport()  # a reconnect: its own budget, not the negative one
            assert link.exchange(cmd(4)).t == pytest.approx(0.03)
