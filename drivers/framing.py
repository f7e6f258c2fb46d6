"""The binary frame of the serial rig protocol: encoding, a streaming decoder, and the payload codecs.

Pure logic: no I/O, no clock. The byte-by-byte layout is documented in ``docs/protocol.md``; in short::

    offset  size  field
    0       2     sync            0xA5 0x5A
    2       1     length N        payload bytes, 0..MAX_PAYLOAD (64)
    3       1     message type    see MessageType
    4       4     sequence number uint32, little-endian
    8       N     payload         little-endian fields, IEEE-754 floats
    8+N     2     CRC-16          CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, no reflection, no final XOR)
                                  over bytes 2 .. 8+N-1 (length, type, sequence, payload); little-endian

The :class:`FrameDecoder` accepts any byte stream — garbage, truncated frames, oversized length fields,
bad checksums — and returns only frames whose CRC checks; everything else is counted and discarded, and
the decoder resynchronises on the next sync pattern. It never raises. Its buffer never holds more than
one maximum-size frame between calls.

The only exception this module raises is :class:`FramingError` (a ``ValueError``): from the encoders
(a value that cannot be put on the wire) and from the payload decoders (a frame of the wrong type or
length).
"""

from __future__ import annotations

import binascii
import math
import struct
from dataclasses import dataclass, field
from enum import IntEnum

from drivers.link import FLAG_SENSOR_FAULT, ActuatorCommand, RigSample

SYNC = b"\xa5\x5a"
HEADER = struct.Struct("<2sBBI")  # sync, length, type, sequence
HEADER_LEN = HEADER.size  # 8
CRC_LEN = 2
MAX_PAYLOAD = 64
MAX_FRAME = HEADER_LEN + MAX_PAYLOAD + CRC_LEN  # 74
PROTOCOL_VERSION = 1
_F32_MAX = 3.4028234663852886e38


class FramingError(ValueError):
    """A value cannot be encoded, or a frame's payload does not match its message type."""


class MessageType(IntEnum):
    """Message types. Requests have bit 7 clear; the rig's replies have bit 7 set."""

    COMMAND = 0x01  #: board → rig: actuator demands for one tick
    PING = 0x02  #: board → rig: liveness / version query (empty payload)
    SAMPLE = 0x81  #: rig → board: the rig's latest sample (reply to COMMAND, same sequence number)
    PONG = 0x82  #: rig → board: reply to PING
    NAK = 0xEE  #: rig → board: request not understood (reason in payload)


class NakReason(IntEnum):
    """Why the rig refused to understand a request (payload byte 1 of a NAK)."""

    UNKNOWN_TYPE = 1
    BAD_LENGTH = 2
    BAD_VALUE = 3


#: payload layouts (little-endian)
COMMAND_PAYLOAD = struct.Struct("<fff")  # v_ch1 V, v_ch2 V, board_current A
SAMPLE_PAYLOAD = struct.Struct("<IdffffBB")  # rig_seq, t s, z3 m, v_patch V, z0dd m/s^2, v_battery V, hv, flags
PONG_PAYLOAD = struct.Struct("<HH")  # protocol version, max payload
NAK_PAYLOAD = struct.Struct("<BB")  # rejected message type, NakReason


def crc16(data: bytes | bytearray | memoryview) -> int:
    """CRC-16/CCITT-FALSE of ``data`` (check value for b"123456789" is 0x29B1)."""
    return binascii.crc_hqx(data, 0xFFFF)


@dataclass(frozen=True)
class Frame:
    """One decoded frame. ``type`` is kept as an int: unknown types reach the caller, who answers NAK."""

    type: int
    seq: int
    payload: bytes = b""


def encode_frame(msg_type: int, seq: int, payload: bytes = b"") -> bytes:
    """The wire bytes of one frame. Raises :class:`FramingError` on an out-of-range field."""
    if not 0 <= int(msg_type) <= 0xFF:
        raise FramingError(f"message type {msg_type!r} outside 0..255")
    if not 0 <= int(seq) <= 0xFFFFFFFF:
        raise FramingError(f"sequence number {seq!r} outside 0..2**32-1")
    if len(payload) > MAX_PAYLOAD:
        raise FramingError(f"payload of {len(payload)} bytes exceeds the maximum of {MAX_PAYLOAD}")
    head = HEADER.pack(SYNC, len(payload), int(msg_type), int(seq))
    body = head[2:] + bytes(payload)
    return SYNC + body + crc16(body).to_bytes(2, "little")


