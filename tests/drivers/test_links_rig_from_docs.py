"""A rig built from the interface documents alone (issue 12, point 9).

This file does what a CompactRIO programmer would do with ``docs/protocol.md`` and ``docs/registers.md``: it
implements the rig side of both protocols from the tables in those pages — the CRC-16/CCITT-FALSE, the frame layout
and the SAMPLE/PONG payloads of the serial protocol over a pty; the MBAP header, FC 03/04/16 and the register map of
Modbus TCP over a socket — **without importing ``hil_stub`` or ``drivers``** (the physics of the laminate comes from
``plant``, standing in for the real laminate on the bench). The rig follows the documented rules: channel demands
are per channel (the patches see ``(v_ch1 - v_ch2) / 2`` differentially), the amplifier slews linearly over one tick,
a COMMAND acts over the rig's next tick, the rig clock starts at the first command, ``rig_seq`` advances once per
tick, base acceleration excludes gravity, floats in Modbus are ABCD. The board (``firmware_sim``, through
``drivers.open_link``) then runs a maintenance visit (MBIT.b) against it in lock-step (the rig advances one tick per
command, the board in virtual time) and must reach the in-process verdict.
"""

from __future__ import annotations

import os
import socket
import struct
import threading
import tty

import numpy as np
import pytest

from plant import PlantModel
from plant.stepper import PlantStepper

pytestmark = pytest.mark.integration

TICK = 0.01  # s (docs/protocol.md: one exchange per 100 Hz board tick; registers.md: rig_tick 100 x 0.1 ms)
V_MIN, V_MAX = -500.0, 1500.0  # V per channel (protocol.md / registers.md: Table 1)


def crc16_ccitt_false(data: bytes) -> int:
    """protocol.md: polynomial 0x1021, initial value 0xFFFF, no reflection, no final XOR."""
    crc = 0xFFFF
    for byte in data:
        crc ^= byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) & 0xFFFF if crc & 0x8000 else (crc << 1) & 0xFFFF
    return crc


def frame(msg_type: int, seq: int, payload: bytes) -> bytes:
    """protocol.md, frame layout: A5 5A | N | type | seq (u32 LE) | payload | CRC (LE) over bytes 2 .. 8+N-1."""
    body = struct.pack("<BBI", len(payload), msg_type, seq) + payload
    return b"\xa5\x5a" + body + struct.pack("<H", crc16_ccitt_false(body))


class DocRig:
    """The physical side: an amplifier (two channels, per-channel demand, linear slew over a tick, Table 1 refusal,
    0.1 s watchdog), the laminate (``plant``, table2) and the sensors (ideal)."""

    def __init__(self) -> None:
        self.model = PlantModel("table2", terminal="amplifier")
        self.stepper = PlantStepper(self.model)
        self.i_z3 = self.model.output_names.index("z3")
        self.t = 0.0
        self.rig_seq = 0
        self.v = (0.0, 0.0)
        self.z3 = 0.0
        self.refused = False
        self.refused_count = 0
        self.cmd_seq_applied = 0
        self.since_command = 0.0
        self.lock = threading.Lock()

    def command(self, seq: int, v1: float, v2: float, current: float) -> bool:
        """A COMMAND / FC 16 write; lock-step: apply and advance one tick. False if refused (outside Table 1)."""
        with self.lock:
            ok = all(np.isfinite((v1, v2, current))) and V_MIN <= v1 <= V_MAX and V_MIN <= v2 <= V_MAX \
                and 0.0 <= current <= 10.0
            new = (v1, v2) if ok else self.v
            self.refused = not ok
            if ok:
                self.cmd_seq_applied = seq
                self.since_command = 0.0
            else:
                self.refused_count += 1
            self.tick(new)
            return ok

    def tick(self, new: tuple[float, float]) -> None:
        if self.since_command > 0.1:  # the rig's own watchdog: no command for 0.1 s -> 0 V
            new = (0.0, 0.0)
        u = np.array([[self.v[0], self.v[1], 0.0], [new[0], new[1], 0.0]])  # linear slew over the tick
        self.z3 = float(self.stepper.advance(u, TICK)[0, self.i_z3])
        self.v = new
        self.t += TICK
        self.rig_seq += 1
        self.since_command += TICK

    def v_patch(self) -> float:
        return (self.v[0] - self.v[1]) / 2  # differential drive seen by the patches (ideal amplifier)

    def flags(self) -> int:
        return 2 if self.refused else 0  # bit 1: the last command was refused


# --------------------------------------------------------------------------------------------- serial (pty)


