"""``shm synth`` + ``shm compare`` end to end (in-process ``main``), the report files, JSON, and bad input."""

from __future__ import annotations

import json
import re
from html import unescape
from pathlib import Path

import pytest

from shm_cli.main import main
from workbench.records import load_record

CUBIC = "workbench_hidden_effects:CubicTipStiffening"


def test_synth_then_compare_with_a_missing_effect(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rec = tmp_path / "mbitb.csv"
    assert main(["synth", "--test", "mbit-b", "--params", "table2", "--effect", CUBIC, "--noise", "z3=2e-6",
                 "--seed", "7", "--out", str(rec)]) == 0
    loaded = load_record(rec)
    assert loaded.test == "mbit-b" and loaded.meta["provenance"]["truth_effects"] == [CUBIC]
    capsys.readouterr()
    out = tmp_path / "report"
    assert main(["compare", str(rec), "--params", "table2", "--json", "--out", str(out)]) == 0
    data = json.loads(capsys.readouterr().out)
    r = data["records"][0]
    assert r["verdicts"] == {"z3": "fails"}
    assert r["metrics"]["z3"]["fit_pct"] < 95.0
    failed = {t["key"] for t in r["residual_tests"]["z3"]["tests"] if t["verdict"] == "FAIL"}
    assert "ee" in failed
    assert r["localisation"]["z3"]["windows"] and r["prediction"]["z3"]["fit_pct"] is not None
    # the files: PNGs and one self-contained HTML (all images inline, nothing fetched)
    html = (out / "report.html").read_text()
    pngs = sorted(p.name for p in out.glob("*.png"))
    assert len(pngs) == 5 and html.count("data:image/png;base64,") == len(pngs)  # every figure inline
    assert not re.search(r"""src=["'](?!data:)""", html) and "<link" not in html
    text = unescape(html)
    assert "where the model fails" in text and "φu²'e²(τ)" in text and "k-step-ahead prediction" in text
    assert json.loads((out / "compare.json").read_text())["records"][0]["verdicts"] == {"z3": "fails"}
    assert (out / "mbitb_z3_summary.png").stat().st_size > 10_000 and (out / "mbitb_prediction.png").exists()
    # adding the missing effect: the same record is now adequate
    capsys.readouterr()
    assert main(["compare", str(rec), "--add", CUBIC, "--json", "--no-predict", "--out", str(tmp_path / "r2")]) == 0
    assert json.loads(capsys.readouterr().out)["records"][0]["verdicts"] == {"z3": "adequate"}


def test_synth_tdms_and_frf_compare(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    tdms = tmp_path / "sine.tdms"
    assert main(["synth", "--test", "sine", "--freq-hz", "3", "--duration-s", "2", "--out", str(tdms)]) == 0
    frf = tmp_path / "frf.csv"
    assert main(["synth", "--test", "frf", "--f0-hz", "5", "--f1-hz", "30", "--n-freqs", "5", "--out",
                 str(frf)]) == 0
    capsys.readouterr()
    assert main(["compare", str(tdms), str(frf), "--json", "--out", str(tmp_path / "rep")]) == 0
    recs = json.loads(capsys.readouterr().out)["records"]
    assert [r["kind"] for r in recs] == ["time", "frf"]
    assert recs[1]["metrics"]["z3"]["fit_pct"] > 95.0 and "not applicable" in recs[1]["residual_tests"]


def test_bad_input_exit_codes(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "bad.csv"
    bad.write_text("time_s,v_ch1_V,z3_m\n0,1,0\n0.001,nan,0\n")
    assert main(["compare", str(bad), "--out", str(tmp_path / "x")]) == 2
    assert re.search(r"bad\.csv, line 3, column 'v_ch1_V'.*not finite", capsys.readouterr().err)
    assert main(["compare", str(tmp_path / "missing.csv"), "--out", str(tmp_path / "x")]) == 2
    assert "file not found" in capsys.readouterr().err
    assert main(["synth", "--test", "mbit-b", "--effect", "no_such_effect", "--out", str(tmp_path / "a.csv")]) == 2
    assert "unknown effect 'no_such_effect'" in capsys.readouterr().err
    assert main(["synth", "--test", "mbit-a", "--noise", "z3=abc", "--out", str(tmp_path / "a.csv")]) == 2
    assert "not a number" in capsys.readouterr().err
    assert main(["synth", "--test", "frf", "--out", str(tmp_path / "a.tdms")]) == 2
    assert main(["compare", str(bad), "--level", "2", "--out", str(tmp_path / "x")]) == 2
