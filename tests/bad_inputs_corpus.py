"""The bad-input corpus (issue 12, point 10): files and command lines a lab would get wrong, with what the one-line
error must name. Used by ``tests/shm_cli/test_bad_inputs.py``.

A case is ``Case(id, argv, needles, code=2)``: ``argv`` may hold ``{d}`` (the corpus directory, where
:func:`write_corpus_files` put every file) and ``{shipped}`` (the shipped configuration directory); ``needles``
are strings that must all appear in the error output (case-insensitive): the file/key/option or value, and a word
of the reason. Every case must fail during validation, before any heavy simulation.
"""

from __future__ import annotations

import re
import shlex
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = ROOT / "board_config"
#: the corpora's command-line cases, one a line (tests/data/bad_inputs/*.txt; the format is in each file's head)
CASE_TABLES = ROOT / "tests" / "data" / "bad_inputs"


@dataclass(frozen=True)
class Case:
    id: str
    argv: tuple[str, ...]
    needles: tuple[str, ...]
    code: int = 2

    def resolved(self, d: Path) -> list[str]:
        """The command line, with ``{d}`` the corpus directory and ``{o}`` an output directory of this case's own."""
        return [a.format(d=d, o=d / "out" / self.id, shipped=SHIPPED) for a in self.argv]


def case(id: str, argv: str | list[str], *needles: str, code: int = 2) -> Case:
    args = tuple(argv.split()) if isinstance(argv, str) else tuple(argv)
    return Case(id, args, tuple(needles), code)


def case_table(name: str) -> list[Case]:
    """The cases of the table ``tests/data/bad_inputs/<name>``: ``id | command line (shell words) | needle ...``,
    a last field ``exit=N`` for an exit code other than 2; blank lines and ``#`` comments skipped."""
    cases = []
    for line in (CASE_TABLES / name).read_text(encoding="utf-8").splitlines():
        if not line.strip() or line.startswith("#"):
            continue
        id, argv, *needles = line.split(" | ")
        code = int(needles.pop()[len("exit="):]) if needles and needles[-1].startswith("exit=") else 2
        cases.append(case(id, shlex.split(argv), *needles, code=code))
    return cases


# ------------------------------------------------------------------------------------------------------------
# files
RECORD_HEADER = """# format = "mfc-shm-record/1"
# test = "mbit-b"
# sample_rate_Hz = 100.0
"""


def variant(text: str, old: str, new: str) -> str:
    """``text`` with its first ``old`` replaced by ``new`` (``old`` must be there: a corpus file that silently equals
    the good one would test nothing)."""
    assert old in text, old
    return text.replace(old, new, 1)


def _rows(n: int = 40) -> list[str]:
    rows = ["time_s,v_ch1_V,v_ch2_V,z3_mm"]
    for k in range(n):
        v = 100.0 + (300.0 if k >= 10 else 0.0)
        rows.append(f"{k * 0.01:.2f},{v:g},{200 - v:g},{0.001 * k:.4f}")
    return rows


def _record(rows: list[str] | None = None, header: str = RECORD_HEADER) -> str:
    return header + "\n".join(rows if rows is not None else _rows()) + "\n"


def _replace_row(k: int, text: str) -> str:
    rows = _rows()
    rows[k] = text
    return _record(rows)


FRF_HEADER = """# format = "mfc-shm-frf/1"
# [frf]
# drive = "va"
# amplitude = 100.0
# amplitude_unit = "V"
"""


def _frf(rows: str, head: str = FRF_HEADER, columns: str = "frequency_Hz,z3_amp_m_per_V,z3_phase_deg") -> str:
    """An FRF table file: ``head`` (its TOML header lines), the column line, ``rows``."""
    return f"{head}{columns}\n{rows}"


def _wrong_headers() -> dict[str, tuple[str, tuple[str, ...]]]:
    """Good rows under a wrong TOML header: the records of ``tests/data/bad_inputs/record_headers.toml``."""
    table = tomllib.loads((CASE_TABLES / "record_headers.toml").read_text(encoding="utf-8"))
    return {name: (_record(header=f["header"]), tuple(f["needles"])) for name, f in table.items()}


