"""A run never loses its own result (issue 29, point 1).

* Samples lost during an MBIT (a fault-injecting in-process link that fails every 50th exchange, as a dropped reply
  does) are empty cells in the visit's record: the run finishes with its verdict, summary.json counts the lost
  exchanges, and ``shm compare`` reads the record, leaving the gaps out with a note.
* A step that fails after the board stopped (the figures; the visit records) is named, summary.json, usage.db and
  the records are written, and the exit code is 1, never 2.
"""

from __future__ import annotations

import json
import sqlite3

import pytest

import drivers.sim_link as sim_link
from drivers.link import LinkError
from shm_cli.main import main

pytestmark = pytest.mark.slow


def _shm(argv: list[str]) -> int:
    try:
        return int(main(argv) or 0)
    except SystemExit as exc:
        return int(exc.code or 0)


class DroppingLink(sim_link.InProcessLink):
    """Every ``EVERY``-th exchange from board time 5 s on is lost (rig time passes, no sample), as a dropped reply."""

    EVERY = 50

    def exchange(self, command):
        if self.exchanges >= 500 and self.exchanges % self.EVERY == 7:
            self.exchanges += 1
            self.failures += 1
            self.rig.apply(command)
            self.rig.advance(self.tick)
            raise LinkError(f"{self.url}: reply dropped (test)")
        return super().exchange(command)


def test_samples_lost_in_an_mbit_are_gaps_and_the_run_keeps_its_result(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(sim_link, "InProcessLink", DroppingLink)
    out = tmp_path / "run"
    code = _shm(["run", "--scenario", "maintenance", "--quiet", "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 0, err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["maintenance_verdicts"][-1]["verdict"] == "PASS"
    assert summary["link_stats"]["lost_exchanges"] >= 40
    closing = (out / "timeline.txt").read_text().splitlines()[-1]
    assert f"exchanges without a sample {summary['link_stats']['lost_exchanges']};" in closing
    rec_a = out / "records" / "visit-001_mbit-a.csv"
    text = rec_a.read_text()
    assert '# missing = "empty"' in text
    empty = [ln for ln in text.splitlines() if ln and not ln.startswith("#") and ln.endswith(",")]
    assert len(empty) >= 15  # MBIT.a (22 s) holds some of the lost exchanges
    monkeypatch.undo()
    cmp_out = tmp_path / "cmp"
    code = _shm(["compare", str(rec_a), "--params", "table2", "--out", str(cmp_out), "--json"])
    captured = capsys.readouterr()
    assert code in (0, 1), captured.err  # judged (pass or fail), not refused
    assert "lost sample(s)" in captured.err


def test_a_failing_step_after_the_board_stopped_is_named_and_exits_1(tmp_path, monkeypatch, capsys):
    import studies.board_run.report as report
    import studies.health.visit_records as visit_records

    def broken(*a, **k):
        raise RuntimeError("disk on fire")

    monkeypatch.setattr(report, "write_plots_and_report", broken)
    real = visit_records.VisitRecordWriter.__call__

    def refusing(self, ev):
        if ev.kind == "mbit_record" and ev.data["mbit"] == "b":
            from workbench.records import RecordError
            raise RecordError("visit-001_mbit-b.csv", "value nan is not finite", where="sample 88", column="z3_m")
        return real(self, ev)

    monkeypatch.setattr(visit_records.VisitRecordWriter, "__call__", refusing)
    out = tmp_path / "run"
    code = _shm(["run", "--scenario", "maintenance", "--quiet", "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 1, err
    assert "could not write a visit record" in err and "these steps failed" in err
    summary = json.loads((out / "summary.json").read_text())
    assert set(summary["failed"]) == {"the visit records", "the figures and report.html"}
    assert "sample 88" in summary["failed"]["the visit records"]
    assert summary["maintenance_verdicts"][-1]["verdict"] == "PASS" and summary["status"] == "finished"
    assert (out / "records" / "visit-001_mbit-a.csv").exists() and (out / "timeline.txt").exists()
    con = sqlite3.connect(out / "usage.db")
    try:
        assert con.execute("SELECT status FROM runs").fetchall() == [("finished",)]
    finally:
        con.close()
