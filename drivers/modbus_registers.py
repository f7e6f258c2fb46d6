"""The rig's Modbus register map: addresses, types, units, scaling, access and ranges, and its codecs.

Pure logic (no I/O). Both sides use it: :class:`drivers.modbus_link.ModbusLink` (the board, Modbus master)
and the HIL stub's Modbus server. ``docs/registers.md`` is generated from :data:`REGISTER_MAP`
(``python -m drivers.modbus_registers``) and a test keeps the two in step.

Conventions
-----------
* Addresses are 0-based protocol addresses (what goes in the PDU). Tools that count from 1 (mbpoll without
  ``-0``, most HMIs) show address + 1.
* Encoding: every register is big-endian (high byte first, as Modbus requires). 32- and 64-bit values span
  consecutive registers with the **most significant word first** ("big-endian word order", byte order
  ABCD for float32 and ABCDEFGH for float64; mbpoll reads them with ``-t 3:float -B``).
* Floats are IEEE-754 in SI units (scale 1). The scaled int16/uint16 mirrors are for HMIs that cannot read
  floats: engineering value = raw × scale; values beyond the integer range saturate.
* A value never appears in a register as NaN or Inf: the rig replaces it by 0 and sets the sensor-fault flag.
* Writes must cover whole values (a float32 is written as both of its registers in one request); a write
  that splits a value, touches an address outside the map or a read-only register is refused with
  exception 02 (ILLEGAL DATA ADDRESS); a set-point outside its range with exception 03 (ILLEGAL DATA
  VALUE). A refused write changes nothing.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass
from enum import IntEnum
from typing import Literal

from drivers.link import FLAG_SENSOR_FAULT, ActuatorCommand, RigSample

Table = Literal["input", "holding", "coil", "discrete"]
DType = Literal["float32", "float64", "uint32", "uint16", "int16", "bit"]
#: the version a rig of this map announces (holding 8): 2 = version 1 + the sample mirror (holding 100-121) and
#: FC 23; the board drives version 1 rigs too, with FC 16 + FC 04 per tick
MAP_VERSION = 2
#: the map versions the board can drive; FC 23 from this version on
SUPPORTED_MAP_VERSIONS = (1, 2)
FC23_MAP_VERSION = 2

_WORDS = {"float32": 2, "float64": 4, "uint32": 2, "uint16": 1, "int16": 1, "bit": 1}
_STRUCT = {"float32": ">f", "float64": ">d", "uint32": ">I", "uint16": ">H", "int16": ">h"}


class ModbusExceptionCode(IntEnum):
    """Modbus exception codes used by the rig."""

    ILLEGAL_FUNCTION = 0x01
    ILLEGAL_ADDRESS = 0x02
    ILLEGAL_VALUE = 0x03
    DEVICE_FAILURE = 0x04


@dataclass(frozen=True)
class Register:
    """One entry of the map."""

    name: str
    table: Table
    address: int
    dtype: DType
    unit: str
    description: str
    writable: bool = False
    scale: float = 1.0
    lower: float | None = None
    upper: float | None = None

    @property
    def words(self) -> int:
        return _WORDS[self.dtype]

    @property
    def end(self) -> int:
        """One past the last address the value occupies."""
        return self.address + self.words


# Status word bits (input register ``status``): the low byte is RigSample.flags as is.
STATUS_FLAGS_MASK = 0x00FF
STATUS_HV_PRESENT = 0x0100

#: the map; the board's exchange writes holding 0..7 (FC16) and reads input 0..21 (FC04)
REGISTER_MAP: tuple[Register, ...] = (
    # ---- input registers (FC 04): the rig's latest sample, refreshed by the rig loop every tick
    Register("rig_seq", "input", 0, "uint32", "count", "rig sample counter (frozen value = stale sensor path)"),
    Register("t", "input", 2, "float64", "s", "rig time of the sample"),
    Register("z3", "input", 6, "float32", "m", "laser tip displacement z3"),
    Register("v_patch", "input", 8, "float32", "V", "patch terminal voltage"),
    Register("z0dd", "input", 10, "float32", "m/s^2", "base acceleration"),
    Register("v_battery", "input", 12, "float32", "V", "board battery terminal voltage"),
    Register("cmd_seq_applied", "input", 14, "uint32", "count", "sequence number of the last command accepted"),
    Register("status", "input", 16, "uint16", "bits",
             "bits 0-7 RigSample.flags (0 sensor fault, 1 limit refused, 2 rig fault); "
             "bit 8 HV equipment present"),
    Register("refused_count", "input", 17, "uint16", "count", "commands refused so far (wraps at 65536)"),
    Register("z3_scaled", "input", 18, "int16", "m", "z3 for HMIs, 0.01 mm per LSB (saturates at ±327.67 mm)",
             scale=1e-5),
    Register("v_patch_scaled", "input", 19, "int16", "V", "v_patch for HMIs, 0.1 V per LSB", scale=0.1),
    Register("z0dd_scaled", "input", 20, "int16", "m/s^2", "z0dd for HMIs, 0.01 m/s^2 per LSB", scale=0.01),
    Register("v_battery_scaled", "input", 21, "uint16", "V", "v_battery for HMIs, 1 mV per LSB", scale=1e-3),
    # ---- holding registers (FC 03 read, FC 06/16 write): the board's command and rig settings
    Register("v_ch1", "holding", 0, "float32", "V", "amplifier channel 1 demand", True, lower=-500.0, upper=1500.0),
    Register("v_ch2", "holding", 2, "float32", "V", "amplifier channel 2 demand", True, lower=-500.0, upper=1500.0),
    Register("board_current", "holding", 4, "float32", "A", "current drawn by the board electronics", True,
             lower=0.0, upper=10.0),
    Register("cmd_seq", "holding", 6, "uint32", "count", "board tick counter of this command", True),
    Register("map_version", "holding", 8, "uint16", "1", "version of this register map"),
    Register("rig_tick", "holding", 9, "uint16", "s", "the rig's tick, 0.1 ms per LSB", scale=1e-4),
    Register("v_limit_min", "holding", 10, "float32", "V", "lowest channel demand the rig accepts (Table 1)"),
    Register("v_limit_max", "holding", 12, "float32", "V", "highest channel demand the rig accepts (Table 1)"),
    # ---- coils (FC 01 read, FC 05/15 write)
    Register("amplifier_active", "coil", 0, "bit", "1", "the applied demand is not 0 V (read-only)"),
    # ---- discrete inputs (FC 02)
    Register("hv_present", "discrete", 0, "bit", "1", "external high-voltage equipment connected"),
    Register("sensor_fault", "discrete", 1, "bit", "1", "sensor fault flag"),
    Register("limit_refused", "discrete", 2, "bit", "1", "last command refused (outside limits)"),
    Register("rig_fault", "discrete", 3, "bit", "1", "rig fault flag"),
)

BY_NAME: dict[str, Register] = {r.name: r for r in REGISTER_MAP}


def _span(table: Table) -> tuple[int, int]:
    regs = [r for r in REGISTER_MAP if r.table == table]
    return min(r.address for r in regs), max(r.end for r in regs)


INPUT_START, INPUT_END = _span("input")  # 0, 22
HOLDING_START, HOLDING_END = _span("holding")  # 0, 14
COMMAND_START, COMMAND_END = 0, 8  # holding block the board writes each tick
INPUT_COUNT = INPUT_END - INPUT_START
#: map version 2: holding registers MIRROR_START .. MIRROR_START + INPUT_COUNT - 1 hold the sample block again (input
#: registers 0-21, same layout, read-only), so that one FC 23 writes the command (holding 0-7) and reads the sample
MIRROR_START = 100
MIRROR_END = MIRROR_START + INPUT_COUNT
HOLDING_COUNT = HOLDING_END - HOLDING_START
DISCRETE_COUNT = _span("discrete")[1]
COIL_COUNT = _span("coil")[1]


# ------------------------------------------------------------------------------------------- scalar codecs


def encode_value(reg: Register, value: float) -> list[int]:
    """The registers holding ``value`` (engineering units) for ``reg``; ints saturate, floats must be finite."""
    if reg.dtype == "bit":
        return [1 if value else 0]
    if reg.dtype in ("float32", "float64"):
        v = float(value)
        if not math.isfinite(v):
            v = 0.0
        if reg.dtype == "float32":
            v = max(min(v, 3.4028234663852886e38), -3.4028234663852886e38)
        raw = struct.pack(_STRUCT[reg.dtype], v)
    else:
        fmt = _STRUCT[reg.dtype]
        lo, hi = {">I": (0, 2**32 - 1), ">H": (0, 2**16 - 1), ">h": (-(2**15), 2**15 - 1)}[fmt]
        x = float(value) / reg.scale if math.isfinite(float(value)) else 0.0
        n = (hi if x > 0 else lo) if math.isinf(x) else int(min(max(round(x), lo), hi))  # huge values saturate
        raw = struct.pack(fmt, n)
    return [int.from_bytes(raw[i : i + 2], "big") for i in range(0, len(raw), 2)]


def decode_value(reg: Register, words: list[int] | tuple[int, ...]) -> float:
    """The engineering value of ``reg`` from its registers."""
    if len(words) != reg.words:
        raise ValueError(f"register {reg.name}: expected {reg.words} word(s), got {len(words)}")
    if reg.dtype == "bit":
        return float(bool(words[0]))
    raw = b"".join(int(w & 0xFFFF).to_bytes(2, "big") for w in words)
    (x,) = struct.unpack(_STRUCT[reg.dtype], raw)
    return float(x) * reg.scale  # floats have scale 1


def float32_to_registers(value: float) -> list[int]:
    """IEEE-754 float32, high word first (ABCD)."""
    return encode_value(BY_NAME["z3"], value)


def registers_to_float32(words: list[int]) -> float:
    return decode_value(BY_NAME["z3"], words)


# ------------------------------------------------------------------------------------------- block codecs


def _put(block: list[int], start: int, name: str, value: float) -> None:
    reg = BY_NAME[name]
    off = reg.address - start
    block[off : off + reg.words] = encode_value(reg, value)


def _get(block: list[int] | tuple[int, ...], start: int, name: str) -> float:
    reg = BY_NAME[name]
    off = reg.address - start
    return decode_value(reg, list(block[off : off + reg.words]))


def status_word(sample: RigSample) -> int:
    return (sample.flags & STATUS_FLAGS_MASK) | (STATUS_HV_PRESENT if sample.hv_present else 0)


_BLOCK = struct.Struct(">IdffffIHHhhhH")  # the input block's 22 registers in map order (checked at import)
_F32_MAX = 3.4028234663852886e38


def _f(x: float) -> float:
    """A float register's value: non-finite -> 0, float32 range saturated (as :func:`encode_value`)."""
    return max(min(x, _F32_MAX), -_F32_MAX) if math.isfinite(x) else 0.0


