"""The rig's identity block (holding registers 8-13: map version, tick, Table 1 limits) and why a rig cannot be
driven (:func:`rig_identity_problem`, pure); :class:`RigMismatchError` for a peer serving another map."""

from __future__ import annotations

from drivers.link import LinkError
from drivers.modbus_registers import BY_NAME, SUPPORTED_MAP_VERSIONS, decode_value


class RigMismatchError(LinkError):
    """The peer answers but is not a rig this board can drive (another map version, word order, limits or tick)."""


ID_START = 8  # holding map_version .. v_limit_max
ID_COUNT = 6


def rig_identity_problem(words: list[int], tick: float = 0.01) -> str:
    """Why the rig whose holding registers 8–13 are ``words`` cannot be driven ('' if it can). Pure.

    Checks the map version, the rig's tick and the Table 1 limits, and tells a wrong float word order (CDAB) by
    the limits decoding correctly only with the words swapped.
    """
    from board_config import load_mfc_limits

    limits = load_mfc_limits()
    version = words[0]
    if version not in SUPPORTED_MAP_VERSIONS:
        return (f"map_version is {version}, this board speaks register map versions "
                f"{', '.join(map(str, SUPPORTED_MAP_VERSIONS))}")
    lo = decode_value(BY_NAME["v_limit_min"], words[2:4])
    hi = decode_value(BY_NAME["v_limit_max"], words[4:6])
    if (lo, hi) != (limits.voltage_min, limits.voltage_max):
        swapped = (decode_value(BY_NAME["v_limit_min"], [words[3], words[2]]),
                   decode_value(BY_NAME["v_limit_max"], [words[5], words[4]]))
        if swapped == (limits.voltage_min, limits.voltage_max):
            return ("float word order is low word first (CDAB); the map needs the high word first (ABCD): "
                    f"v_limit_min reads {lo:g} V instead of {limits.voltage_min:g} V")
        return (f"its channel limits are [{lo:g}, {hi:g}] V, the board's Table 1 limits are "
                f"[{limits.voltage_min:g}, {limits.voltage_max:g}] V")
    rig_tick = decode_value(BY_NAME["rig_tick"], words[1:2])
    if abs(rig_tick - tick) > 0.5e-4:
        return f"rig_tick is {1e3 * rig_tick:g} ms, the board ticks every {1e3 * tick:g} ms"
    return ""