#: record files: name -> (content or bytes, needles of the error). Line numbers: 3 header lines, the column line
#: is line 4, data row k (1-based) is line 4 + k.
RECORDS: dict[str, tuple[str | bytes, tuple[str, ...]]] = {
    "nan_value.csv": (_replace_row(5, "0.04,100,100,nan"), ("nan_value.csv", "line 9", "z3_mm", "not finite")),
    "inf_value.csv": (_replace_row(6, "0.05,inf,100,0"), ("inf_value.csv", "line 10", "v_ch1_V", "not finite")),
    "text_value.csv": (_replace_row(7, "0.06,100,abc,0"), ("text_value.csv", "line 11", "'abc' is not a number")),
    "empty_field.csv": (_replace_row(3, "0.02,100,,0"), ("empty_field.csv", "line 7", "empty field")),
    "short_row.csv": (_replace_row(4, "0.03,100,100"), ("short_row.csv", "line 8", "3 fields", "4 columns")),
    "long_row.csv": (_replace_row(4, "0.03,100,100,0,7"), ("long_row.csv", "line 8", "5 fields", "4 columns")),
    "decimal_comma.csv": (_replace_row(4, "0,03,100,100,0"), ("decimal_comma.csv", "line 8", "decimal comma")),
    "time_backwards.csv": (_replace_row(6, "0.01,100,100,0"), ("time_backwards.csv", "line 10", "strictly increasing")),
    "time_repeated.csv": (_replace_row(6, "0.04,100,100,0"), ("time_repeated.csv", "line 10", "strictly increasing")),
    "truncated.csv": (_record()[:-3], ("truncated.csv", "line 44", "cut off")),
    "empty.csv": ("", ("empty.csv", "no column header")),
    "header_only.csv": (RECORD_HEADER + "time_s,v_ch1_V,v_ch2_V,z3_mm\n", ("header_only.csv", "no data rows")),
    "one_row.csv": (_record(_rows(1)), ("one_row.csv", "at least 2 samples")),
    "no_unit.csv": (_record([r if i else "time_s,v_ch1_V,v_ch2_V,z3" for i, r in enumerate(_rows())]),
                    ("no_unit.csv", "column 'z3'", "no unit")),
    "bad_unit.csv": (_record([r if i else "time_s,v_ch1_V,v_ch2_V,z3_furlong" for i, r in enumerate(_rows())]),
                     ("bad_unit.csv", "z3_furlong", "unknown unit")),
    "wrong_kind_unit.csv": (_record([r if i else "time_s,v_ch1_V,v_ch2_V,z3_V" for i, r in enumerate(_rows())]),
                            ("wrong_kind_unit.csv", "z3_V", "measured in m")),
    "dup_quantity.csv": (_record([r if i else "time_s,v_ch1_V,v_ch1_mV,z3_mm" for i, r in enumerate(_rows())]),
                         ("dup_quantity.csv", "v_ch1", "twice")),
    "time_not_first.csv": (_record([",".join(reversed(r.split(","))) for r in _rows()]),
                           ("time_not_first.csv", "first column must be the time")),
    "no_input.csv": (_record([",".join(r.split(",")[::3]) for r in _rows()]), ("no_input.csv", "no input channel")),
    "no_output.csv": (_record([",".join(r.split(",")[:3]) for r in _rows()]),
                      ("no_output.csv", "no measured output")),
    **_wrong_headers(),
    "both_drives.csv": (_record([r + ",0" if i else r + ",va_V" for i, r in enumerate(_rows())]),
                        ("both_drives.csv", "either", "va")),
    "latin1.csv": (_record().replace("mbit-b", "mbit-b\u00e9").encode("latin-1"), ("latin1.csv", "utf-8")),
    "binary.csv": (bytes(range(256)) * 4, ("binary.csv", "utf-8")),
    "sidecar_conflict.csv": (_record(), ("sidecar_conflict.meta.toml", "test", "conflicts")),
    "sidecar_bad.csv": (_record(), ("sidecar_bad.meta.toml", "not valid toml")),
    "record.xlsx": ("not a record", ("record.xlsx", "unknown record type")),
    "corrupt.tdms": (b"TDSm" + bytes(200), ("corrupt.tdms", "not a readable TDMS")),
    "empty.tdms": (b"", ("empty.tdms", "tdms")),
    "frf_negative_freq.csv": (_frf("-1,1e-6,0\n2,1e-6,-10\n"), ("frf_negative_freq.csv", "line 7", "frequency",
                                                                 "positive")),
    "frf_no_frf_table.csv": (_frf("1,1e-6,0\n2,1e-6,-10\n", head='# format = "mfc-shm-frf/1"\n'),
                             ("frf_no_frf_table.csv", "frf", "drive")),
    "frf_bad_drive.csv": (_frf("1,1e-6,0\n2,1e-6,-10\n", head=FRF_HEADER.replace('"va"', '"wind"')),
                          ("frf_bad_drive.csv", "frf.drive", "wind")),
    "frf_unsorted.csv": (_frf("2,1e-6,0\n1,1e-6,-10\n"), ("frf_unsorted.csv", "line 8", "increasing")),
    "frf_no_phase.csv": (_frf("1,1e-6\n2,1e-6\n", columns="frequency_Hz,z3_amp_m_per_V"),
                         ("frf_no_phase.csv", "z3", "phase")),
}
SIDECARS = {
    "sidecar_conflict.meta.toml": 'test = "sine"\n',
    "sidecar_bad.meta.toml": "test = = 3\n",
}