@dataclass
class DecoderStats:
    """What the decoder has seen (all counts since creation or the last :meth:`FrameDecoder.reset`)."""

    frames: int = 0  #: frames with a good CRC returned to the caller
    crc_errors: int = 0  #: candidate frames dropped for a bad CRC (includes truncated frames)
    oversized: int = 0  #: headers whose length field exceeded MAX_PAYLOAD
    discarded_bytes: int = 0  #: bytes thrown away while hunting for a sync pattern or after a bad frame

    def as_dict(self) -> dict[str, int]:
        return dict(self.__dict__)


@dataclass
class FrameDecoder:
    """Streaming frame decoder with resynchronisation; ``feed`` never raises.

    After a bad CRC or an oversized length field the decoder drops only the first sync byte of the
    failed candidate and hunts again, so a good frame that started inside the bad one is still found.
    """

    _buf: bytearray = field(default_factory=bytearray, repr=False)
    stats: DecoderStats = field(default_factory=DecoderStats)

    def reset(self) -> None:
        """Forget any partial frame (after a reconnect)."""
        self.stats.discarded_bytes += len(self._buf)
        self._buf.clear()

    @property
    def pending(self) -> int:
        """Bytes held back waiting for the rest of a frame (always < MAX_FRAME)."""
        return len(self._buf)

    def feed(self, data: bytes | bytearray | memoryview) -> list[Frame]:
        """Add received bytes; return the complete, CRC-checked frames they finish (in order)."""
        out: list[Frame] = []
        view = memoryview(bytes(data)) if not isinstance(data, bytes) else memoryview(data)
        chunk = 4 * MAX_FRAME  # bounded work buffer even for a huge single feed
        for start in range(0, len(view), chunk):
            self._buf += view[start : start + chunk]
            self._drain(out)
        return out

    def _drain(self, out: list[Frame]) -> None:
        buf = self._buf
        st = self.stats
        while buf:
            i = buf.find(SYNC)
            if i < 0:
                keep = 1 if buf[-1] == SYNC[0] else 0  # a sync may straddle two reads
                st.discarded_bytes += len(buf) - keep
                del buf[: len(buf) - keep]
                return
            if i:
                st.discarded_bytes += i
                del buf[:i]
            if len(buf) < HEADER_LEN:
                return
            length = buf[2]
            if length > MAX_PAYLOAD:
                st.oversized += 1
                st.discarded_bytes += 1
                del buf[:1]
                continue
            total = HEADER_LEN + length + CRC_LEN
            if len(buf) < total:
                return
            body = bytes(buf[2 : total - CRC_LEN])
            if crc16(body) != int.from_bytes(buf[total - CRC_LEN : total], "little"):
                st.crc_errors += 1
                st.discarded_bytes += 1
                del buf[:1]
                continue
            _, _, msg_type, seq = HEADER.unpack_from(buf, 0)
            out.append(Frame(msg_type, seq, body[HEADER_LEN - 2 :]))
            st.frames += 1
            del buf[:total]


# ---------------------------------------------------------------------------------------------- payloads


def _f32(name: str, value: float) -> float:
    v = float(value)
    if not math.isfinite(v) or abs(v) > _F32_MAX:
        raise FramingError(f"{name}={value!r} cannot be sent as a finite float32")
    return v


def encode_command(command: ActuatorCommand) -> bytes:
    """A COMMAND frame carrying ``command`` (sequence number = ``command.seq`` mod 2**32)."""
    payload = COMMAND_PAYLOAD.pack(_f32("v_ch1", command.v_ch1), _f32("v_ch2", command.v_ch2),
                                   _f32("board_current", command.board_current))
    return encode_frame(MessageType.COMMAND, command.seq & 0xFFFFFFFF, payload)


