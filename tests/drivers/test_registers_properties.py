"""The Modbus register map (docs/registers.md is the oracle): the encodings (float32 word order stated and checked
against pymodbus), the block codecs, the write checks and the generated docs table; Table 1 set-points exactly at
the limit are accepted, one float32 step beyond is refused with exception 03; whole-value, read-only and out-of-map
writes are refused with exception 02; integers saturate; no NaN ever sits in a register."""

from __future__ import annotations

import itertools
import math
import re
import struct
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from pymodbus.client import ModbusTcpClient

from drivers.link import FLAG_LIMIT_REFUSED, FLAG_RIG_FAULT, FLAG_SENSOR_FAULT, ActuatorCommand, RigSample
from drivers.modbus_registers import (
    BY_NAME,
    COIL_COUNT,
    COMMAND_END,
    COMMAND_START,
    DISCRETE_COUNT,
    HOLDING_COUNT,
    HOLDING_END,
    INPUT_COUNT,
    MAP_VERSION,
    REGISTER_MAP,
    STATUS_HV_PRESENT,
    ModbusExceptionCode,
    WriteVerdict,
    check_holding_write,
    decode_command_block,
    decode_input_block,
    decode_value,
    encode_command_block,
    encode_input_block,
    encode_value,
    float32_to_registers,
    initial_holding_block,
    markdown_table,
    registers_to_float32,
    status_word,
)

DOC = (Path(__file__).resolve().parents[2] / "docs" / "registers.md").read_text()
F32_MAX = float(np.finfo(np.float32).max)
f32 = st.floats(width=32, allow_nan=False, allow_infinity=False)
ADDR, VALUE = ModbusExceptionCode.ILLEGAL_ADDRESS, ModbusExceptionCode.ILLEGAL_VALUE


def above(x: float) -> float:
    return float(np.nextafter(np.float32(x), np.float32(np.inf)))


def below(x: float) -> float:
    return float(np.nextafter(np.float32(x), np.float32(-np.inf)))


def command(v1=0.0, v2=0.0, cur=0.0, seq=1) -> list[int]:
    return encode_command_block(ActuatorCommand(seq, v1, v2, cur))


CURRENT = initial_holding_block()


def test_documented_word_order_examples():
    for value, hexval in re.findall(r"([−\-\d.]+) (?:as float32 )?is `0x([0-9A-F]{8})`", DOC):
        x = float(value.replace("−", "-"))
        words = [int(hexval[:4], 16), int(hexval[4:], 16)]
        assert float32_to_registers(x) == words
        assert registers_to_float32(words) == x


def test_block_sizes_are_the_documented_spans():
    assert (INPUT_COUNT, HOLDING_COUNT, DISCRETE_COUNT, COIL_COUNT) == (22, 14, 4, 1)
    assert "holding 0–7" in DOC and "0–21" in DOC and (COMMAND_START, COMMAND_END) == (0, 8)


@pytest.mark.parametrize(("name", "lo", "hi"), [("v_ch1", -500.0, 1500.0), ("v_ch2", -500.0, 1500.0),
                                                ("board_current", 0.0, 10.0)])
def test_set_points_exactly_at_a_table1_limit_are_accepted(name, lo, hi):
    reg = BY_NAME[name]
    for ok in (lo, hi):
        v = check_holding_write(reg.address, encode_value(reg, ok), CURRENT)
        assert v == WriteVerdict(None, "", (name,)), ok
    for bad in (below(lo), above(hi), math.nan, math.inf):
        before = list(CURRENT)
        words = (encode_value(reg, bad) if math.isfinite(bad)
                 else list(struct.unpack(">HH", struct.pack(">f", bad))))  # what a foreign master could send
        v = check_holding_write(reg.address, words, CURRENT)
        assert v.code is VALUE, bad
        assert f"'{name}'=" in v.reason and f"[{lo}, {hi}]" in v.reason
        assert CURRENT == before  # a refused write changes nothing


