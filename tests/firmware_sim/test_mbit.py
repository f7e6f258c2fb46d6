"""MBIT definitions (board_config/mbit.toml) and the clamped channel-voltage sequences (firmware_sim.mbit)."""

from __future__ import annotations

import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from board_config import ConfigError, load_mbit, load_mbit_definitions, load_mfc_limits
from firmware_sim.mbit import MbitClampError, VoltageClampWarning, differential_waveform, generate_mbit

LIMITS = load_mfc_limits()


def test_shipped_definitions_match_the_paper():
    defs = load_mbit_definitions()
    a, b = defs["a"], defs["b"]
    assert (a.waveform, a.amplitude, a.frequency) == ("sine", 600.0, 0.1)
    assert (b.waveform, b.amplitude) == ("step", 300.0)
    assert a.channel_polarity == b.channel_polarity == (1, -1)
    assert a.sample_rate == b.sample_rate == 100.0
    assert a.common_mode == 100.0  # keeps channel 2 at >= -500 V
    assert a.duration == 20.0 and a.n_samples == 2001


def test_mbit_a_stays_inside_table1_with_the_bias_and_keeps_the_bending_drive():
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no clamp warning for the shipped MBITs
        seq = generate_mbit(load_mbit("a"))
    assert not seq.clamp.clamped
    assert seq.v_ch1.min() >= LIMITS.voltage_min and seq.v_ch2.min() >= LIMITS.voltage_min
    assert seq.v_ch2.min() == pytest.approx(-500.0) and seq.v_ch1.max() == pytest.approx(700.0)
    assert np.allclose(seq.va_applied, 600.0 * np.sin(2 * np.pi * 0.1 * seq.t), atol=1e-9)
    assert np.allclose(0.5 * (seq.v_ch1 + seq.v_ch2), 100.0)


def test_unbiased_600v_sine_is_clamped_and_reported():
    defn = replace(load_mbit("a"), common_mode=0.0)
    with pytest.warns(VoltageClampWarning, match=r"clamped.*v_ch1.*v_ch2"):
        seq = generate_mbit(defn)
    rep = seq.clamp
    assert rep.clamped
    ch1, ch2 = rep.channels
    va = 600.0 * np.sin(2 * np.pi * 0.1 * seq.t)
    # each channel dips to -600 V in its own half-cycle: channel 2 while v_a > 500 V, channel 1 while v_a < -500 V
    assert ch2.n_clamped == int((-va < -500.0).sum()) > 0
    assert ch1.n_clamped == int((va < -500.0).sum()) > 0
    assert ch1.worst_excess == pytest.approx(100.0) and ch2.worst_excess == pytest.approx(100.0)
    assert ch2.demand_min == pytest.approx(-600.0)
    assert seq.v_ch1.min() == seq.v_ch2.min() == -500.0
    # first clamped samples: 600 sin(2π·0.1·t) passes 500 V at t = asin(5/6)/(2π·0.1) = 1.565 s (ch2), +5 s (ch1)
    assert ch2.first_time == pytest.approx(seq.t[np.argmax(va > 500.0)])
    assert 1.56 < ch2.first_time < 1.58 and 6.56 < ch1.first_time < 6.58
    # the applied bending drive is reduced where the clamp acted: (600 + 500)/2
    assert seq.va_applied.max() == pytest.approx(550.0) and seq.va_applied.min() == pytest.approx(-550.0)
    with pytest.raises(MbitClampError, match=r"v_ch2: \d+ samples clamped"):
        generate_mbit(defn, on_clamp="raise")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert generate_mbit(defn, on_clamp="report").clamp.clamped  # report only, no warning


def test_step_waveform():
    b = load_mbit("b")
    seq = generate_mbit(b)
    t = seq.t
    assert np.all(seq.va_demand[t <= b.t_start] == 0.0)
    assert np.all(seq.va_demand[t >= b.t_start + b.rise_time - 1e-12] == pytest.approx(300.0))
    assert np.allclose(seq.v_ch1, seq.va_demand) and np.allclose(seq.v_ch2, -seq.va_demand)
    inp = seq.to_inputs()
    assert inp.values.shape == (1, b.n_samples, 3) and inp.dt == pytest.approx(0.01)
    assert np.all(inp.values[0, :, 2] == 0.0)
    assert seq.command(len(seq) - 1) == (300.0, -300.0)
    assert set(seq.columns()) == {"time_s", "va_demand_V", "v_ch1_V", "v_ch2_V", "va_applied_V"}