def _i(x: float, scale: float, lo: int, hi: int) -> int:
    """A scaled integer register's value (as :func:`encode_value`): rounded, saturated, non-finite -> 0."""
    if not math.isfinite(x):
        return 0
    y = x / scale  # may overflow to +-inf for a huge finite x: saturated like any out-of-range value
    return (hi if y > 0 else lo) if math.isinf(y) else int(min(max(round(y), lo), hi))


def encode_input_block(sample: RigSample, cmd_seq_applied: int = 0, refused_count: int = 0) -> list[int]:
    """Input registers INPUT_START..INPUT_END-1 for ``sample`` (non-finite values must be sanitised first).

    One ``struct.pack`` of the whole block (a request of the stub encodes it; the per-register
    :func:`encode_input_block_by_register` is ~10x slower and gives the same registers: a test holds them equal)."""
    t = float(sample.t)
    raw = _BLOCK.pack(sample.seq & 0xFFFFFFFF, t if math.isfinite(t) else 0.0, _f(sample.z3), _f(sample.v_patch),
                      _f(sample.z0dd), _f(sample.v_battery), cmd_seq_applied & 0xFFFFFFFF, status_word(sample),
                      refused_count & 0xFFFF, _i(sample.z3, 1e-5, -32768, 32767),
                      _i(sample.v_patch, 0.1, -32768, 32767), _i(sample.z0dd, 0.01, -32768, 32767),
                      _i(sample.v_battery, 1e-3, 0, 65535))
    return list(struct.unpack(">22H", raw))