def test_the_whole_command_block_at_the_limits():
    v = check_holding_write(0, command(1500.0, -500.0, 10.0, seq=2**32 - 1), CURRENT)
    assert v.code is None and v.changed == ("v_ch1", "v_ch2", "board_current", "cmd_seq")
    v = check_holding_write(0, command(-500.0, 1500.0, 0.0), CURRENT)
    assert v.code is None
    assert check_holding_write(0, command(1500.0, above(1500.0), 0.0), CURRENT).code is VALUE


def test_the_rigs_own_limits_replace_table1_for_the_channels():
    for name in ("v_ch1", "v_ch2"):
        reg = BY_NAME[name]
        assert check_holding_write(reg.address, encode_value(reg, 100.0), CURRENT, -100.0, 100.0).code is None
        assert check_holding_write(reg.address, encode_value(reg, -100.0), CURRENT, -100.0, 100.0).code is None
        v = check_holding_write(reg.address, encode_value(reg, 101.0), CURRENT, -100.0, 100.0)
        assert v.code is VALUE and "[-100.0, 100.0]" in v.reason
        assert check_holding_write(reg.address, encode_value(reg, -101.0), CURRENT, -100.0, 100.0).code is VALUE
    reg = BY_NAME["board_current"]  # not a channel: its own range stays
    assert check_holding_write(reg.address, encode_value(reg, 10.0), CURRENT, -1.0, 1.0).code is None


@pytest.mark.parametrize(("address", "n", "code", "says"), [
    (0, 0, VALUE, "empty write"),
    (-1, 2, ADDR, "holding -1..0 outside the map (0..13)"),
    (HOLDING_END, 1, ADDR, "holding 14..14 outside the map (0..13)"),
    (HOLDING_END - 1, 2, ADDR, "holding 13..14 outside the map (0..13)"),
    (HOLDING_END - 2, 2, ADDR, "'v_limit_max' (holding 12) is read-only"),
    (8, 1, ADDR, "'map_version' (holding 8) is read-only"),
    (1, 1, ADDR, "write 1..1 splits 'v_ch1' (holding 0..1)"),
    (0, 3, ADDR, "write 0..2 splits 'v_ch2' (holding 2..3)"),
    (6, 3, ADDR, "'map_version' (holding 8) is read-only"),
])
def test_writes_refused_with_exception_02_or_03(address, n, code, says):
    v = check_holding_write(address, [0] * n, CURRENT)
    assert v.code is code and v.reason == says and v.changed == ()


def test_cmd_seq_has_no_range_and_a_single_register_write_of_a_whole_value_is_fine():
    assert check_holding_write(6, [0xFFFF, 0xFFFF], CURRENT).changed == ("cmd_seq",)
    assert check_holding_write(4, encode_value(BY_NAME["board_current"], 0.5), CURRENT).changed == ("board_current",)
    # only the written registers are new: a bad value already in the block elsewhere is not re-checked
    odd = list(CURRENT)
    odd[2:4] = encode_value(BY_NAME["v_ch2"], 5000.0)
    assert check_holding_write(0, encode_value(BY_NAME["v_ch1"], 5.0), odd).code is None


def test_integers_round_and_saturate_at_their_type():
    vp = BY_NAME["v_patch_scaled"]  # int16, 0.1 V per LSB
    assert encode_value(vp, 12.34) == [123] and encode_value(vp, 12.36) == [124]
    assert encode_value(vp, 1e9) == [0x7FFF] and encode_value(vp, -1e9) == [0x8000]
    assert decode_value(vp, [0x7FFF]) == pytest.approx(3276.7) and decode_value(vp, [0x8000]) == pytest.approx(-3276.8)
    vb = BY_NAME["v_battery_scaled"]  # uint16, 1 mV
    assert encode_value(vb, -3.0) == [0] and encode_value(vb, 1e6) == [0xFFFF]
    assert decode_value(vb, [3050]) == pytest.approx(3.05)
    seq = BY_NAME["rig_seq"]
    assert encode_value(seq, 2**32 - 1) == [0xFFFF, 0xFFFF] and encode_value(seq, 2**40) == [0xFFFF, 0xFFFF]
    assert encode_value(seq, 65537) == [1, 1] and decode_value(seq, [1, 1]) == 65537
    assert encode_value(vp, math.nan) == [0]
    assert encode_value(BY_NAME["hv_present"], 2) == [1] and encode_value(BY_NAME["hv_present"], 0) == [0]
    assert decode_value(BY_NAME["hv_present"], [7]) == 1.0 and decode_value(BY_NAME["hv_present"], [0]) == 0.0


