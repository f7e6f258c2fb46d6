"""The serial frame: CRC, encoding, and the streaming decoder under garbage, truncation, oversize and fuzzing."""

from __future__ import annotations

import math
import struct

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from drivers.framing import (
    HEADER_LEN,
    MAX_FRAME,
    MAX_PAYLOAD,
    SYNC,
    Frame,
    FrameDecoder,
    FramingError,
    MessageType,
    NakReason,
    crc16,
    decode_command,
    decode_nak,
    decode_pong,
    decode_sample,
    encode_command,
    encode_frame,
    encode_nak,
    encode_pong,
    encode_sample,
    sanitize_sample,
)
from drivers.link import FLAG_SENSOR_FAULT, ActuatorCommand, RigSample

f32 = st.floats(width=32, allow_nan=False, allow_infinity=False)
u32 = st.integers(0, 2**32 - 1)
frames = st.builds(Frame, st.integers(0, 255), u32, st.binary(max_size=MAX_PAYLOAD))


def test_crc_is_ccitt_false_check_value():
    assert crc16(b"123456789") == 0x29B1


def test_command_frame_layout_byte_by_byte():
    """The layout documented in docs/protocol.md, checked on one concrete frame."""
    b = encode_command(ActuatorCommand(seq=0x01020304, v_ch1=600.0, v_ch2=-500.0, board_current=0.0))
    assert b[:2] == b"\xa5\x5a"
    assert b[2] == 12  # payload length
    assert b[3] == MessageType.COMMAND
    assert b[4:8] == bytes([4, 3, 2, 1])  # little-endian sequence
    assert struct.unpack("<fff", b[8:20]) == (600.0, -500.0, 0.0)
    assert int.from_bytes(b[20:22], "little") == crc16(b[2:20])
    assert len(b) == HEADER_LEN + 12 + 2


@given(frames)
def test_frame_round_trip(fr):
    assert FrameDecoder().feed(encode_frame(fr.type, fr.seq, fr.payload)) == [fr]


@given(u32, f32, f32, f32)
def test_command_round_trip_is_exact_for_float32_values(seq, v1, v2, cur):
    cmd = ActuatorCommand(seq, v1, v2, cur)
    (fr,) = FrameDecoder().feed(encode_command(cmd))
    assert decode_command(fr) == cmd


@given(u32, u32, st.floats(allow_nan=False, allow_infinity=False, min_value=-1e300, max_value=1e300),
       f32, f32, f32, f32, st.booleans(), st.integers(0, 255))
def test_sample_round_trip(reply_seq, seq, t, z3, vp, zdd, vb, hv, flags):
    s = RigSample(seq, t, z3, vp, zdd, vb, hv, flags)
    (fr,) = FrameDecoder().feed(encode_sample(s, reply_seq))
    assert fr.seq == reply_seq and fr.type == MessageType.SAMPLE
    assert decode_sample(fr) == s


def test_non_finite_sample_values_never_reach_the_wire():
    s = RigSample(1, 0.5, math.nan, math.inf, 1.0, 3.0, False, 0)
    clean = sanitize_sample(s)
    assert clean.z3 == 0.0 and clean.v_patch == 0.0 and clean.flags & FLAG_SENSOR_FAULT
    (fr,) = FrameDecoder().feed(encode_sample(s, 7))
    got = decode_sample(fr)
    assert got.z3 == 0.0 and got.flags & FLAG_SENSOR_FAULT and got.z0dd == 1.0


def test_encoders_refuse_what_cannot_be_sent():
    with pytest.raises(FramingError, match="v_ch1"):
        encode_command(ActuatorCommand(1, math.nan, 0.0, 0.0))
    with pytest.raises(FramingError, match="float32"):
        encode_command(ActuatorCommand(1, 1e39, 0.0, 0.0))
    with pytest.raises(FramingError, match="payload"):
        encode_frame(1, 1, bytes(MAX_PAYLOAD + 1))
    with pytest.raises(FramingError, match="sequence"):
        encode_frame(1, -1)
    with pytest.raises(FramingError, match="type"):
        encode_frame(256, 1)


