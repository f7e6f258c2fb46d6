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
from dataclasses import dataclass
from pathlib import Path

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
    "bad_toml_header.csv": (_record(header="# format = \n# test = mbit-b\n"), ("bad_toml_header.csv", "toml")),
    "unknown_meta_key.csv": (_record(header=RECORD_HEADER + "# colour = \"red\"\n"),
                             ("unknown_meta_key.csv", "colour", "unknown key")),
    "bad_format_tag.csv": (_record(header="# format = \"mfc-shm-record/9\"\n"),
                           ("bad_format_tag.csv", "format", "unsupported format")),
    "bad_rate_meta.csv": (_record(header="# sample_rate_Hz = -100.0\n"),
                          ("bad_rate_meta.csv", "sample_rate_Hz", "positive")),
    "rate_mismatch.csv": (_record(header="# sample_rate_Hz = 1000.0\n"),
                          ("rate_mismatch.csv", "sample_rate_Hz", "time column has 100")),
    "bad_terminal.csv": (_record(header="# terminal = \"toaster\"\n"), ("bad_terminal.csv", "terminal", "toaster")),
    "bad_hours.csv": (_record(header="# operating_hours = -5\n"), ("bad_hours.csv", "operating_hours", ">= 0")),
    "bad_segment.csv": (_record(header="# [[segments]]\n# start_s = 1.0\n# end_s = 0.5\n# label = \"x\"\n"),
                        ("bad_segment.csv", "segments[0]", "after start_s")),
    "bad_channel_key.csv": (_record(header="# [channels.z3_mm]\n# colour = \"red\"\n"),
                            ("bad_channel_key.csv", "channels.z3_mm.colour", "unknown key")),
    "channel_not_there.csv": (_record(header="# [channels.z2_mm]\n# sensor = \"x\"\n"),
                              ("channel_not_there.csv", "channels.z2_mm", "does not have")),
    "bad_noise_std.csv": (_record(header="# [channels.z3_mm]\n# noise_std = -1.0\n"),
                          ("bad_noise_std.csv", "noise_std", "non-negative")),
    "input_missing.csv": (_record(header="# inputs = [\"va_V\"]\n"), ("input_missing.csv", "va_V", "missing")),
    "both_drives.csv": (_record([r + ",0" if i else r + ",va_V" for i, r in enumerate(_rows())]),
                        ("both_drives.csv", "either", "va")),
    "latin1.csv": (_record().replace("mbit-b", "mbit-b\u00e9").encode("latin-1"), ("latin1.csv", "utf-8")),
    "binary.csv": (bytes(range(256)) * 4, ("binary.csv", "utf-8")),
    "sidecar_conflict.csv": (_record(), ("sidecar_conflict.meta.toml", "test", "conflicts")),
    "sidecar_bad.csv": (_record(), ("sidecar_bad.meta.toml", "not valid toml")),
    "record.xlsx": ("not a record", ("record.xlsx", "unknown record type")),
    "corrupt.tdms": (b"TDSm" + bytes(200), ("corrupt.tdms", "not a readable TDMS")),
    "empty.tdms": (b"", ("empty.tdms", "tdms")),
    "frf_negative_freq.csv": (
        "# format = \"mfc-shm-frf/1\"\n# [frf]\n# drive = \"va\"\n# amplitude = 100.0\n# amplitude_unit = \"V\"\n"
        "frequency_Hz,z3_amp_m_per_V,z3_phase_deg\n-1,1e-6,0\n2,1e-6,-10\n",
        ("frf_negative_freq.csv", "line 7", "frequency", "positive")),
    "frf_no_frf_table.csv": (
        "# format = \"mfc-shm-frf/1\"\nfrequency_Hz,z3_amp_m_per_V,z3_phase_deg\n1,1e-6,0\n2,1e-6,-10\n",
        ("frf_no_frf_table.csv", "frf", "drive")),
    "frf_bad_drive.csv": (
        "# format = \"mfc-shm-frf/1\"\n# [frf]\n# drive = \"wind\"\n# amplitude = 100.0\n# amplitude_unit = \"V\"\n"
        "frequency_Hz,z3_amp_m_per_V,z3_phase_deg\n1,1e-6,0\n2,1e-6,-10\n",
        ("frf_bad_drive.csv", "frf.drive", "wind")),
    "frf_unsorted.csv": (
        "# format = \"mfc-shm-frf/1\"\n# [frf]\n# drive = \"va\"\n# amplitude = 100.0\n# amplitude_unit = \"V\"\n"
        "frequency_Hz,z3_amp_m_per_V,z3_phase_deg\n2,1e-6,0\n1,1e-6,-10\n",
        ("frf_unsorted.csv", "line 8", "increasing")),
    "frf_no_phase.csv": (
        "# format = \"mfc-shm-frf/1\"\n# [frf]\n# drive = \"va\"\n# amplitude = 100.0\n# amplitude_unit = \"V\"\n"
        "frequency_Hz,z3_amp_m_per_V\n1,1e-6\n2,1e-6\n",
        ("frf_no_phase.csv", "z3", "phase")),
}
SIDECARS = {
    "sidecar_conflict.meta.toml": 'test = "sine"\n',
    "sidecar_bad.meta.toml": "test = = 3\n",
}

