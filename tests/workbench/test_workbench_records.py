"""Measurement records: the CSV format, sidecar metadata, TDMS import, FRF tables, and every validation error."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from workbench.records import FrfRecord, Record, RecordError, load_record, write_frf_table, write_tdms_record
from workbench.records._io import write_csv_record
from workbench.records._units import G0, split_column

#: record texts load_record must refuse, one a line, with the reason
BAD_TEXTS = Path(__file__).parents[1] / "data" / "bad_record_texts.txt"
HEADER = """# format = "mfc-shm-record/1"
# test = "mbit-b"
# sample_rate_Hz = 100.0
## a comment line
# [channels.z3_mm]
# sensor = "laser E1"
# position_m = 0.38
# noise_std = 0.002
"""


def _csv(tmp_path: Path, body: str, header: str = HEADER, name: str = "r.csv") -> Path:
    p = tmp_path / name
    p.write_text(header + body)
    return p


def _rows(n: int = 5, dt: float = 0.01) -> str:
    lines = ["time_s,v_ch1_V,v_ch2_V,z3_mm"]
    for k in range(n):
        lines.append(f"{k * dt:.3f},{100 + 10 * k},{100 - 10 * k},{0.1 * k}")
    return "\n".join(lines) + "\n"


def test_units_split() -> None:
    assert split_column("z0dd_m_s2")[0] == "z0dd"
    assert split_column("v_ch1_V")[1].token == "V"
    assert split_column("z3_amp_m_per_V")[0] == "z3_amp"
    assert split_column("z3_amp_m_per_V")[1].si == "m/V"
    assert split_column("z3")[1] is None


def test_csv_loads_in_si_with_metadata(tmp_path: Path) -> None:
    rec = load_record(_csv(tmp_path, _rows()))
    assert isinstance(rec, Record)
    assert rec.test == "mbit-b" and rec.inputs == ("v_ch1", "v_ch2") and rec.outputs == ("z3",)
    np.testing.assert_allclose(rec["z3"], 1e-4 * np.arange(5))  # mm -> m
    ch = rec.channels["z3"]
    assert ch.sensor == "laser E1" and ch.position_m == 0.38 and ch.noise_std == pytest.approx(2e-6)
    assert rec.sample_rate_Hz == pytest.approx(100.0) and rec.uniform
    name, unit, va = rec.drive()
    assert name == "va" and unit == "V"
    np.testing.assert_allclose(va, 10.0 * np.arange(5))  # differential part only
    u = rec.input_signals()
    assert u.values.shape == (1, 5, 3) and u.dt == pytest.approx(0.01)


def test_accel_in_g_converts_and_drive_is_base(tmp_path: Path) -> None:
    body = "time_s,z0dd_g,v_stored_mV\n0,0,0\n0.001,0.1,5\n0.002,-0.1,-5\n"
    rec = load_record(_csv(tmp_path, body, header='# test = "sine"\n'))
    np.testing.assert_allclose(rec["z0dd"], [0, 0.1 * G0, -0.1 * G0])
    np.testing.assert_allclose(rec["v_stored"], [0, 5e-3, -5e-3])
    assert rec.drive()[0] == "z0dd"


def test_roundtrip_writer(tmp_path: Path) -> None:
    t = np.arange(200) * 1e-3
    meta = {"test": "sine", "inputs": ["v_ch1_V", "v_ch2_V"], "segments": [{"start_s": 0.0, "end_s": 0.1,
                                                                             "label": "rise"}],
            "channels": {"z3_m": {"sensor": "laser"}}, "provenance": {"seed": 3, "effects": ["x"]}}
    p = write_csv_record(tmp_path / "w.csv", t, {"v_ch1_V": np.sin(t), "v_ch2_V": -np.sin(t), "z3_m": t ** 2}, meta)
    rec = load_record(p)
    np.testing.assert_allclose(rec["z3"], t ** 2, rtol=1e-9, atol=1e-15)
    assert rec.segments[0].label == "rise" and rec.meta["provenance"]["seed"] == 3
    part = rec.slice(0.05, 0.15)
    assert part.t[0] == pytest.approx(0.05) and part.segments[0].end_s == pytest.approx(0.1)


def test_sidecar_metadata_and_conflict(tmp_path: Path) -> None:
    p = _csv(tmp_path, _rows(), header="", name="s.csv")
    (tmp_path / "s.meta.toml").write_text('test = "step"\nterminal = "amplifier"\n')
    rec = load_record(p)
    assert rec.test == "step" and rec.terminal == "amplifier"
    p2 = _csv(tmp_path, _rows(), header='# test = "sine"\n', name="c.csv")
    (tmp_path / "c.meta.toml").write_text('test = "step"\n')
    with pytest.raises(RecordError, match=r"c\.meta\.toml.*'test'.*conflicts"):
        load_record(p2)


def _bad_texts() -> list[Any]:
    """The cases of ``tests/data/bad_record_texts.txt`` (its head says the form) as pytest params named by their id."""
    cases = []
    for line in BAD_TEXTS.read_text(encoding="utf-8").splitlines():
        if line.strip() and not line.startswith("#"):
            id, header, body, pattern = line.split(" | ")
            header, body = ("" if header == "-" else header).replace("\\n", "\n"), body.replace("\\n", "\n")
            cases.append(pytest.param(body, header, pattern, id=id))
    return cases


@pytest.mark.parametrize(("body", "header", "pattern"), _bad_texts())
def test_validation_errors_name_file_place_and_reason(tmp_path: Path, body: str, header: str, pattern: str) -> None:
    p = _csv(tmp_path, body, header=header)
    with pytest.raises(RecordError, match=pattern) as info:
        load_record(p)
    assert str(p) in str(info.value)


def test_missing_file_and_unknown_type(tmp_path: Path) -> None:
    with pytest.raises(RecordError, match="file not found"):
        load_record(tmp_path / "nope.csv")
    (tmp_path / "x.mat").write_text("")
    with pytest.raises(RecordError, match=r"unknown record type '\.mat'"):
        load_record(tmp_path / "x.mat")


def test_jittered_time_is_resampled_for_the_model(tmp_path: Path) -> None:
    t = np.arange(100) * 1e-3
    t[1:-1] += np.random.default_rng(0).uniform(-2e-5, 2e-5, 98)
    p = write_csv_record(tmp_path / "j.csv", t, {"v_ch1_V": 10 * t, "z3_m": t}, {"test": "free"})
    rec = load_record(p)
    assert not rec.uniform
    u = rec.input_signals()
    assert u.dt == pytest.approx(1e-3, rel=1e-3)
    np.testing.assert_allclose(u.values[0, :, 0], 10 * u.t, atol=1e-6)


# --- TDMS -------------------------------------------------------------------------------------------------------

def _crio_tdms(path: Path, n: int = 500, lengths: tuple[int, int, int] | None = None, unit: str = "mm") -> None:
    """A file shaped like a CompactRIO logger's: one group, waveform timing, LabVIEW unit strings."""
    from nptdms import ChannelObject, GroupObject, RootObject, TdmsWriter

    lengths = lengths or (n, n, n)
    inc = 1e-3
    chans = [("HV channel 1", "V", 100 + 50 * np.sin(np.arange(lengths[0]) * 0.01)),
             ("HV channel 2", "V", 100 - 50 * np.sin(np.arange(lengths[1]) * 0.01)),
             ("Laser tip", unit, np.cos(np.arange(lengths[2]) * 0.01))]
    objs = [RootObject(properties={"test": "sine", "sample_rate_Hz": 1000.0}), GroupObject("Measurements")]
    for name, u, data in chans:
        objs.append(ChannelObject("Measurements", name, data, properties={
            "unit_string": u, "wf_increment": inc, "wf_start_offset": 0.0, "wf_samples": len(data)}))
    with TdmsWriter(str(path)) as w:
        w.write_segment(objs)