def encode_input_block_by_register(sample: RigSample, cmd_seq_applied: int = 0, refused_count: int = 0) -> list[int]:
    """:func:`encode_input_block` register by register through :data:`REGISTER_MAP` (the reference)."""
    b = [0] * INPUT_COUNT
    _put(b, INPUT_START, "rig_seq", sample.seq & 0xFFFFFFFF)
    _put(b, INPUT_START, "t", sample.t)
    for name in ("z3", "v_patch", "z0dd", "v_battery"):
        _put(b, INPUT_START, name, getattr(sample, name))
        _put(b, INPUT_START, f"{name}_scaled", getattr(sample, name))
    _put(b, INPUT_START, "cmd_seq_applied", cmd_seq_applied & 0xFFFFFFFF)
    _put(b, INPUT_START, "status", status_word(sample))
    _put(b, INPUT_START, "refused_count", refused_count & 0xFFFF)
    return b


@dataclass(frozen=True)
class InputBlock:
    """The decoded input registers."""

    sample: RigSample
    cmd_seq_applied: int
    refused_count: int


def decode_input_block(words: list[int] | tuple[int, ...]) -> InputBlock:
    """Decode a read of input registers INPUT_START..INPUT_END-1 (a non-finite value sets FLAG_SENSOR_FAULT)."""
    if len(words) != INPUT_COUNT:
        raise ValueError(f"input block: expected {INPUT_COUNT} registers, got {len(words)}")
    status = int(_get(words, INPUT_START, "status"))
    flags = status & STATUS_FLAGS_MASK
    values = {n: _get(words, INPUT_START, n) for n in ("t", "z3", "v_patch", "z0dd", "v_battery")}
    if not all(math.isfinite(v) for v in values.values()):
        flags |= FLAG_SENSOR_FAULT
    sample = RigSample(seq=int(_get(words, INPUT_START, "rig_seq")), hv_present=bool(status & STATUS_HV_PRESENT),
                       flags=flags, **values)
    return InputBlock(sample, int(_get(words, INPUT_START, "cmd_seq_applied")),
                      int(_get(words, INPUT_START, "refused_count")))