_TABLE2 = (SHIPPED / "params" / "table2.toml").read_text()


def _param_variant(old: str, new: str) -> str:
    return variant(_TABLE2, old, new)


#: parameter-set files: name -> (content, needles)
PARAMS: dict[str, tuple[str, tuple[str, ...]]] = {
    "p_syntax.toml": (_TABLE2 + "\nthis is = = not toml\n", ("p_syntax.toml", "toml")),
    "p_negative_mass.toml": (_param_variant("value = 1.16e-3", "value = -1.16e-3"), ("p_negative_mass.toml", "m1")),
    "p_zero_stiffness.toml": (_param_variant("value = 21.28", "value = 0.0"), ("p_zero_stiffness.toml", "k3")),
    "p_nan.toml": (_param_variant("value = 0.098", "value = nan"), ("p_nan.toml", "c1")),
    "p_inf.toml": (_param_variant("value = 1500.0", "value = inf"), ("p_inf.toml", "R_ep")),
    "p_string_value.toml": (_param_variant("value = 332.98", "value = \"stiff\""), ("p_string_value.toml", "k1")),
    "p_wrong_unit.toml": (_param_variant('unit = "N/m",   method = "MEM", definition = "Stiffness related to tip',
                                         'unit = "lbf/in",   method = "MEM", definition = "Stiffness related to tip'),
                          ("p_wrong_unit.toml", "k3", "unit")),
    "p_unknown_param.toml": (_TABLE2.replace("[parameters]\n", "[parameters]\nflux_capacitor = { value = 1.21, "
                                             "unit = \"1\" }\n", 1), ("p_unknown_param.toml", "flux_capacitor")),
    "p_missing_param.toml": ("\n".join(ln for ln in _TABLE2.splitlines() if not ln.startswith("k3 ")) + "\n",
                             ("p_missing_param.toml", "k3")),
    "p_unknown_section.toml": (_TABLE2 + "\n[extras]\nx = 1\n",
                               ("p_unknown_section.toml", "extras", "unknown section")),
    "p_no_parameters.toml": ("[meta]\nname = \"x\"\n", ("p_no_parameters.toml", "parameters", "missing")),
    "p_value_missing.toml": (_param_variant("value = 1.06e-5,", ""), ("p_value_missing.toml", "C_ep")),
    "p_effects_not_array.toml": (_TABLE2 + "\neffects = 3\n", ("p_effects_not_array.toml", "effects")),
    "p_unknown_effect.toml": (_TABLE2 + "\n[[effects]]\nname = \"warp_drive\"\n",
                              ("warp_drive", "unknown effect")),
    "p_empty.toml": ("", ("p_empty.toml", "parameters")),
}

_MAINT = (SHIPPED / "scenarios" / "maintenance.toml").read_text()


def _scn_variant(old: str, new: str) -> str:
    return variant(_MAINT, old, new)


