"""The serial frame against its specification: docs/protocol.md is the oracle (its tables and worked examples are
parsed here), the limits are checked exactly at the boundary, and the decoder's statistics are exact counts."""

from __future__ import annotations

import math
import re
import struct
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from drivers.framing import (
    COMMAND_PAYLOAD,
    MAX_FRAME,
    MAX_PAYLOAD,
    NAK_PAYLOAD,
    PONG_PAYLOAD,
    PROTOCOL_VERSION,
    SAMPLE_PAYLOAD,
    SYNC,
    DecoderStats,
    Frame,
    FrameDecoder,
    FramingError,
    MessageType,
    NakReason,
    decode_command,
    decode_nak,
    decode_pong,
    decode_sample,
    encode_command,
    encode_frame,
    encode_nak,
    encode_ping,
    encode_pong,
    encode_sample,
    sanitize_sample,
)
from drivers.link import FLAG_LIMIT_REFUSED, FLAG_SENSOR_FAULT, ActuatorCommand, RigSample

DOC = (Path(__file__).resolve().parents[2] / "docs" / "protocol.md").read_text()
F32_MAX = float(struct.unpack("<f", b"\xff\xff\x7f\x7f")[0])


def _hex(text: str) -> bytes:
    return bytes.fromhex(text.replace(" ", ""))


def _messages_table() -> dict[str, tuple[int, int]]:
    """name -> (type code, payload bytes) from the "Messages" table of docs/protocol.md."""
    rows = re.findall(r"^\| `0x([0-9A-F]{2})` \| (\w+) \| [^|]+ \| (\d+)", DOC, flags=re.M)
    return {name: (int(code, 16), int(n)) for code, name, n in rows}


def test_message_codes_and_payload_sizes_are_the_documented_ones():
    table = _messages_table()
    assert set(table) == {m.name for m in MessageType}
    sizes = {"COMMAND": COMMAND_PAYLOAD.size, "PING": 0, "SAMPLE": SAMPLE_PAYLOAD.size, "PONG": PONG_PAYLOAD.size,
             "NAK": NAK_PAYLOAD.size}
    for name, (code, n) in table.items():
        assert MessageType[name] == code, name
        assert sizes[name] == n, name


def test_nak_reasons_are_the_documented_ones():
    m = re.search(r"reason uint8 \(([^)]*)\)", DOC)
    assert m
    documented = {int(num): words for num, words in re.findall(r"(\d+) ([a-z ]+?)(?:,|$)", m.group(1))}
    assert documented == {r.value: r.name.lower().replace("_", " ") for r in NakReason}


def test_frame_limits_are_the_documented_ones():
    assert f"0 … {MAX_PAYLOAD} (`MAX_PAYLOAD`)" in DOC
    assert f"A frame is 10 … {MAX_FRAME} bytes long" in DOC
    assert "`A5 5A`" in DOC and SYNC == _hex("A5 5A")
    assert f"protocol version uint16 (= {PROTOCOL_VERSION}), maximum payload uint16 (= {MAX_PAYLOAD})" in DOC


def test_worked_examples_byte_for_byte():
    ping = _hex(re.search(r"PING seq 7: `([0-9A-F ]+)`", DOC).group(1))
    pong = _hex(re.search(r"its PONG: `([0-9A-F ]+)`", DOC).group(1))
    nak = _hex(re.search(r"bad length \(seq 1235\): `([0-9A-F ]+)`", DOC).group(1))
    assert encode_ping(7) == ping and encode_pong(7) == pong
    assert encode_nak(1235, MessageType.COMMAND, NakReason.BAD_LENGTH) == nak
    d = FrameDecoder()
    f_ping, f_pong, f_nak = d.feed(ping + pong + nak)
    assert (f_ping.type, f_ping.seq, f_ping.payload) == (MessageType.PING, 7, b"")
    assert decode_pong(f_pong) == PROTOCOL_VERSION
    rejected, reason = decode_nak(f_nak)
    assert rejected == MessageType.COMMAND and reason is NakReason.BAD_LENGTH  # the enum, not just its number
    assert d.stats == DecoderStats(frames=3)


def _code_blocks_after(marker: str) -> bytes:
    """The hex bytes of the first fenced block after ``marker`` (separators and captions dropped)."""
    block = DOC.split(marker, 1)[1].split("```", 2)[1]
    rows = [ln for ln in block.splitlines() if re.fullmatch(r"[0-9A-F |]+", ln.strip() or "x")]
    return _hex("".join(rows).replace("|", ""))


