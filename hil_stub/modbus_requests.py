"""What the stub's Modbus server answers before pymodbus decodes a request (docs/registers.md, "Errors and what the
rig answers"): a function code the map does not serve, a quantity or byte count out of range. Pure.

pymodbus 3.16 answers an unknown function code and a bad quantity alike with exception 01 on function 0x80, and
decodes some codes the map does not serve (FC 21 "write file record") itself; :func:`check_request_pdu` gives the
exception the spec wants, which :meth:`hil_stub.modbus_server.ModbusRigServer.precheck` sends.
"""

from __future__ import annotations

import struct

#: the function codes the map serves (docs/registers.md); pymodbus decodes these, every other one is answered with
#: ILLEGAL FUNCTION (pymodbus would also decode e.g. FC 21 "write file record" and answer it from a datastore that
#: has no files)
SERVED_FUNCTIONS = frozenset({1, 2, 3, 4, 5, 6, 15, 16, 22, 23})


def check_request_pdu(pdu: bytes) -> int | None:
    """The Modbus exception a request PDU (function code + data) deserves before it reaches the datastore, or None.

    pymodbus 3.16 answers an unknown function code and a bad quantity alike with exception 01 on function 0x80;
    the spec wants 01 (ILLEGAL FUNCTION) echoing the function code, and 03 (ILLEGAL DATA VALUE) for a quantity or
    byte count out of range. Pure.
    """
    if not pdu:
        return None
    fc = pdu[0]
    if fc not in SERVED_FUNCTIONS:
        return 0x01
    if fc == 22:
        return None if len(pdu) == 7 else 0x03
    if fc == 23:
        if len(pdu) < 10:
            return 0x03
        (_ra, r_qty, _wa, w_qty, nbytes) = struct.unpack(">HHHHB", pdu[1:10])
        if not 1 <= r_qty <= 125 or not 1 <= w_qty <= 121 or nbytes != 2 * w_qty or len(pdu) != 10 + nbytes:
            return 0x03
        return None
    if fc in (1, 2, 3, 4, 5, 6):
        if len(pdu) != 5:
            return 0x03
        (_addr, value) = struct.unpack(">HH", pdu[1:5])
        if fc in (1, 2) and not 1 <= value <= 2000:
            return 0x03
        if fc in (3, 4) and not 1 <= value <= 125:
            return 0x03
        if fc == 5 and value not in (0x0000, 0xFF00):
            return 0x03
        return None
    if fc in (15, 16):
        if len(pdu) < 6:
            return 0x03
        (_addr, qty, nbytes) = struct.unpack(">HHB", pdu[1:6])
        want = (qty + 7) // 8 if fc == 15 else 2 * qty
        limit = 1968 if fc == 15 else 123
        if not 1 <= qty <= limit or nbytes != want or len(pdu) != 6 + nbytes:
            return 0x03
    return None