def _changed(base: str, change: dict[str, Any]) -> str:
    """The shipped file ``base`` changed as a table of ``tests/data/bad_inputs/config_files.toml`` says (its head
    lists the changes)."""
    if "content" in change:
        return str(change["content"])
    text = variant(base, *change["replace"]) if "replace" in change else base
    if "drop_lines_starting" in change:
        text = "\n".join(ln for ln in text.splitlines() if not ln.startswith(change["drop_lines_starting"])) + "\n"
    if "cut_from" in change:
        text = "\n".join(text.split(change["cut_from"])[0].splitlines()) + "\n"
    return text + change.get("append", "")


_CONFIG_FILES = tomllib.loads((CASE_TABLES / "config_files.toml").read_text(encoding="utf-8"))


def _config_files(kind: str, shipped: Path) -> dict[str, tuple[str, tuple[str, ...]]]:
    base = shipped.read_text()
    return {name: (_changed(base, change), tuple(change["needles"])) for name, change in _CONFIG_FILES[kind].items()}


#: parameter-set, scenario and board configuration files: name -> (content, needles)
PARAMS = _config_files("params", SHIPPED / "params" / "table2.toml")
SCENARIOS = _config_files("scenario", SHIPPED / "scenarios" / "maintenance.toml")
BOARDS = _config_files("board", SHIPPED / "board.toml")


def write_corpus_files(d: Path) -> None:
    """Write every corpus file (and a few good ones the cases refer to) into ``d``."""
    d.mkdir(parents=True, exist_ok=True)
    for table in (RECORDS, PARAMS, SCENARIOS, BOARDS):
        for name, (content, _) in table.items():
            (d / name).write_bytes(content if isinstance(content, bytes) else content.encode("utf-8"))
    for name, content in SIDECARS.items():
        (d / name).write_text(content)
    (d / "good.csv").write_text(_record(_rows(400)))  # long enough for every analysis's own length checks
    (d / "a_file").write_text("I am a file, not a directory\n")
    (d / "notsqlite.db").write_bytes(b"this is not sqlite" * 64)
    import sqlite3

    con = sqlite3.connect(d / "foreign.db")
    con.execute("CREATE TABLE invoices(id INTEGER PRIMARY KEY, amount REAL)")
    con.commit()
    con.close()
    run_dir = d / "foreign_run"
    run_dir.mkdir(exist_ok=True)
    (run_dir / "usage.db").write_bytes((d / "foreign.db").read_bytes())
    done = d / "finished_run"
    done.mkdir(exist_ok=True)
    (done / "summary.json").write_text('{"scenario": "maintenance", "ticks": 6000}')
    (done / "usage.db").write_bytes(b"")
    np.savez(d / "not_a_record.npz", x=np.zeros(3))
    (d / "latin1.toml").write_bytes('[scenario]\nname = "\u00e9t\u00e9"\n'.encode("latin-1"))
    (d / "random.toml").write_bytes(bytes((k * 151 + 7) % 256 for k in range(300)))