def test_floats_never_carry_nan_and_float32_saturates():
    z3 = BY_NAME["z3"]
    for bad in (math.nan, math.inf, -math.inf):
        assert encode_value(z3, bad) == [0, 0] and encode_value(BY_NAME["t"], bad) == [0, 0, 0, 0]
    assert registers_to_float32(encode_value(z3, 1e39)) == F32_MAX
    assert registers_to_float32(encode_value(z3, -1e39)) == -F32_MAX
    assert decode_value(z3, [0x13FC0, 0]) == 1.5  # words are 16 bit
    with pytest.raises(ValueError, match="register z3: expected 2 word"):
        decode_value(z3, [0])


def sample(**kw) -> RigSample:
    base = {"seq": 7, "t": 0.07, "z3": 1e-3, "v_patch": 12.5, "z0dd": -0.25, "v_battery": 3.05, "hv_present": True,
            "flags": FLAG_LIMIT_REFUSED | FLAG_RIG_FAULT}
    return RigSample(**(base | kw))


def test_status_word_and_counters_wrap():
    assert status_word(sample()) == FLAG_LIMIT_REFUSED | FLAG_RIG_FAULT | STATUS_HV_PRESENT
    blk = decode_input_block(encode_input_block(sample()))  # a rig that has applied and refused nothing yet
    assert (blk.cmd_seq_applied, blk.refused_count) == (0, 0)
    assert status_word(sample(hv_present=False, flags=0x1FF)) == 0xFF
    blk = decode_input_block(encode_input_block(sample(seq=2**32 + 3), cmd_seq_applied=2**32 + 9,
                                                refused_count=65536 + 4))
    assert (blk.sample.seq, blk.cmd_seq_applied, blk.refused_count) == (3, 9, 4)
    assert blk.sample.hv_present is True and blk.sample.flags == FLAG_LIMIT_REFUSED | FLAG_RIG_FAULT
    assert blk.sample.v_patch == 12.5 and blk.sample.t == 0.07
    words = encode_input_block(sample())
    assert decode_value(BY_NAME["v_patch_scaled"], words[19:20]) == pytest.approx(12.5)
    assert decode_value(BY_NAME["v_battery_scaled"], words[21:22]) == pytest.approx(3.05)
    assert decode_value(BY_NAME["z3_scaled"], words[18:19]) == pytest.approx(1e-3)
    assert decode_value(BY_NAME["z0dd_scaled"], words[20:21]) == pytest.approx(-0.25)


@pytest.mark.parametrize("name", ["t", "z3", "v_patch", "z0dd", "v_battery"])
def test_a_nan_from_a_foreign_rig_raises_the_sensor_fault_flag(name):
    words = encode_input_block(sample(hv_present=False, flags=FLAG_LIMIT_REFUSED))
    reg = BY_NAME[name]
    nan = list(struct.unpack(f">{reg.words}H", struct.pack(">d" if reg.words == 4 else ">f", math.nan)))
    words[reg.address:reg.end] = nan
    assert decode_input_block(words).sample.flags == FLAG_SENSOR_FAULT | FLAG_LIMIT_REFUSED  # added, others kept
    assert decode_input_block(encode_input_block(sample(flags=0))).sample.flags == 0


