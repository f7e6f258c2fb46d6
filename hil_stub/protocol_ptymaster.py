"""pyserial URL handler ``ptymaster://FD``: a serial port on the already open master side of a pty.

A pty's master has no path a server could open (opening ``/dev/ptmx`` again makes a new pty), and pymodbus' serial
server insists on opening its port by URL through :func:`serial.serial_for_url`. With this handler registered
(:func:`register`, pyserial's documented ``protocol_handler_packages`` mechanism) the stub's Modbus RTU server
serves the master of one pty directly, and the board opens its slave side — without a second pty and a relay
thread between them. Under CPU load that matters: the kernel moves pty bytes through a work queue at normal
priority, and every pty a byte crosses is one more wait for it (a pty pair with a relay: four per transaction;
one pty: two).

The port works on a duplicate of the descriptor (closing it leaves the pty alone); line settings (baud rate,
parity) are accepted and mean nothing on a pty, as on any pty.
"""

from __future__ import annotations

import fcntl
import os

import serial
from serial.serialposix import Serial as PosixSerial
from serial.serialutil import SerialException

SCHEME = "ptymaster"


def register() -> None:
    """Make ``ptymaster://FD`` URLs known to :func:`serial.serial_for_url` (idempotent)."""
    if __package__ not in serial.protocol_handler_packages:
        serial.protocol_handler_packages.append(__package__)


def url_for(master_fd: int) -> str:
    """The URL of an open pty master descriptor."""
    return f"{SCHEME}://{int(master_fd)}"


class Serial(PosixSerial):
    """A pyserial port on a duplicate of an open pty master descriptor (see the module docstring)."""

    is_open: bool  # set by pyserial (untyped there)
    fd: int | None

    def open(self) -> None:
        if self._port is None:
            raise SerialException("Port must be configured before it can be used.")
        if self.is_open:
            raise SerialException("Port is already open.")
        text = str(self._port)
        if not text.lower().startswith(SCHEME + "://"):
            raise SerialException(f"expected {SCHEME}://FD, got {text!r}")
        try:
            fd = int(text[len(SCHEME) + 3:])
            self.fd = os.dup(fd)
        except (ValueError, OSError) as exc:
            raise SerialException(f"could not open port {text}: {exc}") from None
        os.set_blocking(self.fd, False)
        self.pipe_abort_read_r, self.pipe_abort_read_w = os.pipe()
        self.pipe_abort_write_r, self.pipe_abort_write_w = os.pipe()
        fcntl.fcntl(self.pipe_abort_read_r, fcntl.F_SETFL, os.O_NONBLOCK)
        fcntl.fcntl(self.pipe_abort_write_r, fcntl.F_SETFL, os.O_NONBLOCK)
        self.is_open = True
        self._reset_input_buffer()  # like any pyserial open: what the board sent while nobody served is dropped

    def _reconfigure_port(self, force_update: bool = False) -> None:
        """Nothing to set on a pty master (the pty is raw already; a baud rate means nothing there)."""
        if self.fd is None:
            raise SerialException("Can only operate on a valid file descriptor")

    def _update_dtr_state(self) -> None:
        pass

    def _update_rts_state(self) -> None:
        pass