def _file_cases() -> list[Case]:
    cases: list[Case] = []
    time_records = {k: v for k, v in RECORDS.items() if not k.startswith("frf_")}
    # every bad record through compare (and a selection through diagnose, fit and health, which load the same way)
    for name, (_, needles) in RECORDS.items():
        cases.append(case(f"compare-{name}", ["compare", f"{{d}}/{name}", "--out", "{o}"], *needles))
    for i, (name, (_, needles)) in enumerate(time_records.items()):
        if i % 2 == 0:
            cases.append(case(f"diagnose-{name}", ["diagnose", f"{{d}}/{name}", "--out", "{o}"], *needles))
        else:
            cases.append(case(f"fit-{name}", ["fit", f"{{d}}/{name}", "--free", "k3", "--save", "{o}/x.toml"],
                              *needles))
    for name in ("nan_value.csv", "bad_unit.csv", "corrupt.tdms", "time_backwards.csv"):
        cases.append(case(f"discover-{name}", ["discover", f"{{d}}/{name}", "--out", "{o}"], *RECORDS[name][1]))
    for name in ("nan_value.csv", "truncated.csv", "bad_unit.csv", "corrupt.tdms", "time_backwards.csv"):
        cases.append(case(f"health-{name}", ["health", f"{{d}}/{name}", "--out", "{o}"],
                          *RECORDS[name][1]))
    # every bad parameter set through model info, and some through synth, run, campaign, harvest, compare
    for name, (_, needles) in PARAMS.items():
        cases.append(case(f"model-info-{name}", ["model", "info", "--params", f"{{d}}/{name}"], *needles))
    for name in ("p_negative_mass.toml", "p_nan.toml", "p_syntax.toml"):
        needles = PARAMS[name][1]
        cases.append(case(f"synth-{name}", ["synth", "--test", "step", "--params", f"{{d}}/{name}", "--out",
                                            "{o}/x.csv"], *needles))
        cases.append(case(f"run-{name}", ["run", "--scenario", "maintenance", "--quiet", "--params", f"{{d}}/{name}",
                                          "--out", "{o}"], *needles))
        cases.append(case(f"campaign-{name}", ["campaign", "--n", "2", "--params", f"{{d}}/{name}", "--out",
                                               "{o}", "--no-progress"], *needles))
        cases.append(case(f"harvest-{name}", ["harvest", "--params", f"{{d}}/{name}", "--out", "{o}"],
                          *needles))
        cases.append(case(f"compare-{name}", ["compare", "{d}/good.csv", "--params", f"{{d}}/{name}", "--out",
                                              "{o}"], *needles))
    for name, (_, needles) in SCENARIOS.items():
        cases.append(case(f"run-{name}", ["run", "--scenario", f"{{d}}/{name}", "--quiet", "--out",
                                          "{o}"], *needles))
    for name, (_, needles) in BOARDS.items():
        cases.append(case(f"run-{name}", ["run", "--scenario", "maintenance", "--board-config", f"{{d}}/{name}",
                                          "--quiet", "--out", "{o}"], *needles))
    return cases


def _option_cases() -> list[Case]:
    return case_table("options.txt")


def unique_ids(cases: list[Case]) -> list[Case]:
    """``cases``, after checking that no two share an id (the ids name the tests)."""
    ids = [c.id for c in cases]
    dup = {i for i in ids if ids.count(i) > 1}
    assert not dup, f"duplicate case ids: {dup}"
    return cases


def all_cases() -> list[Case]:
    return unique_ids(_file_cases() + _option_cases())


def one_line_error(err: str) -> str:
    """The error output with progress bars and blank lines removed (what the user reads)."""
    lines = [ln for ln in re.split(r"[\r\n]+", err) if ln.strip()]
    return "\n".join(lines)
