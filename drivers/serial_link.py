"""``SerialLink``: the framed rig protocol (``drivers.framing``) over any pyserial port.

URLs (registered in :mod:`drivers.hardware_links`)::

    serial:/dev/ttyUSB0?baud=115200          a serial device or a pty path (``serial:`` + any pyserial URL:
    serial:/tmp/shm-hil/rig.pty              ``serial:loop://``, ``serial:rfc2217://host:port`` ...)
    socket://127.0.0.1:7000?timeout=0.02     raw TCP (pyserial's socket:// handler)
    rfc2217://host:port                      a networked serial server (RFC 2217)

Link options, given in the URL query and removed before the URL reaches pyserial:

    baud       line speed (default 115200; ignored by ptys and sockets)
    parity     N, E or O (default N)
    timeout    reply timeout per exchange in seconds (default 0.008: a command+sample round trip is
               62 bytes, 5.4 ms on a 115200-baud line)
    handshake  1 (default) sends a PING at open() and checks the protocol version; 0 skips it
    reopen     consecutive timeouts after which the port is closed and reopened (default 25)

One :meth:`SerialLink.exchange` per tick: write a COMMAND frame, read until the SAMPLE with the same
sequence number arrives or the timeout expires. Stale replies (earlier sequence numbers), garbage and
bad frames are counted and skipped. A lost port (pty closed, EIO, socket reset) closes the link; it is
reopened with a back-off counted in exchange calls (1, 2, 4 … 64), so a dead port costs one cheap
``LinkError`` per tick and never blocks the tick loop (:class:`~drivers.reconnecting_link.ReconnectingLink`).
Every incident is logged on the ``drivers.serial_link`` logger and counted in :attr:`SerialLink.stats`.
"""

from __future__ import annotations

import logging
import time
from urllib.parse import urlencode

import serial

from board_config.errors import InputError
from board_config.url_options import UrlOptions, split_url_query
from drivers.framing import (
    PROTOCOL_VERSION,
    Frame,
    FrameDecoder,
    FramingError,
    MessageType,
    decode_nak,
    decode_pong,
    decode_sample,
    encode_command,
    encode_ping,
)
from drivers.link import ActuatorCommand, LinkError, RigSample
from drivers.reconnecting_link import ReconnectingLink

log = logging.getLogger("drivers.serial_link")

_OUR_KEYS = ("baud", "parity", "timeout", "handshake", "reopen")
_EXCHANGE_BITS = 62 * 10  # COMMAND (22 bytes) + SAMPLE (40 bytes), 8N1
_OPEN_BUDGET_S = 0.5  # reply budget of the PING at open (no tick deadline yet)


def split_link_options(target: str) -> tuple[str, dict[str, str]]:
    """Split ``target`` into (URL for pyserial, our options). Unknown query keys stay with pyserial."""
    base, pairs = split_url_query(target)
    if "?" not in target:
        return target, {}
    ours = {key: value for key, value in pairs if key in _OUR_KEYS}
    theirs = [(key, value) for key, value in pairs if key not in _OUR_KEYS]
    return (base + ("?" + urlencode(theirs) if theirs else "")), ours


