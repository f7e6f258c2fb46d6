"""The rig side of the framed serial protocol (``drivers.framing``), on a pty, a serial device or a TCP socket.

``where`` selects the port:

* ``"pty"`` — a new pseudo-terminal; the board opens ``serial:<link>`` where ``<link>`` is a stable symlink
  to the pty's slave side (:class:`~hil_stub.pty_port.PtyPort`); ``"pty:/path/name"`` picks the link's path;
* ``"socket://HOST:PORT"`` — *listen* on TCP (port 0 picks a free one); the board connects with
  ``socket://HOST:PORT`` (pyserial's raw-socket URL); a new connection replaces the previous one;
* anything else — a serial device path or pyserial URL the stub opens (a real port looped to the board's,
  or one end of a socat pair).

One thread per server: read, decode (garbage, bad CRC, truncated and oversized frames are counted and
skipped by the decoder), answer each request: COMMAND → the host's sample (SAMPLE, same sequence number),
PING → PONG, a malformed or unknown request → NAK; replies from a confused peer are ignored; while the rig's
scenario schedules a link outage nothing is answered (lock-step: the rig still advances one tick per command).
Wire faults (:class:`~hil_stub.faults.ReplyFaulter`) act on the replies. Nothing a client sends can stop the thread;
a port that fails is closed and reopened after a pause.
"""

from __future__ import annotations

import contextlib
import logging
import math
import select
import socket
import threading
import time
from abc import ABC, abstractmethod
from collections import Counter
from pathlib import Path

import serial

from board_config.errors import InputError
from board_config.url_options import split_host_port
from drivers.framing import (
    Frame,
    FrameDecoder,
    FramingError,
    MessageType,
    NakReason,
    decode_command,
    encode_nak,
    encode_pong,
    encode_sample,
)
from hil_stub.faults import LinkFaults, ReplyFaulter
from hil_stub.pty_port import PtyPort
from hil_stub.rig_host import Delivery, RigHost

log = logging.getLogger("hil_stub.frame_server")
REOPEN_PAUSE_S = 0.2


class _Channel(ABC):
    """A byte pipe the server owns: the URL the board opens to reach it, and a line for the operator."""

    @abstractmethod
    def endpoint(self) -> tuple[str, str]:
        """(the URL the board opens, a line for the operator), as they are now (a port picked at open, a pty's name)."""

    @abstractmethod
    def open(self) -> None: ...

    @abstractmethod
    def close(self) -> None: ...

    @abstractmethod
    def read(self, timeout: float) -> bytes: ...

    @abstractmethod
    def write(self, data: bytes) -> None: ...


class _PtyChannel(_Channel):
    def __init__(self, link: Path | None) -> None:
        self.pty = PtyPort(link)

    def endpoint(self) -> tuple[str, str]:
        return f"serial:{self.pty.link}", f"serial frames on pty {self.pty.slave_name} (stable link {self.pty.link})"

    def open(self) -> None:
        self.pty.open()

    def close(self) -> None:
        self.pty.close()

    def read(self, timeout: float) -> bytes:
        return self.pty.read(timeout)

    def write(self, data: bytes) -> None:
        self.pty.write(data)


class _SerialChannel(_Channel):
    def __init__(self, where: str, baudrate: int) -> None:
        self.where = where
        self.url = where.removeprefix("serial:")
        self.baudrate = baudrate
        self.port: serial.SerialBase | None = None

    def endpoint(self) -> tuple[str, str]:
        return f"serial:{self.where}", f"serial frames on {self.where}"

    def open(self) -> None:
        self.port = serial.serial_for_url(self.url, baudrate=self.baudrate, timeout=0.01, write_timeout=0.1)

    def close(self) -> None:
        if self.port is not None:
            with contextlib.suppress(OSError, serial.SerialException):
                self.port.close()
            self.port = None

    def read(self, timeout: float) -> bytes:
        assert self.port is not None
        return self.port.read(max(1, self.port.in_waiting))

    def write(self, data: bytes) -> None:
        assert self.port is not None
        self.port.write(data)