def encode_command_block(command: ActuatorCommand) -> list[int]:
    """Holding registers COMMAND_START..COMMAND_END-1 for ``command`` (values must be finite)."""
    for name in ("v_ch1", "v_ch2", "board_current"):
        if not math.isfinite(getattr(command, name)):
            raise ValueError(f"command seq {command.seq}: {name}={getattr(command, name)!r} is not finite")
    b = [0] * (COMMAND_END - COMMAND_START)
    for name in ("v_ch1", "v_ch2", "board_current"):
        _put(b, COMMAND_START, name, getattr(command, name))
    _put(b, COMMAND_START, "cmd_seq", command.seq & 0xFFFFFFFF)
    return b


def decode_command_block(words: list[int] | tuple[int, ...]) -> ActuatorCommand:
    if len(words) != COMMAND_END - COMMAND_START:
        raise ValueError(f"command block: expected {COMMAND_END - COMMAND_START} registers, got {len(words)}")
    return ActuatorCommand(seq=int(_get(words, COMMAND_START, "cmd_seq")),
                           v_ch1=_get(words, COMMAND_START, "v_ch1"), v_ch2=_get(words, COMMAND_START, "v_ch2"),
                           board_current=_get(words, COMMAND_START, "board_current"))


def initial_holding_block(v_min: float = -500.0, v_max: float = 1500.0, tick: float = 0.01,
                          map_version: int = MAP_VERSION) -> list[int]:
    """Holding registers at power-up: zero command, the map version, the rig's limits (V) and tick (s)."""
    b = [0] * HOLDING_COUNT
    _put(b, HOLDING_START, "map_version", map_version)
    _put(b, HOLDING_START, "rig_tick", tick)
    _put(b, HOLDING_START, "v_limit_min", v_min)
    _put(b, HOLDING_START, "v_limit_max", v_max)
    return b


# ------------------------------------------------------------------------------------------- write checks


@dataclass(frozen=True)
class WriteVerdict:
    """The outcome of checking a write request: ``code`` None means accepted."""

    code: ModbusExceptionCode | None
    reason: str = ""
    changed: tuple[str, ...] = ()
    #: False when a written value is NaN or ±Inf: refused before it reaches the rig (no count, no flag)
    finite: bool = True