#: scenario files: name -> (content, needles)
SCENARIOS: dict[str, tuple[str, tuple[str, ...]]] = {
    "s_syntax.toml": (_MAINT + "\n[[phase]\n", ("s_syntax.toml", "toml")),
    "s_neg_duration.toml": (_scn_variant("duration = { value = 3, unit", "duration = { value = -3, unit"),
                            ("s_neg_duration.toml", "phase[0].duration")),
    "s_zero_duration.toml": (_scn_variant("duration = { value = 55, unit", "duration = { value = 0, unit"),
                             ("s_zero_duration.toml", "phase[1].duration")),
    "s_nan_duration.toml": (_scn_variant("duration = { value = 2, unit", "duration = { value = nan, unit"),
                            ("s_nan_duration.toml", "phase[2].duration")),
    "s_wrong_unit.toml": (_scn_variant('duration = { value = 3, unit = "s"', 'duration = { value = 3, unit = "min"'),
                          ("s_wrong_unit.toml", "phase[0].duration", "unit")),
    "s_bad_kind.toml": (_scn_variant('kind = "ground"', 'kind = "orbit"'), ("s_bad_kind.toml", "phase[0].kind",
                                                                           "orbit")),
    "s_bad_verdict.toml": (_scn_variant('expect_verdict = "PASS"', 'expect_verdict = "MAYBE"'),
                           ("s_bad_verdict.toml", "expect_verdict", "MAYBE")),
    "s_neg_seed.toml": (_scn_variant("seed = 1", "seed = -4"), ("s_neg_seed.toml", "seed")),
    "s_float_seed.toml": (_scn_variant("seed = 1", "seed = 1.5"), ("s_float_seed.toml", "seed")),
    "s_unknown_key.toml": (_scn_variant("seed = 1", "seed = 1\ncolour = \"red\""), ("s_unknown_key.toml", "colour")),
    "s_unknown_params.toml": (_scn_variant('params = "table2"', 'params = "no_such_set"'),
                              ("s_unknown_params.toml", "no_such_set")),
    "s_battery_low.toml": (_scn_variant("value = 3.0, unit = \"V\"", "value = 0.5, unit = \"V\""),
                           ("s_battery_low.toml", "battery_initial_voltage")),
    "s_battery_huge.toml": (_scn_variant("value = 3.0, unit = \"V\"", "value = 300.0, unit = \"V\""),
                            ("s_battery_huge.toml", "battery_initial_voltage")),
    "s_no_phase.toml": ("\n".join(_MAINT.split("[[phase]]")[0].splitlines()) + "\n", ("s_no_phase.toml", "phase")),
    "s_board_override_bad.toml": (_MAINT + "\n[board.tick]\nrate = { value = -100.0, unit = \"Hz\" }\n",
                                  ("s_board_override_bad.toml", "tick.rate")),
    "s_board_override_unknown.toml": (_MAINT + "\n[board.warp]\nfactor = { value = 9.0, unit = \"1\" }\n",
                                      ("s_board_override_unknown.toml", "warp")),
    "s_deviation_range.toml": (_scn_variant('params = "table2"', 'params = "table2"\ndeviations = { k3 = -7.0 }'),
                               ("s_deviation_range.toml", "k3")),
    "s_unknown_effect.toml": (_scn_variant('params = "table2"', 'params = "table2"\neffects = ["warp_drive"]'),
                              ("s_unknown_effect.toml", "warp_drive")),
    "s_huge_duration.toml": (_scn_variant("duration = { value = 55, unit", "duration = { value = 1e15, unit"),
                             ("s_huge_duration.toml",)),
    "s_event_after_end.toml": (_MAINT + "\n[[event]]\nkind = \"rearm\"\nat = { value = -5, unit = \"s\" }\n",
                               ("s_event_after_end.toml", "event[0].at")),
}

_BOARD = (SHIPPED / "board.toml").read_text()


def _board_variant(old: str, new: str) -> str:
    return variant(_BOARD, old, new)


#: board configuration files: name -> (content, needles)
BOARDS: dict[str, tuple[str, tuple[str, ...]]] = {
    "b_syntax.toml": (_BOARD + "\n[tick\n", ("b_syntax.toml", "toml")),
    "b_neg_rate.toml": (_board_variant("value = 100.0, unit = \"Hz\"", "value = -100.0, unit = \"Hz\""),
                        ("b_neg_rate.toml", "tick.rate")),
    "b_zero_rate.toml": (_board_variant("value = 100.0, unit = \"Hz\"", "value = 0.0, unit = \"Hz\""),
                         ("b_zero_rate.toml", "tick.rate")),
    "b_nan_current.toml": (_board_variant("value = 8.0e-6", "value = nan"), ("b_nan_current.toml",
                                                                            "power.current_standby")),
    "b_wrong_unit.toml": (_board_variant("value = 2.0,  unit = \"V\",     definition = \"Wake threshold",
                                         "value = 2.0,  unit = \"mV\",     definition = \"Wake threshold"),
                          ("b_wrong_unit.toml", "wake.patch_voltage", "unit")),
    "b_unknown_section.toml": (_BOARD + "\n[turbo]\nboost = { value = 1.0, unit = \"1\" }\n",
                               ("b_unknown_section.toml", "turbo")),
    "b_unknown_key.toml": (_board_variant("[tick]\n", "[tick]\nwarp = { value = 1.0, unit = \"1\" }\n"),
                           ("b_unknown_key.toml", "tick.warp")),
    "b_missing_key.toml": ("\n".join(ln for ln in _BOARD.splitlines() if not ln.startswith("stale_ticks")) + "\n",
                           ("b_missing_key.toml", "stale_ticks")),
    "b_float_count.toml": (_board_variant("link_loss_ticks = { value = 2,", "link_loss_ticks = { value = 2.5,"),
                           ("b_float_count.toml", "tick.link_loss_ticks")),
    "b_neg_count.toml": (_board_variant("overrun_ticks   = { value = 5,", "overrun_ticks   = { value = -5,"),
                         ("b_neg_count.toml", "tick.overrun_ticks")),
    "b_bad_sequence.toml": (_board_variant('sequence    = ["a", "b"]', 'sequence    = ["a", "z"]'),
                            ("b_bad_sequence.toml", "sequence")),
    "b_string_value.toml": (_board_variant("value = 0.05,   unit = \"m\"", "value = \"far\",   unit = \"m\""),
                            ("b_string_value.toml", "sensors.z3_limit")),
    "b_brownout_order.toml": (_board_variant("value = 2.30,   unit = \"V\"", "value = 2.95,   unit = \"V\""),
                              ("b_brownout_order.toml", "brownout")),
}


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