def test_payload_decoders_name_the_problem():
    with pytest.raises(FramingError, match="expected a SAMPLE frame"):
        decode_sample(Frame(MessageType.COMMAND, 3, bytes(12)))
    with pytest.raises(FramingError, match="payload of 5 bytes, expected 12"):
        decode_command(Frame(MessageType.COMMAND, 3, bytes(5)))
    nan_cmd = struct.pack("<fff", math.nan, 0.0, 0.0)
    with pytest.raises(FramingError, match="non-finite"):
        decode_command(Frame(MessageType.COMMAND, 3, nan_cmd))
    assert decode_nak(FrameDecoder().feed(encode_nak(5, 0x33, NakReason.UNKNOWN_TYPE))[0]) == (
        0x33, NakReason.UNKNOWN_TYPE)
    assert decode_pong(FrameDecoder().feed(encode_pong(9))[0]) == 1


def test_resync_after_garbage_truncation_bad_crc_and_oversize():
    good1 = encode_command(ActuatorCommand(1, 10.0, 0.0, 0.0))
    good2 = encode_command(ActuatorCommand(2, 20.0, 0.0, 0.0))
    good3 = encode_command(ActuatorCommand(3, 30.0, 0.0, 0.0))
    corrupt = bytearray(good2)
    corrupt[10] ^= 0x10
    oversized = SYNC + bytes([MAX_PAYLOAD + 1, 1]) + bytes(20)
    stream = (b"\x00\xa5\xff garbage \xa5" + good1[:9]  # truncated frame
              + good1 + bytes(corrupt) + oversized + b"\xa5\x5a" + good2 + good3)
    d = FrameDecoder()
    got = d.feed(stream)
    assert [decode_command(f).seq for f in got] == [1, 2, 3]
    assert d.stats.crc_errors >= 2 and d.stats.oversized >= 1 and d.stats.discarded_bytes > 0
    assert d.pending < MAX_FRAME


@settings(max_examples=300)
@given(st.lists(st.one_of(st.binary(max_size=100), frames.map(lambda f: encode_frame(f.type, f.seq, f.payload))),
                max_size=30),
       st.integers(1, 97))
def test_fuzz_decoder_never_raises_and_stays_bounded(chunks, split):
    """Arbitrary bytes (with real frames mixed in) in arbitrary pieces: feed never raises, the held buffer
    stays below one maximum frame, and every payload decoder raises only FramingError."""
    data = b"".join(chunks)
    d = FrameDecoder()
    out = []
    for i in range(0, len(data), split):
        out += d.feed(data[i : i + split])
        assert d.pending < MAX_FRAME
    for fr in out:
        for decoder in (decode_command, decode_sample, decode_nak, decode_pong):
            try:
                decoder(fr)
            except FramingError:
                pass


@given(st.lists(frames, min_size=1, max_size=8), st.binary(max_size=40), st.integers(1, 50))
def test_frames_survive_leading_garbage_and_any_split(frs, garbage, split):
    data = garbage + b"".join(encode_frame(f.type, f.seq, f.payload) for f in frs)
    d = FrameDecoder()
    out = []
    for i in range(0, len(data), split):
        out += d.feed(data[i : i + split])
    # a fake header in the garbage makes the decoder wait, fail the CRC and hunt again from the next byte:
    # every real frame comes out, in order (barring a 2^-16 CRC coincidence that random garbage never hits)
    assert out[-len(frs):] == frs


@given(frames, st.data())
def test_every_single_bit_error_is_detected(fr, data):
    wire = bytearray(encode_frame(fr.type, fr.seq, fr.payload))
    pos = data.draw(st.integers(2, len(wire) - 1))  # after the sync (a broken sync just loses the frame)
    wire[pos] ^= 1 << data.draw(st.integers(0, 7))
    assert FrameDecoder().feed(bytes(wire)) == []


def test_huge_single_feed_is_processed_in_bounded_chunks():
    good = encode_command(ActuatorCommand(5, 1.0, 2.0, 0.0))
    d = FrameDecoder()
    out = d.feed(b"\xa5" * 100_000 + good)
    assert [f.seq for f in out] == [5]
    assert d.pending < MAX_FRAME