class _TcpListenChannel(_Channel):
    def __init__(self, host: str, port: int) -> None:
        self.host, self.port = host, port
        self.listener: socket.socket | None = None
        self.client: socket.socket | None = None

    def endpoint(self) -> tuple[str, str]:
        return f"socket://{self.host}:{self.port}", f"serial frames on tcp {self.host}:{self.port}"

    def open(self) -> None:
        ls = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        ls.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        ls.bind((self.host, self.port))
        ls.listen(1)
        ls.setblocking(False)
        self.port = ls.getsockname()[1]  # keep the same port across reopen
        self.listener = ls

    def close(self) -> None:
        for s in (self.client, self.listener):
            if s is not None:
                with contextlib.suppress(OSError):
                    s.close()
        self.client = self.listener = None

    def read(self, timeout: float) -> bytes:
        assert self.listener is not None
        socks = [self.listener] + ([self.client] if self.client else [])
        ready, _, _ = select.select(socks, [], [], timeout)
        if self.listener in ready:
            conn, _ = self.listener.accept()
            conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            if self.client is not None:
                with contextlib.suppress(OSError):
                    self.client.close()
            self.client = conn
            return b""
        if self.client is not None and self.client in ready:
            try:
                data = self.client.recv(4096)
            except OSError:
                data = b""
            if not data:  # peer closed: wait for the next connection
                with contextlib.suppress(OSError):
                    self.client.close()
                self.client = None
            return data
        return b""

    def write(self, data: bytes) -> None:
        if self.client is not None:
            try:
                self.client.sendall(data)
            except OSError:
                with contextlib.suppress(OSError):
                    self.client.close()
                self.client = None


