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

from bad_inputs_corpus import Case, case_table, unique_ids

from drivers.modbus_registers import COMMAND_START, INPUT_COUNT, MIRROR_START


def link_url_cases() -> list[Case]:
    """A bad URL for every scheme: host, port, IPv6 brackets, path, query values, unknown options and schemes."""
    return case_table("rig_link_urls.txt")


def hil_option_cases() -> list[Case]:
    """`shm hil serve` endpoints and options refused at parse time (before the rig is built), and `shm run`'s and
    `shm hil serve`'s --sched-slice-ms."""
    return case_table("rig_hil_options.txt")


def newer_rig_cases() -> list[Case]:
    return unique_ids(link_url_cases() + hil_option_cases())


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