class SerialLink(ReconnectingLink):
    """The board side of the framed protocol over a pyserial port (see the module docstring for URLs)."""

    verb = "reopen"
    reconnected_note = "port reopened"

    def __init__(self, url: str, *, timeout: float | None = None, baudrate: int | None = None,
                 handshake: bool | None = None) -> None:
        target = url.removeprefix("serial:") if url.startswith("serial:") else url
        self.port_url, ours = split_link_options(target)
        if not self.port_url:
            raise InputError(f"link URL '{url}': no port given (e.g. serial:/dev/ttyUSB0 or socket://HOST:PORT)")
        opts = UrlOptions(url, ours.items())
        self.baudrate = int(baudrate or opts.number("baud", 115200, 50, 20_000_000))
        self.parity = opts.choice("parity", "N", ("N", "E", "O"))
        timeout = float(timeout if timeout is not None else opts.number("timeout", 0.008, 1e-4, 60.0))
        self.handshake = bool(handshake if handshake is not None else opts.flag("handshake", True))
        super().__init__(url, log, timeout=timeout, reopen_after=opts.integer("reopen", 25, 1, 1e9))
        #: line time of one exchange (s): 62 bytes of 10 bits; 0 for ptys and sockets, which have no baud rate
        self.line_time = 0.0 if self.port_url.startswith(("socket://", "loop://")) else _EXCHANGE_BITS / self.baudrate
        #: rig processing budget per exchange (s): what the timeout leaves after the line time, less 1 ms of slack
        self.processing_budget = max(self.timeout - self.line_time - 0.001, 0.0)
        self.last_round_trip_s = 0.0
        self._port: serial.SerialBase | None = None
        self._decoder = FrameDecoder()
        self._ping_seq = 0
        self.rig_protocol_version: int | None = None
        self._ping_due = False

    # ------------------------------------------------------------------------------------------ lifecycle
    def open(self) -> None:
        """Open the port (and check the rig answers a PING unless ``handshake=0``). Raises ``LinkError``."""
        self._bring_up()
        if self.handshake:
            budget = max(self.timeout, _OPEN_BUDGET_S)
            with self._silenced():  # one error below, not a warning per attempt
                try:
                    self.rig_protocol_version = self.ping(attempts=5, timeout=budget)
                except LinkError as exc:
                    self.close()
                    raise LinkError(f"{self.url}: the rig does not answer PING at start-up (5 attempts of "
                                    f"{1e3 * budget:.0f} ms; is it running and speaking docs/protocol.md at "
                                    f"{self.baudrate} baud? last: {str(exc).removeprefix(self.url + ': ')})") from exc
            if self.rig_protocol_version != PROTOCOL_VERSION:
                self.close()
                raise LinkError(f"{self.url}: rig speaks protocol version {self.rig_protocol_version}, "
                                f"this board speaks {PROTOCOL_VERSION}")

    def close(self) -> None:
        port, self._port = self._port, None
        if port is not None:
            try:
                port.close()
            except (OSError, serial.SerialException):  # closing a vanished port
                pass

    @property
    def is_open(self) -> bool:
        return self._port is not None

    def _open_transport(self) -> None:
        try:
            port = serial.serial_for_url(self.port_url, baudrate=self.baudrate, parity=self.parity,
                                         timeout=min(self.timeout, 0.002), write_timeout=max(self.timeout, 0.05),
                                         do_not_open=False)
        except (OSError, serial.SerialException, ValueError) as exc:
            raise LinkError(f"{self.url}: cannot open port '{self.port_url}': {exc}") from exc
        try:
            port.reset_input_buffer()
        except (OSError, serial.SerialException, NotImplementedError):
            pass
        self._port = port
        self._decoder.reset()

    def _drop_transport(self) -> None:
        self.close()

    def _after_reconnect(self) -> None:
        self._ping_due = self.handshake  # the device behind a reopened port may have changed: PING it again

    # ------------------------------------------------------------------------------------------ exchange
    def exchange(self, command: ActuatorCommand) -> RigSample:
        """Send ``command``; return the rig's sample answering it. Raises ``LinkError`` on any failure."""
        try:
            frame = encode_command(command)
        except FramingError as exc:
            self.stats["bad_command"] += 1
            raise LinkError(f"{self.url}: command not sendable: {exc}") from exc
        reply = self._transact(frame, MessageType.COMMAND, command.seq & 0xFFFFFFFF)
        try:
            sample = decode_sample(reply)
        except FramingError as exc:  # a SAMPLE of the wrong size from a foreign rig
            self.stats["bad_reply"] += 1
            raise LinkError(f"{self.url}: bad reply: {exc}") from exc
        if self._ping_due:  # after a reopen: the first answered command is followed by a PING (the rig's version)
            self._check_after_reopen()
        return sample

    def _check_after_reopen(self) -> None:
        try:
            version = self.ping(attempts=1)
        except LinkError:
            self.stats["ping_after_reopen_failed"] += 1
            return  # the rig answered the command: try the PING again after the next one
        self._ping_due = False
        self.stats["ping_after_reopen"] += 1
        if version != PROTOCOL_VERSION:
            self.close()
            raise LinkError(f"{self.url}: the reopened port answers protocol version {version}, this board speaks "
                            f"{PROTOCOL_VERSION}")

    def ping(self, attempts: int = 1, timeout: float | None = None) -> int:
        """Round trip a PING (reply budget ``timeout``, default the link's); return the rig's protocol version."""
        last: LinkError | None = None
        for _ in range(max(1, attempts)):
            self._ping_seq = (self._ping_seq + 1) & 0xFFFFFFFF
            try:
                return decode_pong(self._transact(encode_ping(self._ping_seq), MessageType.PING, self._ping_seq,
                                                  timeout))
            except FramingError as exc:
                last = LinkError(f"{self.url}: bad PONG: {exc}")
            except LinkError as exc:
                last = exc
        assert last is not None
        raise last

    def _transact(self, frame: bytes, request: MessageType, seq: int, timeout: float | None = None) -> Frame:
        self._ensure_up()
        port = self._port
        assert port is not None
        budget = self.timeout if timeout is None else timeout
        want = MessageType.SAMPLE if request == MessageType.COMMAND else MessageType.PONG
        self.stats["requests"] += 1
        try:
            port.write(frame)
        except serial.SerialTimeoutException:
            # pyserial raises "Write timeout" when its clock says the write timeout has passed *after* os.write
            # took the frame — under CPU load the process is simply descheduled for longer than write_timeout
            # between the two (issue 14: this took the pty link down). Not a lost port: wait for the reply as
            # usual; a frame that really did not go out ends as an ordinary reply timeout (and the port is
            # reopened only after ``reopen`` of those in a row).
            self.stats["write_timeouts"] += 1
            self._log.warn("write_timeout", "%s: write of seq %d reported a timeout (CPU load?); waiting for the "
                           "reply anyway", self.url, seq)
        except (OSError, serial.SerialException) as exc:
            raise self._link_down(f"write failed: {exc}") from exc
        t0 = time.monotonic()
        deadline = t0 + budget  # timeouts are the link's only use of a clock
        late = False  # a reply to an earlier request arrived while waiting: the rig is slower than the budget
        while True:
            try:
                data = port.read(max(1, port.in_waiting))
            except (OSError, serial.SerialException) as exc:
                raise self._link_down(f"read failed: {exc}") from exc
            if data:
                before = self._decoder.stats.as_dict()
                frames = self._decoder.feed(data)
                self._count_decoder(before)
                for fr in frames:
                    if fr.type == want and fr.seq == seq:
                        self._timeouts_in_row = 0
                        self.stats["replies"] += 1
                        took = time.monotonic() - t0
                        self.last_round_trip_s = took
                        if took > self.processing_budget + self.line_time:
                            self.stats["slow_replies"] += 1
                            self._log.warn("slow_reply", "%s: reply to seq %d after %.1f ms, over the rig's budget of "
                                           "%.1f ms (line time %.1f ms + processing %.1f ms, docs/real-rig.md)",
                                           self.url, seq, 1e3 * took, 1e3 * (self.processing_budget + self.line_time),
                                           1e3 * self.line_time, 1e3 * self.processing_budget)
                        return fr
                    if fr.type == MessageType.NAK and fr.seq == seq:
                        rejected, reason = decode_nak(fr) if len(fr.payload) == 2 else (fr.type, "?")
                        self.stats["nak"] += 1
                        self._log.warn("nak", "%s: rig NAK for seq %d (type 0x%02X, reason %s)", self.url, seq,
                                    rejected, getattr(reason, "name", reason))
                        raise LinkError(f"{self.url}: rig refused request seq {seq}: "
                                        f"{getattr(reason, 'name', reason)}")
                    self.stats["stale_or_unexpected"] += 1
                    if fr.type == want:
                        late = True
                    log.debug("%s: skipped frame type 0x%02X seq %d while waiting for seq %d", self.url,
                              fr.type, fr.seq, seq)
            if time.monotonic() >= deadline:
                why = f"no reply to seq {seq} within {1e3 * budget:.1f} ms" + (
                    "; a reply to an earlier request arrived late: the rig answers slower than its budget of "
                    f"{1e3 * (self.processing_budget + self.line_time):.1f} ms (docs/real-rig.md)" if late else "")
                if late:
                    self.stats["late_replies"] += 1
                raise self._timed_out(why, may_reopen=not late)  # silence, not slowness, reopens the port

    def _count_decoder(self, before: dict[str, int]) -> None:
        after = self._decoder.stats.as_dict()
        for key in ("crc_errors", "oversized", "discarded_bytes"):
            delta = after[key] - before[key]
            if delta:
                self.stats[key] += delta
                what = "byte(s) of garbage skipped" if key == "discarded_bytes" else f"frame(s) dropped ({key})"
                self._log.warn(key, "%s: %d %s", self.url, delta, what)