def _tdms_sidecar(path: Path) -> None:
    path.with_name(path.stem + ".meta.toml").write_text(
        '[tdms]\ngroup = "Measurements"\n[tdms.channels]\n"HV channel 1" = "v_ch1_V"\n"HV channel 2" = "v_ch2_V"\n'
        '"Laser tip" = "z3_mm"\n')


def test_tdms_import_like_compactrio(tmp_path: Path) -> None:
    p = tmp_path / "crio.tdms"
    _crio_tdms(p)
    _tdms_sidecar(p)
    rec = load_record(p)
    assert rec.test == "sine" and rec.inputs == ("v_ch1", "v_ch2") and rec.outputs == ("z3",)
    assert rec.n_samples == 500 and rec.dt == pytest.approx(1e-3)
    np.testing.assert_allclose(rec["z3"], 1e-3 * np.cos(np.arange(500) * 0.01))


def test_tdms_roundtrip_writer(tmp_path: Path) -> None:
    t = np.arange(300) * 1e-3
    src = write_csv_record(tmp_path / "a.csv", t, {"v_ch1_V": np.sin(t), "z0dd_m_s2": np.cos(t), "z3_m": t},
                           {"test": "free"})
    rec = load_record(src)
    back = load_record(write_tdms_record(rec, tmp_path / "a.tdms"))
    assert back.inputs == rec.inputs and back.outputs == rec.outputs
    np.testing.assert_allclose(back["z0dd"], rec["z0dd"])
    np.testing.assert_allclose(back.t, rec.t, atol=1e-12)