def test_blocks_refuse_the_wrong_length_and_commands_refuse_non_finite_values():
    with pytest.raises(ValueError, match=f"input block: expected {INPUT_COUNT} registers, got 3"):
        decode_input_block([0, 0, 0])
    with pytest.raises(ValueError, match="command block: expected 8 registers, got 7"):
        decode_command_block([0] * 7)
    for i, name in enumerate(("v_ch1", "v_ch2", "board_current")):
        vals = [1.0, 2.0, 0.5]
        vals[i] = math.nan
        with pytest.raises(ValueError, match=f"command seq 4: {name}=nan is not finite"):
            encode_command_block(ActuatorCommand(4, *vals))
    cmd = decode_command_block(command(1500.0, -500.0, 10.0, seq=2**32 + 1))
    assert cmd == ActuatorCommand(1, 1500.0, -500.0, 10.0)


def test_power_up_holding_block():
    def get(block, name):
        r = BY_NAME[name]
        return decode_value(r, block[r.address:r.end])

    b = initial_holding_block()
    assert len(b) == HOLDING_COUNT and b[:8] == [0] * 8
    assert (get(b, "map_version"), get(b, "rig_tick"), get(b, "v_limit_min"), get(b, "v_limit_max")) == \
        (MAP_VERSION, pytest.approx(0.01), -500.0, 1500.0)
    b = initial_holding_block(-100.0, 200.0, 0.005)
    assert (get(b, "rig_tick"), get(b, "v_limit_min"), get(b, "v_limit_max")) == (pytest.approx(0.005), -100.0, 200.0)


# --- encodings against pymodbus, block round trips, the map, the write table, the docs table -------------------


def test_float32_is_ieee754_big_endian_high_word_first():
    assert float32_to_registers(1.5) == [0x3FC0, 0x0000]
    assert float32_to_registers(-500.0) == [0xC3FA, 0x0000]
    assert float32_to_registers(600.0) == [0x4416, 0x0000]
    # a value whose low word is not zero, to pin the word order
    v = struct.unpack(">f", bytes.fromhex("40490fdb"))[0]  # pi as float32
    assert float32_to_registers(v) == [0x4049, 0x0FDB]
    assert registers_to_float32([0x4049, 0x0FDB]) == v


@given(f32)
def test_float32_agrees_with_pymodbus_big_word_order(x):
    dt = ModbusTcpClient.DATATYPE.FLOAT32
    assert float32_to_registers(x) == ModbusTcpClient.convert_to_registers(x, dt, word_order="big")
    assert registers_to_float32(float32_to_registers(x)) == x


@given(st.floats(allow_nan=False, allow_infinity=False))
def test_float64_time_agrees_with_pymodbus(x):
    reg = BY_NAME["t"]
    dt = ModbusTcpClient.DATATYPE.FLOAT64
    assert encode_value(reg, x) == ModbusTcpClient.convert_to_registers(x, dt, word_order="big")
    assert decode_value(reg, encode_value(reg, x)) == x


def test_scaled_integers_round_and_saturate():
    z3s = BY_NAME["z3_scaled"]
    assert encode_value(z3s, 5.4e-3) == [540]
    assert encode_value(z3s, -5.4e-3) == [(-540) & 0xFFFF]
    assert encode_value(z3s, 1.0) == [32767]  # 1 m saturates at 327.67 mm
    assert decode_value(z3s, [(-540) & 0xFFFF]) == pytest.approx(-5.4e-3)
    assert encode_value(BY_NAME["v_battery_scaled"], 3.123) == [3123]
    assert encode_value(BY_NAME["v_battery_scaled"], -1.0) == [0]
    assert encode_value(BY_NAME["z3"], math.nan) == [0, 0]  # never NaN in a register


@given(st.integers(0, 2**32 - 1), f32, f32, f32)
def test_command_block_round_trip(seq, v1, v2, cur):
    cmd = ActuatorCommand(seq, v1, v2, cur)
    words = encode_command_block(cmd)
    assert len(words) == 8 and all(0 <= w <= 0xFFFF for w in words)
    assert decode_command_block(words) == cmd


