"""The Modbus register map: encodings (float32 word order stated and checked), block codecs, write checks, docs."""

from __future__ import annotations

import itertools
import math
import re
import struct
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st
from pymodbus.client import ModbusTcpClient

from drivers.link import FLAG_SENSOR_FAULT, ActuatorCommand, RigSample
from drivers.modbus_registers import (
    BY_NAME,
    HOLDING_COUNT,
    INPUT_COUNT,
    REGISTER_MAP,
    ModbusExceptionCode,
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
)

DOCS = Path(__file__).resolve().parents[2] / "docs" / "registers.md"
f32 = st.floats(width=32, allow_nan=False, allow_infinity=False)


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


def test_non_finite_from_a_foreign_rig_sets_the_sensor_fault_flag():
    words = encode_input_block(RigSample(1, 0.0, 0.0, 0.0, 0.0, 3.0))
    words[6:8] = [0x7FC0, 0x0000]  # a NaN z3 from some other device
    assert decode_input_block(words).sample.flags & FLAG_SENSOR_FAULT


def test_map_has_no_overlaps_and_the_exchange_blocks_are_contiguous():
    for table in ("input", "holding", "coil", "discrete"):
        regs = sorted((r for r in REGISTER_MAP if r.table == table), key=lambda r: r.address)
        for a, b in itertools.pairwise(regs):
            assert a.end == b.address, f"{table}: gap or overlap between {a.name} and {b.name}"
        assert regs[0].address == 0
    assert INPUT_COUNT == 22 and HOLDING_COUNT == 14


CURRENT = initial_holding_block()


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
    text = DOCS.read_text()
    m = re.search(r"<!-- BEGIN GENERATED[^>]*-->\n(.*?)\n<!-- END GENERATED -->", text, re.S)
    assert m, "docs/registers.md lost its generated section"
    assert m.group(1).strip() == markdown_table().strip(), "regenerate with: python -m drivers.modbus_registers"