def test_tdms_mismatched_lengths_and_unknown_unit(tmp_path: Path) -> None:
    p = tmp_path / "bad.tdms"
    _crio_tdms(p, lengths=(500, 500, 499))
    _tdms_sidecar(p)
    with pytest.raises(RecordError, match=r"column 'Laser tip'.*499 samples.*500"):
        load_record(p)
    p2 = tmp_path / "unit.tdms"
    _crio_tdms(p2, unit="inch")
    with pytest.raises(RecordError, match=r"column 'Laser tip'.*unknown unit_string 'inch'"):
        load_record(p2)


def test_tdms_corrupt_file(tmp_path: Path) -> None:
    p = tmp_path / "junk.tdms"
    p.write_bytes(b"hello world" * 10)
    with pytest.raises(RecordError, match="not a readable TDMS file"):
        load_record(p)
    p.write_bytes(b"TDSm" + bytes(range(256)) * 3)  # a truncated/garbled segment: nothing usable inside
    with pytest.raises(RecordError, match="holds no channel data"):
        load_record(p)


# --- frequency-response tables ----------------------------------------------------------------------------------

def test_frf_table_roundtrip_and_errors(tmp_path: Path) -> None:
    f = np.array([1.0, 5.0, 17.0, 40.0])
    h = np.array([1e-5, 1.2e-5, 5e-5, 1e-6]) * np.exp(1j * np.radians([-1, -10, -90, -170]))
    p = write_frf_table(tmp_path / "frf.csv", f, {"z3": (h, "mm_per_V")},
                        {"frf": {"drive": "va", "amplitude": 600.0, "amplitude_unit": "V"}})
    rec = load_record(p)
    assert isinstance(rec, FrfRecord) and rec.drive == "va" and rec.drive_amplitude == 600.0
    np.testing.assert_allclose(rec.responses["z3"].response, h, rtol=1e-8)
    bad = tmp_path / "frf2.csv"
    bad.write_text('# [frf]\n# drive = "va"\n# amplitude = 600.0\n# amplitude_unit = "V"\n'
                   "frequency_Hz,z3_amp_m_per_V\n1,1e-5\n2,1e-5\n")
    with pytest.raises(RecordError, match=r"column 'z3_amp_m_per_V'.*without a phase column"):
        load_record(bad)
    bad.write_text('# [frf]\n# drive = "z0dd"\n# amplitude = 0.1\n# amplitude_unit = "g"\n'
                   "frequency_Hz,v_stored_amp_V_per_V,v_stored_phase_deg\n1,1,0\n2,1,0\n")
    with pytest.raises(RecordError, match=r"must be an output unit per z0dd unit"):
        load_record(bad)
    bad.write_text('# [frf]\n# drive = "va"\n# amplitude = 600.0\n# amplitude_unit = "V"\n'
                   "frequency_Hz,z3_amp_m_per_V,z3_phase_deg\n2,1e-5,0\n1,1e-5,0\n")
    with pytest.raises(RecordError, match=r"line 7, column .frequency_Hz.*strictly increasing"):
        load_record(bad)