class FrameServer:
    """Serve the host's rig over the framed protocol (see the module docstring)."""

    def __init__(self, host: RigHost, where: str = "pty", *, faults: LinkFaults | None = None, seed: int = 0,
                 stream: int = 1, link_path: str | Path | None = None, baudrate: int = 115200) -> None:
        self.host = host
        self.where = where
        self.faulter = ReplyFaulter(faults, seed, stream)
        self.stats: Counter[str] = Counter()
        self._decoder = FrameDecoder()
        if where == "pty" or where.startswith("pty:"):
            link = link_path or (where[4:] or None if where.startswith("pty:") else None)
            self._channel: _Channel = _PtyChannel(Path(link) if link else None)
        elif where.startswith("socket://"):
            endpoint = split_host_port(where.removeprefix("socket://").split("?", 1)[0])
            if endpoint is None:
                raise InputError(f"--serial {where!r}: expected socket://HOST:PORT to listen on")
            self._channel = _TcpListenChannel(*endpoint)
        else:
            self._channel = _SerialChannel(where, baudrate)
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._down_until: float | None = None
        self._disconnect_done = False
        self._force_down: float | None = None
        self._down = threading.Event()  # set while the port is closed by the server
        self._up = threading.Event()  # set once the port is (re)opened

    # ------------------------------------------------------------------------------------------ endpoints
    @property
    def board_url(self) -> str:
        """The URL the board passes to ``shm run --link``."""
        return self._channel.endpoint()[0]

    def describe(self) -> str:
        return self._channel.endpoint()[1]

    # ------------------------------------------------------------------------------------------ lifecycle
    def start(self) -> None:
        self._channel.open()
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name=f"frame-server {self.where}", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
            self._thread = None
        self._channel.close()

    def disconnect(self, seconds: float) -> None:
        """Make the port vanish now for ``seconds`` (wall clock), then come back (does not wait)."""
        self._force_down = float(seconds)

    def go_down(self, timeout: float = 2.0) -> None:
        """Make the port vanish now and stay away until :meth:`come_back` (returns once it is closed)."""
        self._up.clear()
        self._force_down = math.inf
        if not self._down.wait(timeout):
            raise TimeoutError(f"{self.describe()}: the server thread did not close the port")

    def come_back(self, timeout: float = 2.0) -> None:
        """Reopen the port after :meth:`go_down` (returns once it is open again, under the same name)."""
        self._down_until = 0.0
        if not self._up.wait(timeout):
            raise TimeoutError(f"{self.describe()}: the server thread did not reopen the port")

    # ------------------------------------------------------------------------------------------ loop
    def _go_down(self, seconds: float, why: str) -> None:
        self.stats["disconnects"] += 1
        how_long = "until told to come back" if math.isinf(seconds) else f"for {seconds:.2f} s"
        log.warning("%s: %s; port closed %s", self.describe(), why, how_long)
        self.host.incident(f"{self.describe()}: {why}; port closed {how_long}")
        self._channel.close()
        self._decoder.reset()
        self._down_until = time.monotonic() + seconds
        self._down.set()

    def _run(self) -> None:
        lf = self.faulter.faults
        while not self._stop.is_set():
            if self._force_down is not None:
                secs, self._force_down = self._force_down, None
                self._go_down(secs, "disconnect requested")
            if (lf.disconnect_at_s is not None and not self._disconnect_done
                    and self.host.snapshot.sample.t >= lf.disconnect_at_s and self._down_until is None):
                self._disconnect_done = True
                self._go_down(lf.disconnect_for_s, f"injected disconnect at rig t = {lf.disconnect_at_s:g} s")
            if self._down_until is not None:
                if time.monotonic() < self._down_until:
                    self._stop.wait(0.005)
                    continue
                try:
                    self._channel.open()
                    self._down_until = None
                    self._down.clear()
                    self._up.set()
                    self.stats["reopened"] += 1
                    log.warning("%s: port back", self.describe())
                except (OSError, serial.SerialException) as exc:
                    self._down_until = time.monotonic() + REOPEN_PAUSE_S
                    log.warning("%s: reopen failed (%s)", self.where, exc)
                continue
            try:
                data = self._channel.read(0.01)
            except (OSError, serial.SerialException) as exc:
                self._go_down(REOPEN_PAUSE_S, f"port failed ({exc})")
                continue
            if not data:
                continue
            before = self._decoder.stats.as_dict()
            frames = self._decoder.feed(data)
            after = self._decoder.stats.as_dict()
            for key in ("crc_errors", "oversized", "discarded_bytes"):
                if after[key] != before[key]:
                    self.stats[key] += after[key] - before[key]
                    log.info("%s: %d %s from the board", self.where, after[key] - before[key], key)
            for fr in frames:
                reply = self._handle(fr)
                if reply is not None:
                    self._send(reply)

    def _handle(self, fr: Frame) -> bytes | None:
        if fr.type == MessageType.COMMAND:
            try:
                cmd = decode_command(fr)
            except FramingError as exc:
                self.stats["nak"] += 1
                log.warning("%s: bad COMMAND: %s", self.where, exc)
                bad_len = "payload" in str(exc)
                return encode_nak(fr.seq, fr.type, NakReason.BAD_LENGTH if bad_len else NakReason.BAD_VALUE)
            self.stats["commands"] += 1
            if self.host.submit(cmd, source=self.where) is Delivery.UNDELIVERED:
                self.stats["replies_withheld_link_down"] += 1  # the rig's scenario says the link is down
                return None
            return encode_sample(self.host.snapshot.sample, fr.seq)
        if fr.type == MessageType.PING:
            self.stats["pings"] += 1
            if self.host.link_down():
                self.stats["replies_withheld_link_down"] += 1
                return None
            return encode_pong(fr.seq)
        if fr.type & 0x80:
            self.stats["ignored_replies"] += 1
            return None
        self.stats["nak"] += 1
        return encode_nak(fr.seq, fr.type, NakReason.UNKNOWN_TYPE)

    def _send(self, reply: bytes) -> None:
        action, delay = self.faulter.decide()
        delay += self.faulter.faults.processing_s
        if delay > 0:
            time.sleep(delay)
        if action == "drop":
            return
        if action == "corrupt":
            reply = self.faulter.flip_bit(reply, 2)  # anywhere after the sync: the CRC must catch it
        try:
            self._channel.write(reply)
            self.stats["replies"] += 1
        except (OSError, serial.SerialException) as exc:
            self._go_down(REOPEN_PAUSE_S, f"write failed ({exc})")