def check_holding_write(address: int, values: list[int] | tuple[int, ...], current: list[int] | tuple[int, ...],
                        v_min: float = -500.0, v_max: float = 1500.0) -> WriteVerdict:
    """Check a write of ``values`` at holding ``address`` against the map, given the ``current`` block.

    Every written register must belong to a writable entry, whole entries only; every new value must be in
    range (channel demands within ``[v_min, v_max]``, Table 1). Pure: returns a verdict, changes nothing.
    """
    end = address + len(values)
    if not values:
        return WriteVerdict(ModbusExceptionCode.ILLEGAL_VALUE, "empty write")
    if address < HOLDING_START or end > HOLDING_END:
        return WriteVerdict(ModbusExceptionCode.ILLEGAL_ADDRESS,
                            f"holding {address}..{end - 1} outside the map ({HOLDING_START}..{HOLDING_END - 1})")
    touched = [r for r in REGISTER_MAP if r.table == "holding" and r.address < end and r.end > address]
    for r in touched:
        if not r.writable:
            return WriteVerdict(ModbusExceptionCode.ILLEGAL_ADDRESS, f"'{r.name}' (holding {r.address}) is read-only")
        if r.address < address or r.end > end:
            return WriteVerdict(ModbusExceptionCode.ILLEGAL_ADDRESS,
                                f"write {address}..{end - 1} splits '{r.name}' (holding {r.address}..{r.end - 1})")
    new = list(current)
    new[address - HOLDING_START : end - HOLDING_START] = [int(v) & 0xFFFF for v in values]
    for r in touched:
        v = _get(new, HOLDING_START, r.name)
        lo, hi = r.lower, r.upper
        if r.name in ("v_ch1", "v_ch2"):
            lo, hi = v_min, v_max
        if not math.isfinite(v):
            return WriteVerdict(ModbusExceptionCode.ILLEGAL_VALUE, f"'{r.name}'={v!r} {r.unit} is not a finite "
                                f"number (allowed range [{lo}, {hi}])", finite=False)
        if (lo is not None and v < lo) or (hi is not None and v > hi):
            return WriteVerdict(ModbusExceptionCode.ILLEGAL_VALUE,
                                f"'{r.name}'={v!r} {r.unit} outside the allowed range [{lo}, {hi}]")
    return WriteVerdict(None, "", tuple(r.name for r in touched))


# ------------------------------------------------------------------------------------------- documentation


def markdown_table() -> str:
    """The register map as the Markdown tables of ``docs/registers.md``."""
    titles = {"input": "Input registers (FC 04, read-only)",
              "holding": "Holding registers (FC 03 read; FC 06/16 write)",
              "coil": "Coils (FC 01 read; writes refused, exception 02)",
              "discrete": "Discrete inputs (FC 02, read-only)"}
    out: list[str] = []
    for table, title in titles.items():
        out += [f"### {title}", "",
                "| address | mbpoll -r | name | type | words | unit | scale | access | range | description |",
                "| ---: | ---: | --- | --- | ---: | --- | --- | --- | --- | --- |"]
        for r in REGISTER_MAP:
            if r.table != table:
                continue
            rng = ""
            if r.lower is not None or r.upper is not None:
                rng = f"{r.lower:g} … {r.upper:g}"
            span = f"{r.address}" if r.words == 1 else f"{r.address}–{r.end - 1}"
            scale = "IEEE-754" if r.dtype.startswith("float") else f"{r.scale:g}"
            out.append(f"| {span} | {r.address + 1} | `{r.name}` | {r.dtype} | {r.words} | {r.unit} | {scale} | "
                       f"{'R/W' if r.writable else 'R'} | {rng} | {r.description} |")
        out.append("")
        if table == "holding":
            out += [f"Map version 2 adds the **sample mirror**: holding {MIRROR_START}–{MIRROR_END - 1} (mbpoll -r "
                    f"{MIRROR_START + 1}) hold input registers {INPUT_START}–{INPUT_END - 1} again, same layout, "
                    "read-only (FC 03 or the read part of FC 23; writes refused with exception 02).", ""]
    return "\n".join(out)


if __name__ == "__main__":
    print(markdown_table())
