"""When a request's bytes reached the kernel: software receive timestamps on a served TCP connection (Linux).

The stub's answer time measured from the moment its event loop reads a request leaves out the wait before the loop
thread ran at all — on a desk where every core runs a CPU-bound job, the largest part (issue 29, point 2). The
kernel timestamps every received segment when asked (``SO_TIMESTAMPING`` with ``SOF_TIMESTAMPING_RX_SOFTWARE |
SOF_TIMESTAMPING_SOFTWARE``, delivered as ``SCM_TIMESTAMPING`` ancillary data by ``recvmsg``; the clock is
``CLOCK_REALTIME``), so *kernel receive → reply written* is the stub's whole answer time, its own wake-up included.

asyncio's transport reads its socket with ``recv``, which drops ancillary data. :func:`install` switches the
transport's socket (a ``socket.socket``) to :class:`_StampingSocket`, a subclass with the same layout whose ``recv``
is ``recvmsg`` plus keeping the timestamp (:func:`take_rx`); everything else about the socket stays as it was.
Where it cannot apply (not Linux, no socket, the option refused) nothing changes and :func:`install` says False.
The kernel starts stamping a moment after the first socket asks (a deferred switch), so the first request or two may
come without a timestamp (:func:`take_rx` None).
"""

from __future__ import annotations

import socket
import struct
import sys
import weakref
from typing import Any

SO_TIMESTAMPING = getattr(socket, "SO_TIMESTAMPING", 37)  #: SO_TIMESTAMPING_OLD (asm-generic/socket.h)
SOF_TIMESTAMPING_RX_SOFTWARE = 1 << 3
SOF_TIMESTAMPING_SOFTWARE = 1 << 4
_ANC_BYTES = socket.CMSG_SPACE(48)  # struct scm_timestamping: three struct timespec (software stamp in the first)

_rx_at: weakref.WeakKeyDictionary[socket.socket, float] = weakref.WeakKeyDictionary()


class _StampingSocket(socket.socket):
    """A ``socket.socket`` whose ``recv`` also keeps the kernel's receive timestamp (s, CLOCK_REALTIME)."""

    __slots__ = ()  # the same layout as socket.socket: an open socket's class can be switched to this one

    def recv(self, bufsize: int, flags: int = 0) -> bytes:
        data, ancdata, _flags, _addr = self.recvmsg(bufsize, _ANC_BYTES, flags)
        stamp = stamp_from_ancillary(ancdata)
        if stamp is not None:
            _rx_at[self] = stamp
        return data


def stamp_from_ancillary(ancdata: list[tuple[int, int, bytes]]) -> float | None:
    """The software receive timestamp (s since the epoch) in ``recvmsg`` ancillary data; None without one. Pure."""
    for level, kind, payload in ancdata:
        if level == socket.SOL_SOCKET and kind == SO_TIMESTAMPING and len(payload) >= 16:
            sec, nsec = struct.unpack_from("qq", payload)
            if sec or nsec:
                return sec + 1e-9 * nsec
    return None


def transport_socket(transport: Any) -> socket.socket | None:
    """The ``socket.socket`` an asyncio selector transport reads (its private ``_sock``); None for anything else."""
    sock = getattr(transport, "_sock", None)
    return sock if isinstance(sock, socket.socket) else None


def install(transport: Any) -> bool:
    """Ask the kernel for receive timestamps on ``transport``'s TCP socket and keep them; False where it cannot."""
    sock = transport_socket(transport)
    if sock is None or not sys.platform.startswith("linux") or sock.type != socket.SOCK_STREAM:
        return False
    try:
        sock.setsockopt(socket.SOL_SOCKET, SO_TIMESTAMPING,
                        SOF_TIMESTAMPING_RX_SOFTWARE | SOF_TIMESTAMPING_SOFTWARE)
        sock.__class__ = _StampingSocket
    except (OSError, TypeError):
        return False
    return True


def take_rx(transport: Any) -> float | None:
    """The kernel receive timestamp (s, CLOCK_REALTIME: compare with ``time.time()``) of the bytes last read from
    ``transport``'s socket, taken (a second call gives None until more bytes come); None before :func:`install` or
    without one."""
    sock = transport_socket(transport)
    return None if sock is None else _rx_at.pop(sock, None)
