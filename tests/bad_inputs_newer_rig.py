"""The bad-input corpus of the rig side added since issue 12 (issue 33): link URLs for every scheme, `shm hil serve`
options, the scheduler-slice option, and bad writes to the rig's Modbus map. Used by
``tests/hil_stub/test_bad_inputs_newer_rig.py``.

Command-line cases are :class:`bad_inputs_corpus.Case` (``{o}``: the case's own output directory, ``{d}``: the corpus
directory); each must end in exit 2 with one ``error:`` line naming the URL part or option and what is allowed, and
fail during validation (no port is opened, no rig is built for a bad URL). Register-map cases are raw Modbus request
PDUs with the exception the stub must answer (docs/registers.md, "Errors and what the rig answers") and whether the
request may reach the rig at all (only a finite out-of-range demand does: the rig itself refuses and counts it).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

from bad_inputs_corpus import Case, case

from drivers.modbus_registers import COMMAND_START, INPUT_COUNT, MIRROR_START

OUT = "--quiet --out {o}"


def _link(id: str, url: str, *needles: str) -> Case:
    return case(f"rig-{id}", ["run", "--link", url, "--quiet", "--out", "{o}"], url, *needles)


def link_url_cases() -> list[Case]:
    """A bad URL for every scheme: host, port, IPv6 brackets, path, query values, unknown options and schemes."""
    return [
        # modbus-tcp://
        _link("tcp-v6-bracket", "modbus-tcp://[::1:5020", "closing ']'", "[ADDRESS]:PORT"),
        _link("tcp-v6-bare", "modbus-tcp://::1:5020", "brackets"),
        _link("tcp-v6-garbage", "modbus-tcp://[zz]:502", "not an IPv6 address"),
        _link("tcp-host-space", "modbus-tcp://my rig:502", "'my rig'", "host name or IP address"),
        _link("tcp-ipv4-bad", "modbus-tcp://300.1.1.1:502", "300.1.1.1", "IPv4"),
        _link("tcp-userinfo", "modbus-tcp://admin@rig:502", "user information"),
        _link("tcp-path", "modbus-tcp://127.0.0.1:502/holding", "/holding", "means nothing"),
        _link("tcp-port-zero", "modbus-tcp://127.0.0.1:0", "65535"),
        _link("tcp-port-empty", "modbus-tcp://127.0.0.1:", "65535"),
        _link("tcp-unit-nan", "modbus-tcp://127.0.0.1:5020?unit=nan", "unit"),
        _link("tcp-unit-zero", "modbus-tcp://127.0.0.1:5020?unit=0", "unit=0", "[1, 247]"),
        _link("tcp-timeout-inf", "modbus-tcp://127.0.0.1:5020?timeout=inf", "timeout"),
        _link("tcp-timeout-text", "modbus-tcp://127.0.0.1:5020?timeout=soon", "timeout", "not a number"),
        _link("tcp-fc23-two", "modbus-tcp://127.0.0.1:5020?fc23=2", "fc23", "[0, 1]"),
        _link("tcp-unknown-option", "modbus-tcp://127.0.0.1:5020?speed=1", "speed", "unknown option"),
        _link("tcp-rtu-option", "modbus-tcp://127.0.0.1:5020?baud=9600", "baud", "unknown option"),
        # modbus-rtu:
        _link("rtu-parity", "modbus-rtu:/dev/null?parity=X", "parity", "N, E, O"),
        _link("rtu-stopbits", "modbus-rtu:/dev/null?stopbits=3", "stopbits", "[1, 2]"),
        _link("rtu-baud-text", "modbus-rtu:/dev/null?baud=fast", "baud", "not a number"),
        _link("rtu-baud-low", "modbus-rtu:/dev/null?baud=10", "baud", "[300, 4e+06]"),
        _link("rtu-no-path", "modbus-rtu:?baud=9600", "PATH"),
        _link("rtu-unknown-option", "modbus-rtu:/dev/null?bogus=1", "bogus", "unknown option"),
        # socket:// and rfc2217://
        _link("socket-v6-bracket", "socket://[::1", "closing ']'"),
        _link("socket-no-port", "socket://127.0.0.1", "no port"),
        _link("socket-option", "socket://127.0.0.1:7000?bogus=1", "bogus", "logging"),
        _link("rfc2217-port", "rfc2217://127.0.0.1:99999", "99999"),
        _link("rfc2217-host", "rfc2217://rig_#1:2217", "rig_"),
        # serial:
        _link("serial-protocol", "serial:carrier://x", "carrier://", "unknown serial url protocol"),
        _link("serial-option", "serial:/dev/null?speed=9600", "speed", "unknown option"),
        _link("serial-baud-neg", "serial:/dev/null?baud=-5", "baud", "[50, 2e+07]"),
        _link("serial-parity", "serial:/dev/null?parity=Q", "parity", "N, E, O"),
        _link("serial-socket-port", "serial:socket://127.0.0.1:http", "'http'", "65535"),
        _link("serial-loop-option", "serial:loop://?bogus=1", "bogus", "loop://"),
        _link("serial-empty", "serial:", "no port given"),
        # sim
        _link("sim-seed-negative", "sim://?seed=-1", "seed=-1", "0 .. 2^32-1"),
        _link("sim-seed-huge", "sim://?seed=4294967296", "4294967296", "0 .. 2^32-1"),
        _link("sim-seed-text", "sim://?seed=abc", "seed", "integer"),
        _link("sim-host", "sim://rig?seed=1", "'rig' after sim://"),
        _link("sim-unknown-option", "sim://?sede=1", "sede", "unknown option"),
        _link("sim-blank-unknown", "sim://?colour=", "colour", "unknown option"),
        _link("sim-scenario", "sim:no-such-scenario", "no-such-scenario", "unknown scenario"),
        _link("sim-coupling", "sim://?coupling=tight", "coupling", "allowed"),
        _link("sim-params", "sim://?params=nosuch", "nosuch", "unknown parameter set"),
        # unknown schemes
        _link("scheme-simulator", "simulator", "unknown link URL", "known schemes"),
        _link("scheme-ftp", "ftp://rig:21", "unknown link URL"),
        _link("scheme-http", "http://rig:80/modbus", "unknown link URL"),
    ]


def hil_option_cases() -> list[Case]:
    """`shm hil serve` endpoints and options refused at parse time (before the rig is built), and `shm run`'s and
    `shm hil serve`'s --sched-slice-ms."""
    c = case
    return [
        c("rig-hil-tcp-v6-bracket", "hil serve --modbus-tcp [::1:0", "[::1:0", "closing ']'"),
        c("rig-hil-tcp-v6", "hil serve --modbus-tcp [::1]:0", "[::1]:0", "IPv6 is not served"),
        c("rig-hil-tcp-host", "hil serve --modbus-tcp bad!host:0", "bad!host", "host name or IP address"),
        c("rig-hil-tcp-ipv4", "hil serve --modbus-tcp 256.0.0.1:0", "256.0.0.1", "IPv4"),
        c("rig-hil-tcp-no-host", "hil serve --modbus-tcp :0", "--modbus-tcp", "no host"),
        c("rig-hil-tcp-no-port", "hil serve --modbus-tcp 127.0.0.1", "127.0.0.1", "no port"),
        c("rig-hil-serial-socket-v6", "hil serve --serial socket://[::1", "socket://[::1", "closing ']'"),
        c("rig-hil-serial-socket-port", "hil serve --serial socket://127.0.0.1:x", "'x'", "not a number"),
        c("rig-hil-serial-protocol", "hil serve --serial foo://x", "foo://x", "socket://HOST:PORT"),
        c("rig-hil-rtu-missing", "hil serve --modbus-rtu {d}/no/such/tty", "no/such/tty", "no such serial device"),
        c("rig-hil-slice-negative", "hil serve --serial pty --sched-slice-ms -1", "--sched-slice-ms", "0.1 .. 100"),
        c("rig-hil-slice-big", "hil serve --serial pty --sched-slice-ms 500", "--sched-slice-ms", "500"),
        c("rig-hil-slice-tiny", "hil serve --serial pty --sched-slice-ms 0.01", "--sched-slice-ms", "0.01"),
        c("rig-hil-slice-text", "hil serve --serial pty --sched-slice-ms fast", "--sched-slice-ms", "fast"),
        c("rig-hil-slice-nan", "hil serve --serial pty --sched-slice-ms nan", "--sched-slice-ms", "nan"),
        c("rig-hil-clock", "hil serve --serial pty --clock warp", "--clock", "warp"),
        c("rig-hil-start", "hil serve --serial pty --start later", "--start", "later"),
        c("rig-hil-hv", "hil serve --serial pty --hv maybe", "--hv", "maybe"),
        c("rig-hil-parity", "hil serve --modbus-rtu pty --parity X", "--parity", "X"),
        c("rig-hil-noise-nan", "hil serve --serial pty --noise z3=nan", "--noise", "z3=nan"),
        c("rig-hil-deviation-inf", "hil serve --serial pty --deviation k3=inf", "--deviation", "k3"),
        c("rig-hil-stuck-when", "hil serve --serial pty --stuck z3@soon", "--stuck", "soon"),
        c("rig-hil-stuck-negative", "hil serve --serial pty --stuck z3@-1", "--stuck", ">= 0"),
        c("rig-hil-latency-inf", "hil serve --serial pty --latency-ms inf", "--latency-ms", "inf"),
        c("rig-hil-disconnect-nan", "hil serve --serial pty --disconnect-at nan", "--disconnect-at", "nan"),
        c("rig-run-slice-negative", f"run --link modbus-tcp://127.0.0.1:1 --sched-slice-ms -1 {OUT}",
          "--sched-slice-ms", "0.1 .. 100"),
        c("rig-run-slice-big", f"run --link modbus-tcp://127.0.0.1:1 --sched-slice-ms 1000 {OUT}", "--sched-slice-ms",
          "1000"),
    ]


