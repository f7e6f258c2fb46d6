"""The network part of a link URL — ``//HOST:PORT`` of ``socket://``, ``rfc2217://``, ``modbus-tcp://`` and of a
pyserial URL after ``serial:`` — checked before any link is built (issue 33).

urllib and pyserial raise a bare ``ValueError`` ("Invalid IPv6 URL", "Port out of range") for a malformed host or
port, and only when the port is opened; here every such mistake is an :class:`~board_config.errors.InputError`
naming the URL, the part that is wrong and what is allowed. Pure: no I/O, no name resolution.

Allowed: a host name (letters, digits, ``-``, ``_``, dots; labels of 1-63 characters, 253 in all), an IPv4 address
(four numbers 0-255) or an IPv6 address in brackets (``[::1]:5020``, a zone ``[fe80::1%eth0]`` included); a port
1-65535 (``modbus-tcp://`` may leave it out: 502); no user info, no path beyond a bare ``/``, no ``#fragment``.
"""

from __future__ import annotations

import ipaddress
import re

from board_config.errors import InputError

_LABEL = re.compile(r"[A-Za-z0-9_](?:[A-Za-z0-9_-]{0,61}[A-Za-z0-9_])?")
_IPV4_LIKE = re.compile(r"[0-9.]+")
_EXAMPLE = "e.g. 127.0.0.1:5020, rig.local:502 or [::1]:5020"


class LinkUrlError(InputError):
    """A malformed link URL: the message names the URL; :attr:`reason` is the part that is wrong and what is allowed
    (for callers that name the URL themselves, e.g. a command-line option)."""

    def __init__(self, url: str, reason: str) -> None:
        super().__init__(f"link URL '{url}': {reason}")
        self.url = url
        self.reason = reason


def _error(url: str, text: str) -> LinkUrlError:
    return LinkUrlError(url, text)


def check_host(url: str, host: str) -> str:
    """``host`` (without brackets) if it is a host name or an IPv4 address; :class:`InputError` otherwise."""
    if _IPV4_LIKE.fullmatch(host):
        try:
            return str(ipaddress.IPv4Address(host))
        except ValueError:
            raise _error(url, f"host '{host}' is not an IPv4 address (four numbers 0-255 joined by dots)") from None
    if ":" in host:
        raise _error(url, f"host '{host}': an IPv6 address goes in brackets, [ADDRESS]:PORT ({_EXAMPLE})")
    labels = host[:-1].split(".") if host.endswith(".") else host.split(".")
    if len(host) > 253 or not all(_LABEL.fullmatch(label) for label in labels):
        raise _error(url, f"host '{host}' is not a host name or IP address (letters, digits, '-', '_' and dots; "
                          f"IPv6 in brackets; {_EXAMPLE})")
    return host


def _check_ipv6(url: str, text: str) -> str:
    try:
        ipaddress.IPv6Address(text)
    except ValueError:
        raise _error(url, f"'[{text}]' is not an IPv6 address ({_EXAMPLE})") from None
    return text


def check_port(url: str, text: str, lowest: int = 1) -> int:
    """The port ``text`` as an integer in ``lowest`` .. 65535; :class:`InputError` naming it otherwise."""
    if not text.isascii() or not text.isdigit():
        raise _error(url, f"port '{text}' is not a number (a TCP port is {lowest} .. 65535)")
    port = int(text)
    if not lowest <= port <= 65535:
        raise _error(url, f"port {port} is outside {lowest} .. 65535")
    return port