class SerialRig(threading.Thread):
    """protocol.md: COMMAND -> SAMPLE with the same sequence number, PING -> PONG(1, 64), else NAK."""

    def __init__(self, rig: DocRig) -> None:
        super().__init__(daemon=True)
        self.rig = rig
        self.master, slave = os.openpty()
        tty.setraw(self.master)
        tty.setraw(slave)
        self.slave = slave
        self.path = os.ttyname(slave)
        self.stop = threading.Event()
        self.commands = 0

    def run(self) -> None:
        buf = b""
        import select

        while not self.stop.is_set():
            ready, _, _ = select.select([self.master], [], [], 0.05)
            if not ready:
                continue
            buf += os.read(self.master, 4096)
            while True:
                start = buf.find(b"\xa5\x5a")
                if start < 0:
                    buf = buf[-1:] if buf.endswith(b"\xa5") else b""
                    break
                buf = buf[start:]
                if len(buf) < 8:
                    break
                n, msg_type, seq = struct.unpack_from("<BBI", buf, 2)
                if n > 64:
                    buf = buf[1:]
                    continue
                if len(buf) < 10 + n:
                    break
                body, crc = buf[2:8 + n], struct.unpack_from("<H", buf, 8 + n)[0]
                if crc16_ccitt_false(body) != crc:
                    buf = buf[1:]
                    continue
                payload, buf = buf[8:8 + n], buf[10 + n:]
                os.write(self.master, self.answer(msg_type, seq, payload))

    def answer(self, msg_type: int, seq: int, payload: bytes) -> bytes:
        if msg_type == 0x02:  # PING -> PONG: protocol version 1, maximum payload 64
            return frame(0x82, seq, struct.pack("<HH", 1, 64))
        if msg_type == 0x01:
            if len(payload) != 12:
                return frame(0xEE, seq, bytes([msg_type, 2]))  # NAK: bad length
            v1, v2, current = struct.unpack("<fff", payload)
            self.commands += 1
            self.rig.command(seq, v1, v2, current)
            r = self.rig
            sample = struct.pack("<Idffff??", r.rig_seq, r.t, r.z3, r.v_patch(), 0.0, 3.0, True, False)
            sample = sample[:-1] + bytes([r.flags()])
            return frame(0x81, seq, sample)
        return frame(0xEE, seq, bytes([msg_type, 1]))  # NAK: unknown type

    def close(self) -> None:
        self.stop.set()
        self.join(timeout=2)
        os.close(self.master)
        os.close(self.slave)


# --------------------------------------------------------------------------------------------- Modbus TCP


def f32(x: float) -> list[int]:
    hi, lo = struct.unpack(">HH", struct.pack(">f", x))  # registers.md: high word first (ABCD)
    return [hi, lo]


def u32(x: int) -> list[int]:
    return [(x >> 16) & 0xFFFF, x & 0xFFFF]


