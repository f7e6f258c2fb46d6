"""A real third-party Modbus master (Debian's ``mbpoll``) reads and writes the stub's register map, over TCP
and over RTU through a ``socat`` pty pair. Skipped, with the reason printed (``-ra``), when the tools are missing;
``make setup`` installs them."""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest
from links_support import FakeRig, missing_tools, wait_for

from drivers.link import FLAG_LIMIT_REFUSED
from drivers.modbus_registers import INPUT_COUNT, MIRROR_START, encode_input_block, float32_to_registers
from hil_stub.service import HilService

pytestmark = [pytest.mark.integration,
              pytest.mark.skipif(missing_tools("mbpoll") is not None, reason=str(missing_tools("mbpoll")))]

VALUE = re.compile(r"^\[(\d+)\]:\s+(\S+)", re.M)


def mbpoll(target: list[str], *args: str, values: tuple[str, ...] = ()) -> tuple[int, dict[int, str], str]:
    """Run mbpoll once against ``target`` (connection options, then the host or device) and return
    (exit code, {reference: value}, output). Bounded by mbpoll's 0.5 s time-out and our 20 s."""
    *conn, dest = target
    cmd = ["mbpoll", *conn, "-a", "1", "-1", "-o", "0.5", *args, dest]
    if values:
        cmd += ["--", *values]  # mbpoll needs "--" before negative numbers
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=20)
    return r.returncode, {int(k): v for k, v in VALUE.findall(r.stdout)}, r.stdout + r.stderr


@pytest.fixture
def tcp_rig():
    rig = FakeRig()
    with HilService(rig, mode="lockstep") as hil:  # lock-step: the registers change only when a command is written
        srv = hil.add_modbus_tcp("127.0.0.1:0")
        yield hil, rig, ["-m", "tcp", "-p", str(srv.port), "127.0.0.1"]


def test_mbpoll_reads_the_sample_block_over_tcp(tcp_rig):
    hil, _, target = tcp_rig
    rc, vals, out = mbpoll(target, "-t", "3", "-r", "1", "-c", str(INPUT_COUNT))
    assert rc == 0, out
    snap = hil.host.snapshot
    expect = encode_input_block(snap.sample, snap.cmd_seq_applied, snap.refused_count)
    assert [int(vals[i + 1]) for i in range(INPUT_COUNT)] == expect
    assert int(vals[17]) & 0x100  # status: HV equipment present (bit 8)


def test_mbpoll_writes_a_command_and_reads_floats_back_over_tcp(tcp_rig):
    hil, rig, target = tcp_rig
    rc, _, out = mbpoll(target, "-t", "4:float", "-B", "-r", "1", values=("300", "100"))
    assert rc == 0 and "Written 2 references" in out, out
    assert (rig.applied[-1].v_ch1, rig.applied[-1].v_ch2) == (300.0, 100.0)
    rc, vals, out = mbpoll(target, "-t", "4:float", "-B", "-r", "1", "-c", "2")
    assert rc == 0 and (float(vals[1]), float(vals[3])) == (300.0, 100.0), out
    # the rig moved one tick (lock-step) under the new demand: v_patch = (300 - 100)/2, read as a float
    rc, vals, out = mbpoll(target, "-t", "3:float", "-B", "-r", "7", "-c", "2")
    assert rc == 0 and float(vals[9]) == 100.0 and float(vals[7]) == pytest.approx(hil.host.snapshot.sample.z3,
                                                                                     rel=1e-5), out
    # word order: the same two registers read raw are the big-endian float32 words
    rc, vals, _ = mbpoll(target, "-t", "4", "-r", "1", "-c", "2")
    assert [int(vals[1]), int(vals[2])] == float32_to_registers(300.0)


def test_mbpoll_sees_the_documented_exceptions_over_tcp(tcp_rig):
    hil, rig, target = tcp_rig
    rc, _, out = mbpoll(target, "-t", "4", "-r", "9", values=("5",))  # map_version: read-only
    assert rc != 0 and "Illegal data address" in out
    rc, _, out = mbpoll(target, "-t", "3", "-r", str(INPUT_COUNT + 1))  # past the end of the map
    assert rc != 0 and "Illegal data address" in out
    rc, _, out = mbpoll(target, "-t", "4:float", "-B", "-r", "1", values=("2000",))  # above +1500 V
    assert rc != 0 and "Illegal data value" in out
    assert rig.applied == [] and hil.host.snapshot.sample.flags & FLAG_LIMIT_REFUSED
    rc, vals, out = mbpoll(target, "-t", "1", "-r", "1", "-c", "4")  # discrete inputs
    assert rc == 0 and [vals[i] for i in (1, 2, 3, 4)] == ["1", "0", "1", "0"], out


@pytest.fixture
def socat_pair(tmp_path: Path):
    reason = missing_tools("socat")
    if reason:
        pytest.skip(reason)
    a, b = tmp_path / "rig", tmp_path / "board"
    proc = subprocess.Popen(["socat", f"pty,raw,echo=0,link={a}", f"pty,raw,echo=0,link={b}"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        assert wait_for(lambda: a.exists() and b.exists(), timeout=5), "socat did not create the pty pair"
        yield str(a), str(b)
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout=5)


def test_mbpoll_over_rtu_through_a_socat_pty_pair(socat_pair):
    rig_end, board_end = socat_pair
    rig = FakeRig()
    with HilService(rig, mode="lockstep") as hil:
        hil.add_modbus_rtu(rig_end, baudrate=115200, parity="N")
        target = ["-m", "rtu", "-b", "115200", "-P", "none", board_end]
        rc, vals, out = mbpoll(target, "-t", "3", "-r", "1", "-c", str(INPUT_COUNT))
        assert rc == 0, out
        snap = hil.host.snapshot
        assert [int(vals[i + 1]) for i in range(INPUT_COUNT)] == encode_input_block(
            snap.sample, snap.cmd_seq_applied, snap.refused_count)
        rc, _, out = mbpoll(target, "-t", "4:float", "-B", "-r", "3", values=("-250",))
        assert rc == 0, out
        assert rig.applied[-1].v_ch2 == -250.0
        rc, _, out = mbpoll(target, "-t", "4", "-r", "11", values=("1",))  # v_limit_min: read-only
        assert rc != 0 and "Illegal data address" in out
        rc, _, out = mbpoll(target, "-t", "4:float", "-B", "-r", "1", values=("1501",))
        assert rc != 0 and "Illegal data value" in out


def test_mbpoll_reads_the_sample_mirror_of_map_version_2_over_tcp(tcp_rig):
    """The sample mirror (holding 100-121, what FC 23 reads) is the input block again; FC 03 reads it, a write to
    it is refused (issue 29, point 3)."""
    hil, _, target = tcp_rig
    rc, vals, out = mbpoll(target, "-t", "4", "-r", str(MIRROR_START + 1), "-c", str(INPUT_COUNT))
    assert rc == 0, out
    snap = hil.host.snapshot
    assert [int(vals[MIRROR_START + 1 + i]) for i in range(INPUT_COUNT)] == encode_input_block(
        snap.sample, snap.cmd_seq_applied, snap.refused_count)
    rc, vals, out = mbpoll(target, "-t", "4", "-r", "9", "-c", "1")  # map_version
    assert rc == 0 and int(vals[9]) == 2, out
    rc, _, out = mbpoll(target, "-t", "4", "-r", str(MIRROR_START + 1), values=("1",))
    assert rc != 0 and "Illegal data address" in out