def network_endpoint(url: str, scheme: str, default_port: int | None = None, lowest_port: int = 1, *,
                     part: str | None = None) -> tuple[str, int]:
    """``(host, port)`` of ``part`` (default: ``url``), which starts with ``scheme`` (``"modbus-tcp://"``,
    ``"socket://"`` ...) followed by ``HOST[:PORT]`` and optionally ``/`` and ``?query``; errors name ``url``.
    ``default_port`` None: the port is required; ``lowest_port`` 0 for a server's "any free port"."""
    text = url if part is None else part
    if not text.startswith(scheme):
        raise _error(url, f"expected {scheme}HOST:PORT")
    rest = text[len(scheme):]
    authority = re.split(r"[/?#]", rest, maxsplit=1)[0]
    tail = rest[len(authority):]
    if tail.startswith("#") or (tail.startswith("/") and tail.split("?", 1)[0] not in ("/", "")):
        what = tail.split("?", 1)[0]
        raise _error(url, f"'{what}' after HOST:PORT means nothing here (expected {scheme}HOST:PORT?OPTIONS)")
    if not authority:
        raise _error(url, f"no host: expected {scheme}HOST:PORT ({_EXAMPLE})")
    if "@" in authority:
        raise _error(url, f"'{authority}': user information (USER@) is not allowed; expected HOST:PORT")
    if authority.startswith("["):
        inside, sep, after = authority[1:].partition("]")
        if not sep:
            raise _error(url, f"IPv6 address '{authority}' has no closing ']': write [ADDRESS]:PORT, e.g. [::1]:5020")
        host = _check_ipv6(url, inside)
        if after and not after.startswith(":"):
            raise _error(url, f"'{after}' after ']': expected [ADDRESS]:PORT, e.g. [::1]:5020")
        port_text: str | None = after[1:] if after else None
    else:
        if authority.count(":") > 1:
            raise _error(url, f"'{authority}': an IPv6 address goes in brackets, [ADDRESS]:PORT ({_EXAMPLE})")
        host_text, sep, port_part = authority.partition(":")
        if not host_text:
            raise _error(url, f"no host before ':{port_part}' ({_EXAMPLE})")
        host = check_host(url, host_text)
        port_text = port_part if sep else None
    if port_text is None:
        if default_port is None:
            raise _error(url, f"no port: expected {scheme}HOST:PORT ({_EXAMPLE})")
        return host, default_port
    if port_text == "":
        raise _error(url, f"':' with no port after it (a TCP port is {lowest_port} .. 65535)")
    return host, check_port(url, port_text, lowest_port)


#: pyserial's URL protocols (``serial:PROTOCOL://...``) and the query options each takes (pyserial refuses others,
#: but only when the port is opened); the link's own options (``baud``, ``timeout`` ...) are taken out before
PYSERIAL_PROTOCOLS: dict[str, frozenset[str]] = {
    "socket": frozenset({"logging"}),
    "rfc2217": frozenset({"logging", "ign_set_control", "poll_modem", "timeout"}),
    "loop": frozenset({"logging"}),
    "spy": frozenset({"file", "color", "raw", "all"}),
    "alt": frozenset({"class"}),
    "hwgrep": frozenset({"n", "skip_busy"}),
}


def check_serial_target(url: str, target: str, their_keys: list[str], extra_protocols: frozenset[str]) -> None:
    """Check the pyserial part of a serial link URL: ``target`` (a device path or ``PROTOCOL://...``, the link's own
    options taken out) and ``their_keys``, the query options left for pyserial. A network protocol's
    ``//HOST:PORT`` is checked as :func:`network_endpoint` does; ``extra_protocols`` are URL handlers registered
    besides pyserial's own (their options are not checked)."""
    base = target.split("?", 1)[0]
    if "://" not in base:
        if their_keys:
            raise _error(url, f"unknown option(s) {', '.join(sorted(set(their_keys)))} (known: baud, handshake, "
                              f"parity, reopen, timeout)")
        return
    protocol = base.split("://", 1)[0]
    if protocol in extra_protocols:
        return
    known = PYSERIAL_PROTOCOLS.get(protocol)
    if known is None:
        raise _error(url, f"unknown serial URL protocol '{protocol}://' (known: "
                          f"{', '.join(p + '://' for p in sorted({*PYSERIAL_PROTOCOLS, *extra_protocols}))}, or a "
                          f"device path)")
    unknown = sorted(set(their_keys) - known - {"baud", "parity", "timeout", "handshake", "reopen"})
    if unknown:
        raise _error(url, f"unknown option(s) {', '.join(unknown)} for {protocol}:// (known: "
                          f"{', '.join(sorted(known | {'baud', 'handshake', 'parity', 'reopen', 'timeout'}))})")
    if protocol in ("socket", "rfc2217"):
        network_endpoint(url, f"{protocol}://", part=target)