class ModbusTcpRig(threading.Thread):
    """registers.md: unit 1, FC 16 on holding 0-7 (the command), FC 04 on input 0-21 (the sample), FC 03 on
    holding 0-13 (map_version 1, rig_tick, the limits); exception 02 outside the map, 03 for a refused command."""

    def __init__(self, rig: DocRig) -> None:
        super().__init__(daemon=True)
        self.rig = rig
        self.server = socket.create_server(("127.0.0.1", 0))
        self.port = self.server.getsockname()[1]
        self.server.settimeout(0.1)
        self.stop = threading.Event()
        self.holding = [0] * 8 + [1, 100] + f32(V_MIN) + f32(V_MAX)
        self.commands = 0

    def run(self) -> None:
        while not self.stop.is_set():
            try:
                conn, _ = self.server.accept()
            except TimeoutError:
                continue
            conn.settimeout(0.1)
            buf = b""
            with conn:
                while not self.stop.is_set():
                    try:
                        data = conn.recv(4096)
                    except TimeoutError:
                        continue
                    except OSError:
                        break
                    if not data:
                        break
                    buf += data
                    while len(buf) >= 7:
                        tid, _pid, length, unit = struct.unpack_from(">HHHB", buf)
                        if len(buf) < 6 + length:
                            break
                        pdu, buf = buf[7:6 + length], buf[6 + length:]
                        if unit not in (1, 255):
                            continue  # other unit ids: silence
                        reply = self.answer(pdu)
                        conn.sendall(struct.pack(">HHHB", tid, 0, len(reply) + 1, unit) + reply)

    def input_block(self) -> list[int]:
        r = self.rig
        status = r.flags() | 0x0100  # bits 0-7 flags, bit 8 HV equipment present
        z3s = max(-32768, min(32767, round(r.z3 / 1e-5)))
        vps = max(-32768, min(32767, round(r.v_patch() / 0.1)))
        words = (u32(r.rig_seq & 0xFFFFFFFF) + list(struct.unpack(">HHHH", struct.pack(">d", r.t)))
                 + f32(r.z3) + f32(r.v_patch()) + f32(0.0) + f32(3.0) + u32(r.cmd_seq_applied)
                 + [status, r.refused_count & 0xFFFF, z3s & 0xFFFF, vps & 0xFFFF, 0, 3000])
        assert len(words) == 22
        return words

    def answer(self, pdu: bytes) -> bytes:
        fc = pdu[0]
        if fc in (0x03, 0x04):
            start, count = struct.unpack_from(">HH", pdu, 1)
            table = self.holding if fc == 0x03 else self.input_block()
            if not 1 <= count <= 125 or start + count > len(table):
                return bytes([fc | 0x80, 0x02])
            regs = table[start:start + count]
            return bytes([fc, 2 * count]) + struct.pack(f">{count}H", *regs)
        if fc == 0x10:
            start, count, nbytes = struct.unpack_from(">HHB", pdu, 1)
            regs = list(struct.unpack_from(f">{count}H", pdu, 6))
            if start != 0 or count != 8 or nbytes != 16:  # only whole command blocks in this minimal rig
                return bytes([fc | 0x80, 0x02])
            v1, v2, cur = (struct.unpack(">f", struct.pack(">HH", *regs[i:i + 2]))[0] for i in (0, 2, 4))
            seq = (regs[6] << 16) | regs[7]
            self.commands += 1
            if not self.rig.command(seq, v1, v2, cur):
                return bytes([fc | 0x80, 0x03])  # refused: ILLEGAL DATA VALUE, the last output is kept
            self.holding[:8] = regs
            return struct.pack(">BHH", fc, start, count)
        return bytes([fc | 0x80, 0x01])

    def close(self) -> None:
        self.stop.set()
        self.join(timeout=2)
        self.server.close()


# --------------------------------------------------------------------------------------------- the visit


def run_visit(link_url: str, seconds: float = 6.5):
    from board_config.board import load_board_config
    from drivers import open_link
    from firmware_sim.board import Board
    from firmware_sim.runner import BoardRunner

    cfg = load_board_config(None, overrides={"maintenance": {"sequence": ["b"]}}, overrides_source="test")
    link = open_link(link_url)
    runner = BoardRunner(Board(cfg, nominal="table2"), link)
    link.open()
    try:
        result = runner.run(seconds)
    finally:
        link.close()
    mbits = [(e.data["label"], e.data["verdict"], e.data["max_eps"]) for e in result.events if e.kind == "mbit_result"]
    verdicts = [e.data["verdict"] for e in result.events if e.kind == "maintenance_verdict"]
    incidents = [e.data["incident"] for e in result.events if e.kind == "incident"]
    return mbits, verdicts, incidents, runner


@pytest.mark.parametrize("kind", ["serial", "modbus-tcp"])
def test_a_rig_written_from_the_documents_runs_a_maintenance_visit(kind: str):
    rig = DocRig()
    server = SerialRig(rig) if kind == "serial" else ModbusTcpRig(rig)
    server.start()
    try:
        url = (f"serial:{server.path}?timeout=0.5" if kind == "serial"
               else f"modbus-tcp://127.0.0.1:{server.port}?unit=1&timeout=0.5")
        mbits, verdicts, incidents, runner = run_visit(url)
    finally:
        server.close()
    assert verdicts == ["PASS"], (mbits, incidents)
    assert [m[:2] for m in mbits] == [("MBIT.b", "PASS")]
    assert mbits[0][2] < 0.01  # the documented semantics reproduce the board's nominal model (noise-free sensors)
    assert not [i for i in incidents if i not in ("mbit_clamped",)], incidents
    assert server.commands == 651 and runner.zero_sent and rig.v == (0.0, 0.0)  # 650 ticks + the closing zero


def test_the_board_refuses_a_modbus_rig_with_the_wrong_word_order():
    from drivers import LinkError, open_link

    rig = DocRig()
    server = ModbusTcpRig(rig)
    server.holding[10:14] = [server.holding[11], server.holding[10], server.holding[13], server.holding[12]]  # CDAB
    server.start()
    try:
        link = open_link(f"modbus-tcp://127.0.0.1:{server.port}?unit=1")
        with pytest.raises(LinkError, match="word order"):
            link.open()
        server.holding[8] = 3  # a map version this board does not know
        with pytest.raises(LinkError, match="map_version is 3"):
            open_link(f"modbus-tcp://127.0.0.1:{server.port}?unit=1").open()
    finally:
        server.close()