@given(st.integers(0, 2**32 - 1), st.floats(0, 1e6), f32, f32, f32, f32, st.booleans(), st.integers(0, 255),
       st.integers(0, 2**32 - 1), st.integers(0, 2**16 - 1))
def test_input_block_round_trip(seq, t, z3, vp, zdd, vb, hv, flags, applied, refused):
    s = RigSample(seq, t, z3, vp, zdd, vb, hv, flags)
    words = encode_input_block(s, applied, refused)
    assert len(words) == INPUT_COUNT and all(0 <= w <= 0xFFFF for w in words)
    blk = decode_input_block(words)
    assert blk.sample == s and blk.cmd_seq_applied == applied and blk.refused_count == refused


def test_map_has_no_overlaps_and_the_exchange_blocks_are_contiguous():
    for table in ("input", "holding", "coil", "discrete"):
        regs = sorted((r for r in REGISTER_MAP if r.table == table), key=lambda r: r.address)
        for a, b in itertools.pairwise(regs):
            assert a.end == b.address, f"{table}: gap or overlap between {a.name} and {b.name}"
        assert regs[0].address == 0
    assert INPUT_COUNT == 22 and HOLDING_COUNT == 14



@pytest.mark.parametrize(("address", "values", "code", "words"), [
    (0, float32_to_registers(600.0), None, "v_ch1"),
    (0, encode_command_block(ActuatorCommand(3, 100.0, -100.0, 0.002)), None, "cmd_seq"),
    (1, [0x4416], ModbusExceptionCode.ILLEGAL_ADDRESS, "splits"),  # half of v_ch1
    (0, [0x4416], ModbusExceptionCode.ILLEGAL_ADDRESS, "splits"),
    (8, [2], ModbusExceptionCode.ILLEGAL_ADDRESS, "read-only"),  # map_version
    (10, float32_to_registers(-900.0), ModbusExceptionCode.ILLEGAL_ADDRESS, "read-only"),  # v_limit_min
    (13, [0, 0], ModbusExceptionCode.ILLEGAL_ADDRESS, "outside the map"),
    (40, [0], ModbusExceptionCode.ILLEGAL_ADDRESS, "outside the map"),
    (0, float32_to_registers(1500.5), ModbusExceptionCode.ILLEGAL_VALUE, "outside the allowed range"),
    (2, float32_to_registers(-500.5), ModbusExceptionCode.ILLEGAL_VALUE, "outside the allowed range"),
    (0, [0x7FC0, 0x0000], ModbusExceptionCode.ILLEGAL_VALUE, "nan"),
    (4, float32_to_registers(-0.1), ModbusExceptionCode.ILLEGAL_VALUE, "board_current"),
])
def test_holding_write_checks(address, values, code, words):
    v = check_holding_write(address, values, CURRENT)
    assert v.code == code
    if code is None:
        assert words in v.changed
    else:
        assert words in v.reason


def test_limits_are_table1():
    from board_config import load_mfc_limits

    lim = load_mfc_limits()
    assert BY_NAME["v_ch1"].lower == lim.voltage_min and BY_NAME["v_ch1"].upper == lim.voltage_max
    blk = initial_holding_block(lim.voltage_min, lim.voltage_max)
    assert decode_value(BY_NAME["v_limit_min"], blk[10:12]) == -500.0
    assert decode_value(BY_NAME["v_limit_max"], blk[12:14]) == 1500.0


def test_docs_table_is_generated_from_the_map():
    m = re.search(r"<!-- BEGIN GENERATED[^>]*-->\n(.*?)\n<!-- END GENERATED -->", DOC, re.S)
    assert m, "docs/registers.md lost its generated section"
    assert m.group(1).strip() == markdown_table().strip(), "regenerate with: python -m drivers.modbus_registers"
