"""Lost samples are gaps, never a crash (issue 29, point 1): how records mark them and how they are read.

A CSV record whose header says ``missing = "empty"`` marks a lost sample by an empty cell; a TDMS log (or a CSV)
with ``missing = "nan"`` by a NaN, the LabVIEW way of a gap. The row is left out of the record (its stretch listed
in ``Record.gaps``) while the inputs of every row still drive the model. Without the key an empty cell or a NaN is
refused as before, with a hint; a literal NaN in a record marked ``"empty"`` stays refused; a lost time is refused.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from workbench.records import RecordError, load_record, record_from_arrays, write_record

HEAD = """# test = "mbit-a"
# sample_rate_Hz = 100.0
{extra}time_s,v_ch1_V,v_ch2_V,z3_m
"""


def _rows(n: int = 40, lost: tuple[int, ...] = (), nan: tuple[int, ...] = ()) -> str:
    out = []
    for k in range(n):
        v = 100.0 + k
        z = "" if k in lost else ("nan" if k in nan else f"{1e-4 * k:.6g}")
        out.append(f"{k / 100:.2f},{v:g},{-v:g},{z}")
    return "\n".join(out) + "\n"


def _csv(tmp_path: Path, extra: str, body: str) -> Path:
    p = tmp_path / "rec.csv"
    p.write_text(HEAD.format(extra=extra) + body)
    return p


def test_empty_cells_of_a_marked_record_are_gaps_and_the_inputs_still_drive_the_model(tmp_path):
    rec = load_record(_csv(tmp_path, '# missing = "empty"\n', _rows(lost=(10, 11, 30))))
    assert rec.n_samples == 37 and rec.lost_samples == 3
    assert [(g.start_s, g.end_s, g.n_samples) for g in rec.gaps] == [(0.10, 0.11, 2), (0.30, 0.30, 1)]
    assert 0.11 not in rec.t and rec["z3"][10] == pytest.approx(1e-4 * 12)
    u = rec.input_signals()
    assert u.n_samples == 40  # the full time base: the rig got the command of the lost rows too
    assert np.asarray(u.values).reshape(-1, 3)[11, 0] == pytest.approx(111.0)
    assert "3 lost sample(s) in 2 gap(s)" in rec.gap_note() and "0.1-0.11 s" in rec.gap_note()


def test_unmarked_empty_cells_and_nan_are_refused_with_a_hint(tmp_path):
    with pytest.raises(RecordError, match=r"line 14, column 'z3_m': empty field \(a lost sample\? mark lost "
                                          r"samples with missing = \"empty\""):
        load_record(_csv(tmp_path, "", _rows(lost=(10,))))
    with pytest.raises(RecordError, match=r"value nan is not finite .*missing = \"nan\""):
        load_record(_csv(tmp_path, "", _rows(nan=(10,))))


def test_a_literal_nan_in_a_record_marked_empty_stays_refused(tmp_path):
    with pytest.raises(RecordError, match=r"line 16, column 'z3_m': value nan is not finite"):
        load_record(_csv(tmp_path, '# missing = "empty"\n', _rows(lost=(3,), nan=(11,))))


def test_nan_is_a_gap_when_the_record_says_so(tmp_path):
    rec = load_record(_csv(tmp_path, '# missing = "nan"\n', _rows(nan=(5,))))
    assert rec.lost_samples == 1 and rec.gaps[0].start_s == pytest.approx(0.05)


def test_a_lost_time_and_an_unknown_mark_are_refused(tmp_path):
    body = _rows().replace("0.07,107", ",107", 1)
    with pytest.raises(RecordError, match=r"line 12, column 'time_s': the time of a row is missing"):
        load_record(_csv(tmp_path, '# missing = "empty"\n', body))
    with pytest.raises(RecordError, match=r"metadata key 'missing': unknown mark 'blank'"):
        load_record(_csv(tmp_path, '# missing = "blank"\n', _rows()))


def test_a_record_with_gaps_survives_csv_and_tdms_round_trips(tmp_path):
    t = np.arange(300) / 100.0
    v = 200.0 * np.sin(2 * np.pi * 0.5 * t)
    z = 1e-3 * np.sin(2 * np.pi * 0.5 * t - 0.3)
    z[[40, 41, 42, 250]] = np.nan
    rec = record_from_arrays(t, {"v_ch1_V": v, "v_ch2_V": -v, "z3_m": z},
                             {"test": "mbit-a", "missing": "empty", "sample_rate_Hz": 100.0})
    assert rec.lost_samples == 4 and rec.n_samples == 296
    csv = write_record(rec, tmp_path / "r.csv")
    # the lost rows are kept in the file with their time and inputs, the lost cell empty
    lines = [ln for ln in csv.read_text().splitlines() if ln.startswith("0.41,")]
    assert len(lines) == 1 and lines[0].endswith(",")
    back = load_record(csv)
    assert back.gaps == rec.gaps and np.array_equal(back.t, rec.t)
    assert np.allclose(back["z3"], rec["z3"], rtol=1e-9, atol=0)
    tdms = load_record(write_record(rec, tmp_path / "r.tdms"))
    assert tdms.meta["missing"] == "nan" and tdms.lost_samples == 4
    assert np.allclose(tdms["z3"], rec["z3"]) and np.allclose(tdms.t, rec.t)
    part = back.slice(0.3, 1.0)
    assert part.lost_samples == 3 and part.input_signals().n_samples == 70


def test_a_record_that_lost_nearly_everything_is_refused_naming_the_count():
    t = np.arange(5) / 100.0
    z = np.full(5, np.nan)
    z[2] = 0.0
    with pytest.raises(RecordError, match=r"needs at least 2 samples, found 1 \(4 lost\)"):
        record_from_arrays(t, {"v_ch1_V": t, "v_ch2_V": t, "z3_m": z}, {"missing": "empty"})