def newer_rig_cases() -> list[Case]:
    cases = link_url_cases() + hil_option_cases()
    ids = [c.id for c in cases]
    assert len(ids) == len(set(ids)), "duplicate case ids"
    return cases


# ------------------------------------------------------------------------------------------------------------
# the register map
NAN, INF, NEG_INF = (0x7FC0, 0x0000), (0x7F80, 0x0000), (0xFF80, 0x0000)


@dataclass(frozen=True)
class RegisterCase:
    """A request PDU (function code + data, unit 1) the stub must refuse with ``exception``; ``reaches_rig``: the rig
    itself sees and counts it (a finite demand outside Table 1), otherwise nothing about the rig may change."""

    id: str
    pdu: bytes
    exception: int
    reaches_rig: bool = False


def _words(v1: tuple[int, int] = (0x42C8, 0), v2: tuple[int, int] = (0, 0), cur: tuple[int, int] = (0, 0),
           seq: int = 7) -> list[int]:
    """A command block (holding 0-7): v_ch1 (default 100 V), v_ch2, board_current as float32 words, cmd_seq."""
    return [*v1, *v2, *cur, seq >> 16, seq & 0xFFFF]


def _f32(x: float) -> tuple[int, int]:
    hi, lo = struct.unpack(">HH", struct.pack(">f", x))
    return hi, lo


