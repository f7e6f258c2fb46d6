"""The rig side's bad-input corpus of issue 33 (``tests/bad_inputs_newer_rig.py``): link URLs for every scheme and
`shm hil serve` options, run in-process like ``tests/shm_cli/test_bad_inputs.py`` (exit 2, one ``error:`` line naming
the URL
part or option and what is allowed, no traceback, nothing built); bad writes to the Modbus map answered with the
documented exception over TCP and RTU, without the rig noticing anything but a finite out-of-range demand."""

from __future__ import annotations

import os
import socket
import struct
import termios
import tty
from pathlib import Path

import pytest
from bad_inputs_newer_rig import REGISTER_CASES, RegisterCase, newer_rig_cases
from bad_inputs_support import no_leftover_log_handlers, run_shm, run_to_one_clear_line  # noqa: F401 (autouse fixture)
from links_support import FakeRig, rtu_crc

from hil_stub.service import HilService

CASES = newer_rig_cases()


@pytest.fixture(scope="module")
def corpus(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("bad_inputs_newer_rig")


def test_the_corpus_covers_every_scheme_and_the_register_map() -> None:
    assert len(CASES) >= 60 and len(REGISTER_CASES) >= 30
    links = " ".join(a for c in CASES for a in c.argv)
    for scheme in ("modbus-tcp://", "modbus-rtu:", "socket://", "rfc2217://", "serial:", "sim:", "sim://", "ftp://"):
        assert scheme in links, scheme
    assert {c.argv[0] for c in CASES} == {"run", "hil"}


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_bad_rig_input_is_one_clear_line(case, corpus: Path, capsys, monkeypatch) -> None:
    run_to_one_clear_line(case, corpus, capsys, monkeypatch)
    out = corpus / "out" / case.id
    assert not (out / "usage.db").exists()  # refused before the run started: nothing written


# ------------------------------------------------------------------------------------------------------------
# the register map, over TCP and RTU
def _tcp(port: int, pdu: bytes) -> bytes:
    with socket.create_connection(("127.0.0.1", port), timeout=2.0) as s:
        s.sendall(struct.pack(">HHHB", 0x1234, 0, len(pdu) + 1, 1) + pdu)
        buf = b""
        while len(buf) < 7 or len(buf) < 6 + struct.unpack(">H", buf[4:6])[0]:
            chunk = s.recv(512)
            if not chunk:
                break
            buf += chunk
    assert buf[:2] == b"\x12\x34", buf
    return buf[7:]


def _rtu(fd: int, pdu: bytes) -> bytes:
    import select

    termios.tcflush(fd, termios.TCIFLUSH)
    frame = bytes([1]) + pdu
    os.write(fd, frame + rtu_crc(frame))
    buf = b""
    while len(buf) < 5 and select.select([fd], [], [], 2.0)[0]:
        buf += os.read(fd, 256)
    assert len(buf) >= 5 and buf[3:5] == rtu_crc(buf[:3]), buf
    return buf[1:3]


def _rig_state(hil: HilService) -> tuple:
    h = hil.host
    return h.refused_count, h.board_runs, h.commands, h.accepted_seq, h.snapshot.tick


@pytest.fixture(scope="module")
def stub():
    rig = FakeRig()
    with HilService(rig, mode="lockstep") as hil:
        tcp = hil.add_modbus_tcp("127.0.0.1:0")
        rtu = hil.add_modbus_rtu("pty")
        fd = os.open(rtu.board_path, os.O_RDWR | os.O_NOCTTY)
        tty.setraw(fd)
        try:
            yield hil, rig, tcp.port, fd
        finally:
            os.close(fd)


@pytest.mark.integration
@pytest.mark.parametrize("link", ["tcp", "rtu"])
@pytest.mark.parametrize("rc", REGISTER_CASES, ids=[c.id for c in REGISTER_CASES])
def test_a_bad_register_write_gets_the_documented_exception(rc: RegisterCase, link: str, stub) -> None:
    hil, rig, port, fd = stub
    before, applied = _rig_state(hil), len(rig.applied)
    reply = _tcp(port, rc.pdu) if link == "tcp" else _rtu(fd, rc.pdu)
    assert reply[:2] == bytes([(rc.pdu[0] | 0x80) & 0xFF, rc.exception]), (reply.hex(), rc)
    after = _rig_state(hil)
    assert len(rig.applied) == applied  # nothing refused was ever applied
    if rc.reaches_rig:  # a finite demand outside Table 1: the rig refuses and counts it (docs/registers.md)
        assert after[0] == before[0] + 1
    else:
        assert after == before, (before, after)