def test_command_and_sample_worked_examples_byte_for_byte():
    command = _code_blocks_after("COMMAND, tick 1234")
    assert encode_command(ActuatorCommand(1234, 700.0, -500.0, 0.006)) == command
    sample = _code_blocks_after("SAMPLE answering it (rig sample")
    rig = RigSample(seq=1233, t=12.34, z3=5.4e-3, v_patch=600.0, z0dd=0.05, v_battery=3.05, hv_present=True, flags=0)
    assert encode_sample(rig, 1234) == sample
    assert sample[8 + 28] == 1  # hv_present is the byte 0/1
    back = decode_sample(FrameDecoder().feed(sample)[0])
    assert (back.seq, back.t, back.hv_present, back.flags) == (1233, 12.34, True, 0)


def test_the_largest_legal_payload_is_accepted_and_one_more_is_not():
    payload = bytes(range(MAX_PAYLOAD))
    wire = encode_frame(0x7F, 9, payload)
    assert len(wire) == MAX_FRAME
    d = FrameDecoder()
    assert d.feed(wire) == [Frame(0x7F, 9, payload)]
    assert d.stats == DecoderStats(frames=1) and d.pending == 0
    with pytest.raises(FramingError, match=f"65 bytes exceeds the maximum of {MAX_PAYLOAD}"):
        encode_frame(0x7F, 9, payload + b"\x00")
    # a header announcing 65 bytes is not a frame: counted, one byte dropped, the rest hunted
    d = FrameDecoder()
    assert d.feed(SYNC + bytes([MAX_PAYLOAD + 1, 1]) + bytes(4)) == []
    assert d.stats == DecoderStats(oversized=1, discarded_bytes=8)
    assert d.feed(SYNC + bytes([0xFF, 1]) + bytes(4)) == [] and d.stats.oversized == 2


@pytest.mark.parametrize(("field", "lo", "hi"), [("type", 0, 0xFF), ("seq", 0, 0xFFFFFFFF)])
def test_header_fields_at_their_limits(field, lo, hi):
    def enc(v):
        return encode_frame(v, 1) if field == "type" else encode_frame(1, v)

    for ok in (lo, hi):
        f = FrameDecoder().feed(enc(ok))[0]
        assert getattr(f, field) == ok and f.payload == b""  # no payload given: an empty one
    for bad in (lo - 1, hi + 1):
        with pytest.raises(FramingError, match=field.replace("seq", "sequence number")):
            enc(bad)


def test_decoder_statistics_are_exact():
    good = encode_command(ActuatorCommand(1, 100.0, 0.0, 0.0))
    bad = bytearray(encode_command(ActuatorCommand(2, 200.0, 0.0, 0.0)))
    bad[-1] ^= 0xFF  # wrong CRC
    over = SYNC + bytes([MAX_PAYLOAD + 1]) + bytes(9)
    garbage = b"\x00\x11\x22\x33\x44"
    assert SYNC not in bytes(bad[1:]) and SYNC not in over[1:]
    d = FrameDecoder()
    got = d.feed(garbage + good + bytes(bad) + over + good)
    assert [f.seq for f in got] == [1, 1]
    assert d.stats == DecoderStats(frames=2, crc_errors=1, oversized=1,
                                   discarded_bytes=len(garbage) + len(bad) + len(over))
    assert d.stats.as_dict() == {"frames": 2, "crc_errors": 1, "oversized": 1,
                                 "discarded_bytes": len(garbage) + len(bad) + len(over)}
    # a partial frame is held, then counted as discarded by reset()
    assert d.feed(good[:7]) == [] and d.pending == 7
    d.reset()
    assert d.pending == 0 and d.stats.discarded_bytes == len(garbage) + len(bad) + len(over) + 7
    # a lone first sync byte at the end of a read is kept; everything before it is garbage
    d = FrameDecoder()
    assert d.feed(b"\x01\x02" + good[:1]) == [] and d.pending == 1 and d.stats.discarded_bytes == 2
    assert d.feed(good[1:]) == [Frame(MessageType.COMMAND, 1, good[8:-2])]
    assert d.stats == DecoderStats(frames=1, discarded_bytes=2)
    d = FrameDecoder()
    assert d.feed(b"\x01\x02\x03") == [] and d.pending == 0 and d.stats.discarded_bytes == 3


def test_bytes_bytearray_and_memoryview_reads_decode_alike():
    wire = encode_ping(3) + encode_pong(3)
    want = FrameDecoder().feed(wire)
    assert len(want) == 2
    assert FrameDecoder().feed(bytearray(wire)) == want
    assert FrameDecoder().feed(memoryview(wire)) == want


@settings(max_examples=100, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 255), st.integers(0, 2**32 - 1), st.binary(max_size=MAX_PAYLOAD)),
                min_size=1, max_size=8), st.integers(1, 40))