def _fc16(words: list[int], address: int = COMMAND_START, qty: int | None = None, nbytes: int | None = None) -> bytes:
    q = len(words) if qty is None else qty
    n = 2 * len(words) if nbytes is None else nbytes
    return struct.pack(">BHHB", 16, address, q, n) + b"".join(struct.pack(">H", w) for w in words)


def _fc23(words: list[int], read: int = MIRROR_START, read_qty: int = INPUT_COUNT,
          write: int = COMMAND_START) -> bytes:
    return struct.pack(">BHHHHB", 23, read, read_qty, write, len(words), 2 * len(words)) + \
        b"".join(struct.pack(">H", w) for w in words)


REGISTER_CASES: list[RegisterCase] = [
    RegisterCase("fc16-nan-v_ch1", _fc16(_words(v1=NAN)), 3),
    RegisterCase("fc16-inf-v_ch2", _fc16(_words(v2=INF)), 3),
    RegisterCase("fc16-neg-inf-current", _fc16(_words(cur=NEG_INF)), 3),
    RegisterCase("fc16-nan-alone", _fc16(list(NAN)), 3),
    RegisterCase("fc16-nan-board-current-alone", _fc16(list(NAN), address=4), 3),
    RegisterCase("fc23-nan-v_ch1", _fc23(_words(v1=NAN)), 3),
    RegisterCase("fc23-inf-v_ch2", _fc23(_words(v2=INF)), 3),
    RegisterCase("fc06-nan-high-word", struct.pack(">BHH", 6, 0, 0x7FC0), 2),  # one register splits the float
    RegisterCase("fc16-over-limit", _fc16(_words(v1=_f32(1500.5))), 3, reaches_rig=True),
    RegisterCase("fc16-current-over", _fc16(_words(cur=_f32(11.0))), 3, reaches_rig=True),
    RegisterCase("fc16-split-value", _fc16([0x42C8, 0], address=1), 2),
    RegisterCase("fc16-read-only", _fc16([2], address=8), 2),
    RegisterCase("fc16-outside-map", _fc16([0, 0], address=14), 2),
    RegisterCase("fc16-qty-zero", _fc16([], qty=0, nbytes=0), 3),
    RegisterCase("fc16-qty-124", _fc16([0] * 124), 3),
    RegisterCase("fc16-bytecount-mismatch", _fc16(_words(), nbytes=15), 3),
    RegisterCase("fc22-command-block", struct.pack(">BHHH", 22, 0, 0x0000, 0x7FC0), 2),
    RegisterCase("fc22-read-only", struct.pack(">BHHH", 22, 8, 0xFFFF, 0x0000), 2),
    RegisterCase("fc23-write-mirror", _fc23([0, 0], write=MIRROR_START), 2),
    RegisterCase("fc23-read-qty-zero", _fc23(_words(), read_qty=0), 3),
    RegisterCase("fc23-write-qty-122", _fc23([0] * 122), 3),
    RegisterCase("fc05-coil-write", struct.pack(">BHH", 5, 0, 0xFF00), 2),
    RegisterCase("fc15-coil-write", struct.pack(">BHHBB", 15, 0, 1, 1, 1), 2),
    RegisterCase("fc03-qty-126", struct.pack(">BHH", 3, 0, 126), 3),
    RegisterCase("fc04-outside-map", struct.pack(">BHH", 4, 22, 1), 2),
    RegisterCase("fc07-exception-status", bytes([7]), 1),
    RegisterCase("fc08-diagnostics", bytes([8, 0, 0, 0x12, 0x34]), 1),
    RegisterCase("fc11-comm-event-counter", bytes([11]), 1),
    RegisterCase("fc17-report-server-id", bytes([17]), 1),
    RegisterCase("fc20-read-file-record", bytes([20, 7, 6, 0, 4, 0, 1, 0, 1]), 1),
    RegisterCase("fc21-write-file-record", bytes([21, 9, 6, 0, 4, 0, 1, 0, 1, 0x7F, 0xC0]), 1),
    RegisterCase("fc24-read-fifo", struct.pack(">BH", 24, 0), 1),
    RegisterCase("fc43-device-identification", bytes([43, 14, 1, 0]), 1),
    RegisterCase("fc65-user-defined", bytes([65, 1, 2]), 1),
]