# --- what spreadsheets and cut-off loggers do to a CSV (issue 12, point 6) ---------------------------------------
def test_byte_order_mark_is_read_past(tmp_path: Path) -> None:
    p = tmp_path / "bom.csv"
    p.write_bytes(b"\xef\xbb\xbf" + (HEADER + _rows()).encode())
    rec = load_record(p)
    assert rec.test == "mbit-b" and rec.n_samples == 5  # the header was seen as a header
    np.testing.assert_allclose(rec["z3"], 1e-4 * np.arange(5))


@pytest.mark.parametrize("sep", [";", "\t"])
def test_semicolon_or_tab_separators_with_decimal_commas_read_as_the_same_numbers(tmp_path: Path, sep: str) -> None:
    ref = load_record(_csv(tmp_path, _rows(), name="ref.csv"))
    euro = _rows().replace(",", sep)
    euro = "\n".join([euro.splitlines()[0]] + [ln.replace(".", ",") for ln in euro.splitlines()[1:]]) + "\n"
    assert "," in euro.splitlines()[3]  # a decimal comma is really there
    rec = load_record(_csv(tmp_path, euro, name="euro.csv"))
    np.testing.assert_array_equal(rec.t, ref.t)
    for name in ("v_ch1", "v_ch2", "z3"):
        np.testing.assert_array_equal(rec[name], ref[name])


def test_decimal_commas_with_comma_separators_are_named_with_the_line(tmp_path: Path) -> None:
    body = "time_s,v_ch1_V,v_ch2_V,z3_mm\n0,100,100,0\n0,01,110,90,0,1\n"
    with pytest.raises(RecordError, match=r"line 11.*6 fields but the header has 4 columns.*decimal commas"):
        load_record(_csv(tmp_path, body))


@pytest.mark.parametrize("cut", [1, 3, 6])
def test_a_file_cut_in_its_last_row_is_refused_naming_the_line(tmp_path: Path, cut: int) -> None:
    """A logger killed mid-write leaves the last number incomplete ('0.4' cut to '0.'); that row must not be read
    as data (it used to flip a verdict)."""
    text = _rows()
    p = _csv(tmp_path, text[:-cut])
    last_line = len((HEADER + text).splitlines())
    with pytest.raises(RecordError, match=rf"line {last_line}\b.*cut off"):
        load_record(p)


def test_crlf_line_ends_are_read(tmp_path: Path) -> None:
    p = tmp_path / "crlf.csv"
    p.write_bytes((HEADER + _rows()).replace("\n", "\r\n").encode())
    assert load_record(p).n_samples == 5


@pytest.mark.parametrize("cut", [5, 1000])
def test_a_tdms_file_cut_off_mid_write_is_refused(tmp_path: Path, cut: int) -> None:
    from workbench.records import record_from_arrays

    t = np.arange(500) * 1e-3
    rec = record_from_arrays(t, {"v_ch1_V": 100 + 0 * t, "v_ch2_V": 100 + 0 * t, "z3_mm": np.sin(t)},
                             {"test": "step"})
    full = write_tdms_record(rec, tmp_path / "full.tdms")
    p = tmp_path / "cut.tdms"
    p.write_bytes(full.read_bytes()[:-cut])
    with pytest.raises(RecordError, match=r"cut\.tdms, column 'z3'.*samples but.*cut off"):
        load_record(p)