def decode_command(frame: Frame) -> ActuatorCommand:
    """The command in a COMMAND frame; non-finite values are a :class:`FramingError`."""
    _expect(frame, MessageType.COMMAND, COMMAND_PAYLOAD.size)
    v1, v2, cur = COMMAND_PAYLOAD.unpack(frame.payload)
    if not (math.isfinite(v1) and math.isfinite(v2) and math.isfinite(cur)):
        raise FramingError(f"COMMAND seq {frame.seq}: non-finite value in ({v1}, {v2}, {cur})")
    return ActuatorCommand(seq=frame.seq, v_ch1=v1, v_ch2=v2, board_current=cur)


def sanitize_sample(sample: RigSample) -> RigSample:
    """The sample with every non-finite or float32-overflowing value replaced by 0 and the sensor-fault flag set.

    The rig side calls this before encoding: a NaN never goes on the wire or into a register.
    """
    fields = {"z3": sample.z3, "v_patch": sample.v_patch, "z0dd": sample.z0dd, "v_battery": sample.v_battery}
    bad = [k for k, v in fields.items() if not math.isfinite(v) or abs(v) > _F32_MAX]
    t = sample.t if math.isfinite(sample.t) else 0.0
    if not bad and t == sample.t:
        return sample
    clean = {k: (0.0 if k in bad else v) for k, v in fields.items()}
    return RigSample(seq=sample.seq, t=t, hv_present=sample.hv_present,
                     flags=sample.flags | FLAG_SENSOR_FAULT, **clean)


def encode_sample(sample: RigSample, reply_seq: int) -> bytes:
    """A SAMPLE frame answering the COMMAND with sequence number ``reply_seq`` (values sanitised)."""
    s = sanitize_sample(sample)
    payload = SAMPLE_PAYLOAD.pack(s.seq & 0xFFFFFFFF, s.t, s.z3, s.v_patch, s.z0dd, s.v_battery,
                                  1 if s.hv_present else 0, s.flags & 0xFF)
    return encode_frame(MessageType.SAMPLE, reply_seq & 0xFFFFFFFF, payload)


def decode_sample(frame: Frame) -> RigSample:
    """The rig sample in a SAMPLE frame. A non-finite value from a foreign rig sets the sensor-fault flag."""
    _expect(frame, MessageType.SAMPLE, SAMPLE_PAYLOAD.size)
    rig_seq, t, z3, vp, z0dd, vb, hv, flags = SAMPLE_PAYLOAD.unpack(frame.payload)
    if not all(math.isfinite(v) for v in (t, z3, vp, z0dd, vb)):
        flags |= FLAG_SENSOR_FAULT
    return RigSample(seq=rig_seq, t=t, z3=z3, v_patch=vp, z0dd=z0dd, v_battery=vb, hv_present=bool(hv),
                     flags=flags)


def encode_ping(seq: int) -> bytes:
    return encode_frame(MessageType.PING, seq, b"")


def encode_pong(seq: int) -> bytes:
    return encode_frame(MessageType.PONG, seq, PONG_PAYLOAD.pack(PROTOCOL_VERSION, MAX_PAYLOAD))


def decode_pong(frame: Frame) -> int:
    """The rig's protocol version from a PONG frame."""
    _expect(frame, MessageType.PONG, PONG_PAYLOAD.size)
    version, _max_payload = PONG_PAYLOAD.unpack(frame.payload)
    return int(version)


def encode_nak(seq: int, rejected_type: int, reason: NakReason) -> bytes:
    return encode_frame(MessageType.NAK, seq, NAK_PAYLOAD.pack(rejected_type & 0xFF, int(reason)))


def decode_nak(frame: Frame) -> tuple[int, NakReason | int]:
    """(rejected message type, reason) from a NAK frame."""
    _expect(frame, MessageType.NAK, NAK_PAYLOAD.size)
    rejected, reason = NAK_PAYLOAD.unpack(frame.payload)
    try:
        return rejected, NakReason(reason)
    except ValueError:
        return rejected, reason


def _expect(frame: Frame, msg_type: MessageType, size: int) -> None:
    if frame.type != msg_type:
        raise FramingError(f"expected a {msg_type.name} frame (0x{int(msg_type):02X}), got type 0x{frame.type:02X} "
                           f"(seq {frame.seq})")
    if len(frame.payload) != size:
        raise FramingError(f"{msg_type.name} frame seq {frame.seq}: payload of {len(frame.payload)} bytes, "
                           f"expected {size}")
