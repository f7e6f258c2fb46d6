"""``modbus-tcp://`` and ``modbus-rtu:`` link URLs into client settings (the options are listed in
:mod:`drivers.modbus_link`), with the RTU exchange budget that fits one board tick. Pure."""

from __future__ import annotations

from typing import Any
from urllib.parse import urlsplit

from board_config.errors import InputError
from board_config.url_options import UrlOptions, split_url_query

_KNOWN = {"tcp": {"unit", "timeout", "reopen", "handshake", "fc23"},
          "rtu": {"unit", "timeout", "reopen", "baud", "parity", "stopbits", "handshake", "fc23"}}
# RTU bytes on the line per exchange: FC16 request 1+1+2+2+1+16+2 = 25, its reply 8, FC04 request 8, its reply 49
_RTU_EXCHANGE_BYTES = 90
_TICK_S = 0.01  # the board's tick ([tick] rate = 100 Hz)
#: the board's own work in a tick besides the exchange (monitor, supervisor, records; ~0.3-0.7 ms measured, with a
#: margin for a loaded machine): an exchange given up at its budget still leaves the tick on time
_BOARD_RESERVE_S = 0.0015
_RTU_MAX_TIMEOUT_S = _TICK_S - _BOARD_RESERVE_S  # default RTU exchange budget never exceeds this: 8.5 ms
RTU_RIG_BUDGET_S = 0.002  #: the rig's documented processing budget per RTU transaction (docs/real-rig.md)
_RTU_MIN_RIG_S = 0.0005  # a line leaving the rig less than this (both transactions) does not fit a tick


def parse_modbus_url(url: str) -> dict[str, Any]:
    """Parse a ``modbus-tcp://`` or ``modbus-rtu:`` URL into client settings; ``ValueError`` names the problem."""
    if url.startswith("modbus-tcp://"):
        kind = "tcp"
        parts = urlsplit(url.replace("modbus-tcp://", "tcp://", 1))
        if not parts.hostname:
            raise InputError(f"link URL '{url}': expected modbus-tcp://HOST:PORT")
        try:
            port = parts.port or 502
        except ValueError:
            raise InputError(f"link URL '{url}': bad port") from None
        target: dict[str, Any] = {"host": parts.hostname, "port": port}
        opts = UrlOptions.from_query(url, parts.query)
    elif url.startswith("modbus-rtu:"):
        kind = "rtu"
        path, _ = split_url_query(url.removeprefix("modbus-rtu:"))
        if not path:
            raise InputError(f"link URL '{url}': expected modbus-rtu:PATH (a serial device or pty)")
        target = {"port": path}
        opts = UrlOptions.of(url)
    else:
        raise InputError(f"link URL '{url}': not a modbus-tcp:// or modbus-rtu: URL")
    opts.check_known(_KNOWN[kind])
    settings: dict[str, Any] = {"kind": kind, **target,
                                   "unit": opts.integer("unit", 1, 1, 247),
                                   "reopen": opts.integer("reopen", 25, 1, 1e9),
                                   "handshake": opts.flag("handshake", True),
                                   "fc23": opts.flag("fc23", True)}
    if kind == "rtu":
        baud = opts.integer("baud", 115200, 300, 4_000_000)
        parity = opts.choice("parity", "N", ("N", "E", "O"))
        stopbits = opts.integer("stopbits", 1, 1, 2)
        wire = _RTU_EXCHANGE_BYTES * (1 + 8 + stopbits + (parity != "N")) / baud
        # the exchange must fit one 10 ms tick with the board's own work: the line time + the rig's budget of 2 ms
        # per transaction, at least 8 ms, at most 8.5 ms (a give-up then leaves the tick on time); a line too slow
        # for the tick at all (below 115200 baud) keeps 8 ms plus twice its line time and misses deadlines
        fits = wire + _RTU_MIN_RIG_S <= _RTU_MAX_TIMEOUT_S
        default = (max(0.008, min(wire + 2 * RTU_RIG_BUDGET_S, _RTU_MAX_TIMEOUT_S)) if fits
                   else 0.008 + 2 * wire)
        settings.update(baud=baud, parity=parity, stopbits=stopbits, line_time=wire,
                        timeout=opts.number("timeout", default, 1e-4, 60.0))
    else:
        settings["timeout"] = opts.number("timeout", 0.008, 1e-4, 60.0)
        settings["line_time"] = 0.0
    return settings