def test_any_split_of_good_frames_gives_them_all_and_no_errors(frames, split):
    wire = b"".join(encode_frame(*f) for f in frames)
    d = FrameDecoder()
    got = []
    for i in range(0, len(wire), split):
        got += d.feed(wire[i:i + split])
    assert got == [Frame(t, s, p) for t, s, p in frames]
    assert d.stats == DecoderStats(frames=len(frames)) and d.pending == 0


def _sample(**kw) -> RigSample:
    base = {"seq": 5, "t": 1.25, "z3": 1e-3, "v_patch": 10.0, "z0dd": 0.5, "v_battery": 3.0, "hv_present": True,
            "flags": FLAG_LIMIT_REFUSED}
    return RigSample(**(base | kw))


@pytest.mark.parametrize("field", ["t", "z3", "v_patch", "z0dd", "v_battery"])
@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_a_non_finite_value_from_a_rig_raises_the_sensor_fault_flag(field, bad):
    values = {"t": 1.25, "z3": 1e-3, "v_patch": 10.0, "z0dd": 0.5, "v_battery": 3.0} | {field: bad}
    payload = SAMPLE_PAYLOAD.pack(5, values["t"], values["z3"], values["v_patch"], values["z0dd"],
                                  values["v_battery"], 1, FLAG_LIMIT_REFUSED)
    s = decode_sample(Frame(MessageType.SAMPLE, 3, payload))
    assert s.flags == FLAG_LIMIT_REFUSED | FLAG_SENSOR_FAULT and s.hv_present is True
    # our own rig never sends it: sanitised to 0 with the flag
    clean = sanitize_sample(_sample(**{field: bad}))
    assert getattr(clean, field) == 0.0 and clean.flags == FLAG_LIMIT_REFUSED | FLAG_SENSOR_FAULT
    assert all(getattr(clean, k) == getattr(_sample(), k) for k in values if k != field)
    assert (clean.seq, clean.hv_present) == (5, True)


def test_a_finite_sample_keeps_its_flags_and_values():
    s = _sample(hv_present=False, flags=0)
    assert sanitize_sample(s) is s
    f = FrameDecoder().feed(encode_sample(s, 77))[0]
    assert f.seq == 77
    back = decode_sample(f)
    assert back.flags == 0 and back.hv_present is False and back.seq == 5 and back.t == 1.25
    big = _sample(z3=F32_MAX * 2)
    assert sanitize_sample(big).z3 == 0.0 and sanitize_sample(big).flags & FLAG_SENSOR_FAULT
    edge = _sample(v_patch=F32_MAX)  # the largest float32 is still a value
    assert sanitize_sample(edge) is edge


@pytest.mark.parametrize("i", [0, 1, 2])
def test_command_values_must_be_finite_float32(i):
    vals = [100.0, -500.0, 0.006]
    assert decode_command(FrameDecoder().feed(encode_command(ActuatorCommand(3, *vals)))[0]) == \
        ActuatorCommand(3, *(struct.unpack("<fff", struct.pack("<fff", *vals))))
    for bad in (math.nan, math.inf, F32_MAX * 2):
        v = list(vals)
        v[i] = bad
        with pytest.raises(FramingError, match=rf'^{("v_ch1", "v_ch2", "board_current")[i]}='):
            encode_command(ActuatorCommand(3, *v))
    v = list(vals)
    v[i] = F32_MAX
    encode_command(ActuatorCommand(3, *v))  # the largest float32 can be sent
    raw = list(vals)
    raw[i] = math.inf
    with pytest.raises(FramingError, match="COMMAND seq 4: non-finite"):
        decode_command(Frame(MessageType.COMMAND, 4, COMMAND_PAYLOAD.pack(*raw)))


def test_command_sequence_wraps_modulo_2_32():
    f = FrameDecoder().feed(encode_command(ActuatorCommand(2**32 + 5, 0.0, 0.0, 0.0)))[0]
    assert f.seq == 5


def test_payload_decoders_check_type_and_length_and_say_which():
    with pytest.raises(FramingError, match=r"expected a PONG frame \(0x82\), got type 0x81 \(seq 6\)"):
        decode_pong(Frame(MessageType.SAMPLE, 6, bytes(4)))
    with pytest.raises(FramingError, match="NAK frame seq 6: payload of 3 bytes, expected 2"):
        decode_nak(Frame(MessageType.NAK, 6, bytes(3)))
    assert decode_nak(Frame(MessageType.NAK, 6, bytes([0x02, 9]))) == (0x02, 9)  # an unknown reason, as a number
    assert decode_nak(FrameDecoder().feed(encode_nak(1, 0x1FF, NakReason.BAD_VALUE))[0]) == (0xFF,
                                                                                            NakReason.BAD_VALUE)
