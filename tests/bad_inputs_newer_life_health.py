"""The bad-input corpus of issue 33 for ``[life]`` scenarios and ``shm health`` inputs (helper A's part).

Same form as ``tests/bad_inputs_corpus.py`` (its :class:`Case` and :func:`case` are reused): ``{d}`` is the corpus
directory (:func:`write_corpus_files`), ``{o}`` an output directory of the case's own. Every case fails during
validation in the parent, before any worker or fit starts, so the corpus takes seconds. Used by
``tests/shm_cli/test_bad_inputs_newer_life_health.py``.
"""

from __future__ import annotations

import sqlite3
import tomllib
from pathlib import Path
from typing import Any

from bad_inputs_corpus import CASE_TABLES, PARAMS, Case, case, case_table, unique_ids, variant
from scenario_text_support import life_scenario, linear_law

#: a valid life: 3 visits 400 h apart, alpha_h drifting (tests/studies/test_health.py's tiny life)
LIFE = life_scenario("tiny-life", 3, 400, rig='params = "table2"\n', sep="\n")

_LAW = linear_law()


def _life_file(change: dict[str, Any]) -> str:
    """The good life with a table of ``tests/data/bad_inputs/life_files.toml`` applied: ``replace`` (old, new: the
    first old, which must be there), then ``law`` in place of its law."""
    text = variant(LIFE, *change["replace"]) if "replace" in change else LIFE
    return variant(text, _LAW, change["law"]) if "law" in change else text


#: [life] scenario files: name -> (content, needles of the error line)
LIVES: dict[str, tuple[str, tuple[str, ...]]] = {
    name: (_life_file(change), tuple(change["needles"]))
    for name, change in tomllib.loads((CASE_TABLES / "life_files.toml").read_text(encoding="utf-8")).items()}

ONLY_MAINTENANCE = ('[scenario]\nname = "only-maint"\n[[phase]]\nkind = "maintenance"\n'
                    'duration = { value = 30, unit = "s" }\n')

#: a record file for shm health: MBIT-like columns with a TOML header (tests/bad_inputs_corpus.py's form)
_ROWS = "time_s,v_ch1_V,v_ch2_V,z3_mm\n" + "".join(
    f"{k * 0.01:.2f},{100.0 + (300.0 if k >= 10 else 0.0):g},{100.0 - (300.0 if k >= 10 else 0.0):g},"
    f"{0.001 * k:.4f}\n" for k in range(400))


def board_record(hours: float, visit: int, test: str = "mbit-b", run_uid: str = "run-1",
                 board_id: str = "cfg-board1", generator: str = "board") -> str:
    prov = f'# [provenance]\n# generator = "{generator}"\n# visit = {visit}\n'
    if run_uid:
        prov += f'# run_uid = "{run_uid}"\n'
    if board_id:
        prov += f'# board_id = "{board_id}"\n'
    return (f'# format = "mfc-shm-record/1"\n# test = "{test}"\n# sample_rate_Hz = 100.0\n'
            f"# operating_hours = {hours!r}\n" + prov + _ROWS)


def write_corpus_files(d: Path) -> None:
    """Every [life] file, the health record sets and the folders the cases name, into ``d``."""
    d.mkdir(parents=True, exist_ok=True)
    for name, (content, _) in LIVES.items():
        (d / name).write_text(content)
    (d / "only_maint.toml").write_text(ONLY_MAINTENANCE)
    (d / "life.toml").write_text(LIFE)
    for name in ("p_wrong_unit.toml", "p_syntax.toml"):
        (d / name).write_text(PARAMS[name][0])
    life = d / "life_run" / "records"  # a life's records (three visits of one run of one board)
    life.mkdir(parents=True, exist_ok=True)
    for i, h in enumerate((0.0, 100.0, 200.0)):
        (life / f"visit-{i + 1:03d}_mbit-b.csv").write_text(board_record(h, i + 1))
    extra = {
        "other_run.csv": board_record(300.0, 4, run_uid="run-2"),
        "other_board.csv": board_record(300.0, 4, board_id="cfg-board2"),
        "no_uid.csv": board_record(300.0, 4, run_uid=""),
        "same_visit_copy.csv": board_record(100.0, 2),
        "visit_clash.csv": board_record(300.0, 2),
        "hours_1e9.csv": board_record(1e9, 4),
        "hours_nan.csv": board_record(float("nan"), 4),
        "hours_neg.csv": board_record(-1.0, 4),
        "synth_a.csv": board_record(50.0, 1, generator="shm synth", run_uid="", board_id=""),
        "synth_a_again.csv": board_record(50.0, 1, generator="shm synth", run_uid="", board_id=""),
    }
    for name, text in extra.items():
        (d / name).write_text(text)
    foreign = d / "compare_out"  # another command's finished results
    foreign.mkdir(exist_ok=True)
    (foreign / "report.html").write_text("<html>shm compare's report</html>\n")
    run_out = d / "run_out"
    run_out.mkdir(exist_ok=True)
    (run_out / "summary.json").write_text('{"scenario": "maintenance"}\n')
    (run_out / "report.html").write_text("<html>shm run's report</html>\n")
    done = d / "earlier_life"
    done.mkdir(exist_ok=True)
    (done / "summary.json").write_text('{"scenario": "tiny-life", "life": true}\n')
    (done / "life.json").write_text('{"scenario": "tiny-life"}\n')
    (d / "a_file").write_text("I am a file\n")
    con = sqlite3.connect(d / "life_run" / "usage.db")  # a usage.db beside the records (no tables needed)
    con.close()


def _life_cases() -> list[Case]:
    return [case(f"life-{name}", ["run", "--scenario", f"{{d}}/{name}", "--quiet", "--out", "{o}"], *needles)
            for name, (_, needles) in LIVES.items()] + case_table("life_options.txt")


def all_cases() -> list[Case]:
    return unique_ids(_life_cases() + case_table("health_options.txt"))
