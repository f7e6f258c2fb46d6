"""The Modbus register map at its documented limits (docs/registers.md is the oracle): Table 1 set-points exactly at
the limit are accepted, one float32 step beyond is refused with exception 03; whole-value, read-only and out-of-map
writes are refused with exception 02; integers saturate; no NaN ever sits in a register."""

from __future__ import annotations

import math
import re
import struct
from pathlib import Path

import numpy as np
import pytest

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
    registers_to_float32,
    status_word,
)

DOC = (Path(__file__).resolve().parents[2] / "docs" / "registers.md").read_text()
F32_MAX = float(np.finfo(np.float32).max)
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