def test_inverted_polarity_inverts_the_drive():
    a = replace(load_mbit("a"), channel_polarity=(-1, 1))
    seq = generate_mbit(a)
    assert np.allclose(seq.va_applied, -differential_waveform(a, seq.t))


@settings(max_examples=100, deadline=None)
@given(amp=st.floats(1.0, 3000.0), bias=st.floats(-1500.0, 2500.0), step=st.booleans())
def test_channels_never_leave_table1_and_every_clamp_is_counted(amp, bias, step):
    defn = replace(load_mbit("b" if step else "a"), amplitude=amp, common_mode=bias)
    seq = generate_mbit(defn, on_clamp="report")
    for v in (seq.v_ch1, seq.v_ch2):
        assert v.min() >= LIMITS.voltage_min and v.max() <= LIMITS.voltage_max
    p1, p2 = defn.channel_polarity
    for demand, info in ((bias + p1 * seq.va_demand, seq.clamp.channels[0]),
                         (bias + p2 * seq.va_demand, seq.clamp.channels[1])):
        outside = (demand < LIMITS.voltage_min) | (demand > LIMITS.voltage_max)
        assert info.n_clamped == int(outside.sum())
    assert seq.clamp.clamped == bool(seq.clamp.n_clamped)


def _write(tmp_path: Path, body: str) -> Path:
    p = tmp_path / "mbit.toml"
    p.write_text(body)
    return p


GOOD_A = """
[mbit.a]
waveform = "sine"
channel_polarity = [1, -1]
amplitude   = { value = 600.0, unit = "V" }
frequency   = { value = 0.1,   unit = "Hz" }
duration    = { value = 20.0,  unit = "s" }
sample_rate = { value = 100.0, unit = "Hz" }
"""


@pytest.mark.parametrize("change, key, message", [
    (("waveform = \"sine\"", "waveform = \"square\""), "mbit.a.waveform", "expected one of sine, step"),
    (("[1, -1]", "[1, 1]"), "mbit.a.channel_polarity", "signs must differ"),
    (("[1, -1]", "[2, -1]"), "mbit.a.channel_polarity", "expected two signs"),
    (('unit = "V" }', 'unit = "kV" }'), "mbit.a.amplitude.unit", "expected unit 'V'"),
    (("value = 600.0", "value = -600.0"), "mbit.a.amplitude.value", "outside the allowed range"),
    (("value = 100.0, unit = \"Hz\"", "value = 1.0, unit = \"Hz\""), "mbit.a.sample_rate.value",
     "fewer than 20 samples per period"),
    (("value = 20.0", "value = 20.005"), "mbit.a.duration.value", "whole number of samples"),
    (("amplitude   =", "rise_time = { value = 0.01, unit = \"s\" }\namplitude ="), "mbit.a.rise_time",
     "unknown key"),
])
def test_bad_definitions_name_file_key_and_reason(tmp_path, change, key, message):
    path = _write(tmp_path, GOOD_A.replace(*change))
    with pytest.raises(ConfigError) as err:
        load_mbit_definitions(path)
    assert str(path) in str(err.value) and key in str(err.value) and message in str(err.value)


def test_step_rise_shorter_than_a_sample_and_unknown_mbit(tmp_path):
    body = GOOD_A.replace('waveform = "sine"', 'waveform = "step"').replace(
        'frequency   = { value = 0.1,   unit = "Hz" }', 'rise_time = { value = 0.001, unit = "s" }')
    with pytest.raises(ConfigError, match=r"rise_time.*shorter than one command sample"):
        load_mbit_definitions(_write(tmp_path, body))
    with pytest.raises(ConfigError, match=r"unknown MBIT \(defined: a, b\)"):
        load_mbit("c")


def test_sine_above_table1_frequency_range_is_refused():
    a = replace(load_mbit("a"), frequency=20_000.0, sample_rate=1e6, duration=0.001)
    with pytest.raises(ValueError, match="above the MFC operational range"):
        generate_mbit(a)
