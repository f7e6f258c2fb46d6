"""``shm harvest`` end to end: files, JSON, verdicts, exit codes, bad-input messages."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from shm_cli.main import main

WHATIF = str(Path(__file__).parents[1] / "data" / "harvest_whatif.toml")


def test_paper_coupling_end_to_end(tmp_path, capsys):
    out = tmp_path / "paper"
    rc = main(["harvest", "--params", WHATIF, "--coupling", "paper", "--accel-g", "0.1", "--freq-hz", "5.8",
               "--r-int-ohm", "1", "--from-v", "2.0", "--duration-s", "4", "--json", "--out", str(out)])
    assert rc == 0
    summary = json.loads(capsys.readouterr().out)
    for name in ("harvest_summary.json", "charge_curve.csv", "chunks.csv", "audit.csv", "charge_curve.png",
                 "charge_rate.csv"):
        assert (out / name).is_file(), name
    assert summary["setup"]["coupling"] == "paper" and summary["setup"]["terminal"] == "harvest_paper"
    assert summary["time_to_full_is_projection"] is True and summary["projection"]["is_projection"] is True
    assert summary["charge_gained_C"] > 0
    assert not summary["audit"]["closes_within_1pct"]
    assert summary["audit"]["energy_from_nowhere_J"] > 100 * summary["audit"]["rows"][0]["energy_J"]
    assert "reproduced" in summary["verdict"]
    w = summary["what_it_would_take"]
    assert w["energy_to_full_J"] == pytest.approx(591.5, rel=1e-3)  # 234 C of ML2032 above 2.0 V
    assert w["required_mean_cell_power_W"] == pytest.approx(w["energy_to_full_J"] / 600.0)
    assert 30.0 < w["eq8_required_gain_V_per_g"] < 45.0  # the paper's own 35 V/g is the right order for Eq. 8
    assert w["harvest_efficiency_cell_over_base"] is None  # paper mode: the cell's energy is not from the base
    with (out / "charge_curve.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert list(rows[0]) == ["time_s", "v_bat_V", "v_bat_term_V", "soc_1", "v_stored_V"]
    assert float(rows[-1]["v_bat_V"]) > float(rows[0]["v_bat_V"])
    with (out / "audit.csv").open() as fh:
        audit = list(csv.DictReader(fh))
    assert audit[-1]["side"] == "residual" and all(r["term"] for r in audit)


def test_coupled_coupling_table2_text_report(tmp_path, capsys):
    out = tmp_path / "coupled"
    rc = main(["harvest", "--params", "table2", "--duration-s", "3", "--out", str(out)])
    text = capsys.readouterr().out
    assert rc == 0
    assert "never reaches full" in text and "never beats the cell voltage" in text
    assert "NOT reproduced" in text
    assert "sources - uses (residual)" in text
    summary = json.loads((out / "harvest_summary.json").read_text())
    assert summary["audit"]["closes_within_1pct"] is True
    assert summary["stored_gain_V_per_g"] < 0.1  # table2: tens of millivolts per g, not the paper's 35 V/g
    assert summary["time_to_full_s"] is None  # infinite -> null in JSON


# the command's bad options and their one-line errors: the bad-input corpus (tests/data/bad_inputs/options.txt)


def test_help_lists_the_couplings(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["harvest", "--help"])
    assert exc.value.code == 0
    text = capsys.readouterr().out
    assert "--coupling {coupled,paper}" in text and "Eq. 8" in text


def test_cli_claim_constant_matches_the_plant():
    from shm_cli import harvest_cmd
    from studies.harvest import PAPER_CLAIM_S

    assert harvest_cmd.PAPER_CLAIM_S == PAPER_CLAIM_S
