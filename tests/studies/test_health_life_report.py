"""``shm run`` on a [life] scenario writes a life-level report (issue 27, point 2): life.png and a styled
report.html with the first FAULT, the truth and the MBITs visit by visit, linked to the records and life.json."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest
from scenario_text_support import life_scenario

from studies.health.life_report import write_life_report


def _summary(first: int | None = 3) -> dict:
    visits = []
    for i in range(1, 5):
        fault = first is not None and i >= first
        visits.append({"visit": i, "operating_hours": 400.0 * (i - 1), "verdict": "FAULT" if fault else "PASS",
                       "truth_deviations": {"alpha_h": 2e-4 * 400 * (i - 1)}, "seed": i, "wall_s": 1.0,
                       "mbits": [{"label": "MBIT.a", "verdict": "FAULT" if fault else "PASS", "max_count": 200 * fault,
                                  "max_eps": 0.05 * i, "fault_time_s": None},
                                 {"label": "MBIT.b", "verdict": "PASS", "max_count": 0, "max_eps": 0.04 * i,
                                  "fault_time_s": None}],
                       "records": [f"records/visit-{i:03d}_mbit-a.csv", f"records/visit-{i:03d}_mbit-b.csv"]})
    return {"scenario": "tiny-life", "scenario_file": "tiny.toml", "seed": 3, "params": "table2", "workers": 2,
            "wall_s": 4.2, "visits": visits, "first_fault_visit": first,
            "first_fault_operating_hours": None if first is None else 400.0 * (first - 1),
            "flights_between_visits": 40, "visit_interval_h": 400.0}


def test_the_life_page_tells_the_first_fault_the_truth_and_the_mbits(tmp_path):
    assert write_life_report(_summary(), tmp_path, "out/tiny") == {}
    page = (tmp_path / "report.html").read_text()
    assert (tmp_path / "life.png").stat().st_size > 10_000
    assert "<style>" in page and page.count("<img ") == 1
    assert "FIRST FAULT" in page and "visit 3 at 800 h" in page
    assert "true alpha_h" in page and "+16.00 %" in page  # the truth at 800 h
    assert "FAULT (ε 0.150, counter 200)" in page
    assert "href='records/visit-003_mbit-a.csv'" in page and "href='life.json'" in page
    assert "shm health out/tiny --evaluate" in page


def test_a_life_without_fault_says_never(tmp_path):
    write_life_report(_summary(first=None), tmp_path)
    assert "never in this life" in (tmp_path / "report.html").read_text()


@pytest.mark.slow
def test_shm_run_on_a_life_writes_the_report(tmp_path):
    toml = tmp_path / "tiny.toml"
    toml.write_text(life_scenario("tiny-life", 3, 400))
    out = tmp_path / "run"
    r = subprocess.run([sys.executable, "-m", "shm_cli.main", "run", "--scenario", str(toml), "--out", str(out)],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert "report.html" in r.stdout
    life = json.loads((out / "life.json").read_text())
    page = (out / "report.html").read_text()
    assert life["first_fault_visit"] == 3 and "visit 3 at 800 h" in page
    assert (out / "life.png").exists()
