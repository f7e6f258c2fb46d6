"""The bad-input corpus (issue 12, point 10): files and command lines a lab would get wrong, with what the one-line
error must name. Used by ``tests/shm_cli/test_bad_inputs.py``.

A case is ``Case(id, argv, needles, code=2)``: ``argv`` may hold ``{d}`` (the corpus directory, where
:func:`write_corpus_files` put every file) and ``{shipped}`` (the shipped configuration directory); ``needles``
are strings that must all appear in the error output (case-insensitive): the file/key/option or value, and a word
of the reason. Every case must fail during validation, before any heavy simulation.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = ROOT / "board_config"


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


# ------------------------------------------------------------------------------------------------------------
# files
RECORD_HEADER = """# format = "mfc-shm-record/1"
# test = "mbit-b"
# sample_rate_Hz = 100.0
"""


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
    assert old in _TABLE2, old
    return _TABLE2.replace(old, new, 1)


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
    assert old in _MAINT, old
    return _MAINT.replace(old, new, 1)


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
    assert old in _BOARD, old
    return _BOARD.replace(old, new, 1)


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
    c = case
    out = "--out {o}"
    return [
        # shm run
        c("run-seed-neg", f"run --seed -1 --quiet {out}", "--seed", "-1"),
        c("run-seed-text", f"run --seed one --quiet {out}", "--seed", "one"),
        c("run-seed-huge", f"run --seed 99999999999999 --quiet {out}", "--seed", "99999999999999"),
        c("run-duration-zero", f"run --duration-s 0 --quiet {out}", "--duration-s", "0"),
        c("run-duration-neg", f"run --duration-s -5 --quiet {out}", "--duration-s", "-5"),
        c("run-duration-nan", f"run --duration-s nan --quiet {out}", "--duration-s", "nan"),
        c("run-duration-inf", f"run --duration-s inf --quiet {out}", "--duration-s", "inf"),
        c("run-duration-huge", f"run --duration-s 1e13 --quiet {out}", "--duration-s", "memory"),
        c("run-timeline-neg", f"run --timeline-every-s -1 --quiet {out}", "--timeline-every-s", "-1"),
        c("run-timeline-nan", f"run --timeline-every-s nan --quiet {out}", "--timeline-every-s", "nan"),
        c("run-scenario-missing", f"run --scenario {{d}}/nope.toml --quiet {out}", "nope.toml"),
        c("run-scenario-unknown", f"run --scenario no-such --quiet {out}", "no-such", "unknown scenario"),
        c("run-scenario-dir", f"run --scenario {{d}} --quiet {out}", "is a directory"),
        c("run-params-unknown", f"run --params no-such-set --quiet {out}", "no-such-set"),
        c("run-board-missing", f"run --board-config {{d}}/nope.toml --quiet {out}", "nope.toml"),
        c("run-link-scheme", f"run --link carrier-pigeon://x --quiet {out}", "carrier-pigeon://x"),
        c("run-link-noport", f"run --link modbus-tcp://127.0.0.1 --quiet {out}", "modbus-tcp://127.0.0.1",
          code=1),  # an unreachable peer: the job failed, not the input
        c("run-link-badport", f"run --link socket://127.0.0.1:99999 --quiet {out}", "99999"),
        c("run-link-textport", f"run --link modbus-tcp://127.0.0.1:http --quiet {out}", "http"),
        c("run-link-empty", ["run", "--link", "", "--quiet", "--out", "{o}"], "--link", "empty"),
        c("run-live-badport", f"run --live 70000 --quiet {out}", "--live", "70000"),
        c("run-live-nohost", f"run --live :8765 --quiet {out}", "--live", "no host"),
        c("run-live-linger-alone", f"run --live-linger 3 --quiet {out}", "--live-linger", "--live"),
        c("run-live-life", f"run --scenario aging --live 0 --quiet {out}", "--live", "aging", "life"),
        c("run-out-file", "run --quiet --out {d}/a_file", "--out", "a_file", "not a directory"),
        c("run-out-under-file", "run --quiet --out {d}/a_file/sub", "--out", "a_file", "not a directory"),
        c("run-finished-dir", "run --quiet --out {d}/finished_run", "finished_run", "--force"),
        c("run-append-foreign", "run --quiet --append --out {d}/foreign_run", "usage.db", "another application"),
        c("run-append-force", f"run --quiet --append --force {out}", "--force", "not allowed"),
        c("run-log-sync", f"run --log-sync maybe --quiet {out}", "--log-sync", "maybe"),
        c("run-realtime-virtual", f"run --realtime --virtual --quiet {out}", "--virtual", "not allowed"),
        # shm log
        c("log-limit-neg", "log show --db {d}/finished_run/usage.db --limit -1", "--limit", "-1"),
        c("log-limit-text", "log show --db {d}/finished_run/usage.db --limit many", "--limit", "many"),
        c("log-run-zero", "log show --db {d}/finished_run/usage.db --run 0", "--run", "0"),
        c("log-db-missing", "log show --db {d}/nope.db", "nope.db", "no such"),
        c("log-db-notsqlite", "log show --db {d}/notsqlite.db", "notsqlite.db", "not a usage log"),
        c("log-db-foreign", "log show --db {d}/foreign.db", "foreign.db", "not a usage log"),
        c("log-db-dir", "log show --db {d}", "not a usage log"),
        c("log-db-csv", "log show --db {d}/good.csv", "good.csv", "not a usage log"),
        c("log-export-foreign", "log export --db {d}/foreign.db", "foreign.db", "not a usage log"),
        c("log-export-table", "log export --db {d}/foreign.db --table nope", "foreign.db"),
        c("log-tables-and-table", "log show --db {d}/finished_run/usage.db --tables --table runs", "--tables",
          "--table"),
        # shm effects
        c("effects-show-unknown", "effects show warp", "warp", "unknown effect"),
        c("effects-show-missing-file", "effects show {d}/nope_effect.py", "nope_effect.py", "does not exist"),
        c("effects-show-not-an-effect", "effects show os:path", "os:path", "not a PhysicalEffect"),
        c("effects-show-csv-file", "effects show {d}/good.csv", "good.csv"),
        c("effects-show-bad-prefix", ["effects", "show", "geometric_stiffening as 2x"], "2x"),
        c("effects-show-empty", ["effects", "show", ""], "effect"),
        c("effects-no-subcommand", "effects", "subcommand"),
        # shm synth
        c("synth-amp-1MV", "synth --test sine --amplitude 1e6 --out {o}/x.csv", "1e+06", "-500", "1500"),
        c("synth-amp-neg", "synth --test sine --amplitude -300 --out {o}/x.csv", "--amplitude", "-300"),
        c("synth-amp-nan", "synth --test sine --amplitude nan --out {o}/x.csv", "--amplitude", "nan"),
        c("synth-bias-over", "synth --test sine --amplitude 600 --bias-v 1000 --out {o}/x.csv", "1600",
          "1500"),
        c("synth-bias-inf", "synth --test sine --bias-v inf --out {o}/x.csv", "--bias-v", "inf"),
        c("synth-base-huge", "synth --test sine --drive base --amplitude 1e4 --out {o}/x.csv", "10000 g",
          "100 g"),
        c("synth-freq-zero", "synth --test sine --freq-hz 0 --out {o}/x.csv", "--freq-hz", "0"),
        c("synth-freq-neg", "synth --test sine --freq-hz -2 --out {o}/x.csv", "--freq-hz", "-2"),
        c("synth-rate-zero", "synth --test sine --rate-hz 0 --out {o}/x.csv", "--rate-hz", "0"),
        c("synth-duration-neg", "synth --test sine --duration-s -1 --out {o}/x.csv", "--duration-s", "-1"),
        c("synth-duration-huge", "synth --test sine --duration-s 1e12 --out {o}/x.csv", "1e+12", "memory"),
        c("synth-rate-huge", "synth --test sine --rate-hz 1e15 --out {o}/x.csv", "1e+15", "memory"),
        c("synth-nfreqs-one", "synth --test frf --n-freqs 1 --out {o}/x.csv", "--n-freqs", "1"),
        c("synth-nfreqs-huge", "synth --test frf --n-freqs 100000000 --out {o}/x.csv", "--n-freqs"),
        c("synth-f1-below-f0", "synth --test sweep --f0-hz 10 --f1-hz 5 --out {o}/x.csv", "f1", "f0"),
        c("synth-seed-neg", "synth --test step --seed -3 --out {o}/x.csv", "--seed", "-3"),
        c("synth-test-unknown", "synth --test lunar --out {o}/x.csv", "--test", "lunar"),
        c("synth-out-suffix", "synth --test step --out {d}/o_synth/x.xlsx", "x.xlsx", ".csv"),
        c("synth-out-dir", "synth --test step --out {d}", "--out", "directory"),
        c("synth-out-under-file", "synth --test step --out {d}/a_file/x.csv", "--out", "a_file"),
        c("synth-set-syntax", "synth --test step --set k3 --out {o}/x.csv", "--set", "NAME=VALUE"),
        c("synth-set-text", "synth --test step --set k3=stiff --out {o}/x.csv", "k3", "stiff"),
        c("synth-set-unknown", "synth --test step --set warp=1 --out {o}/x.csv", "warp"),
        c("synth-set-nan", "synth --test step --set k3=nan --out {o}/x.csv", "k3", "nan"),
        c("synth-deviation-low", "synth --test step --deviation k3=-2 --out {o}/x.csv", "k3", "-1"),
        c("synth-deviation-unknown", "synth --test step --deviation warp=0.1 --out {o}/x.csv", "warp"),
        c("synth-noise-neg", "synth --test step --noise z3=-1e-6 --out {o}/x.csv", "z3", "noise"),
        c("synth-noise-chan", "synth --test step --noise flux=1 --out {o}/x.csv", "flux"),
        c("synth-effect-unknown", "synth --test step --effect warp_drive --out {o}/x.csv", "warp_drive"),
        c("synth-channel-unknown", "synth --test step --channels z9 --out {o}/x.csv", "z9"),
        c("synth-base-step", "synth --test step --drive base --out {o}/x.csv", "step", "base"),
        # shm model
        c("model-frf-points-zero", "model frf --points 0 --out {o}", "--points", "0"),
        c("model-frf-points-huge", "model frf --points 10000000000 --out {o}", "--points"),
        c("model-frf-fmin-neg", "model frf --f-min-hz -1 --out {o}", "--f-min-hz", "-1"),
        c("model-frf-fmax-nan", "model frf --f-max-hz nan --out {o}", "--f-max-hz", "nan"),
        c("model-frf-order", "model frf --f-min-hz 100 --f-max-hz 10 --out {o}", "--f-min-hz", "--f-max-hz"),
        c("model-frf-out-file", "model frf --out {d}/a_file", "--out", "a_file"),
        c("model-step-amp-huge", "model step --amplitude-v 1e6 --out {o}", "--amplitude-v", "1500"),
        c("model-step-duration-neg", "model step --duration-s -2 --out {o}", "--duration-s", "-2"),
        c("model-step-duration-huge", "model step --duration-s 1e12 --out {o}", "--duration-s"),
        c("model-loop-freq-zero", "model loop --freq-hz 0 --out {o}", "--freq-hz", "0"),
        c("model-loop-cycles-neg", "model loop --cycles -1 --out {o}", "--cycles", "-1"),
        c("model-loop-cycles-huge", "model loop --cycles 1e12 --out {o}", "--cycles"),
        c("model-info-params-missing", "model info --params {d}/nope.toml", "nope.toml"),
        c("model-info-params-dir", "model info --params {d}", "is a directory"),
        c("model-info-params-csv", "model info --params {d}/good.csv", "good.csv"),
        # shm harvest
        c("harvest-accel-neg", "harvest --accel-g -0.1 --out {o}", "acceleration", "-0.1"),
        c("harvest-accel-nan", "harvest --accel-g nan --out {o}", "--accel-g", "nan"),
        c("harvest-freq-zero", "harvest --freq-hz 0 --out {o}", "frequency", "0"),
        c("harvest-rint-neg", "harvest --r-int-ohm -1 --out {o}", "resistance", "-1"),
        c("harvest-duration-neg", "harvest --duration-s -600 --out {o}", "duration", "-600"),
        c("harvest-duration-huge", "harvest --duration-s 1e15 --out {o}", "duration", "range"),
        c("harvest-battery-unknown", "harvest --battery AA-cell --out {o}", "AA-cell"),
        c("harvest-from-v", "harvest --from-v 9 --out {o}", "start voltage", "9"),
        c("harvest-diode-neg", "harvest --diode-drop-v -0.5 --out {o}", "diode", "-0.5"),
        c("harvest-current-neg", "harvest --board-current-ma -1 --out {o}", "board load current", "-0.001 A"),
        c("harvest-out-file", "harvest --out {d}/a_file", "--out", "a_file"),
        # shm campaign
        c("campaign-n-zero", "campaign --n 0 --out {o} --no-progress", "--n", "0"),
        c("campaign-n-huge", "campaign --n 10000000000000 --out {o} --no-progress", "--n"),
        c("campaign-workers-zero", "campaign --n 2 --workers 0 --out {o} --no-progress", "--workers", "0"),
        c("campaign-batch-zero", "campaign --n 2 --batch-size 0 --out {o} --no-progress", "--batch-size", "0"),
        c("campaign-noise-neg", "campaign --n 2 --noise-um -1 --out {o} --no-progress", "--noise-um", "-1"),
        c("campaign-noise-nan", "campaign --n 2 --noise-um nan --out {o} --no-progress", "--noise-um", "nan"),
        c("campaign-ranges-text", "campaign --n 2 --ranges a:b:c --out {o} --no-progress", "--ranges", "a:b:c"),
        c("campaign-ranges-order", "campaign --n 2 --ranges 50:0:10 --out {o} --no-progress", "--ranges"),
        c("campaign-ranges-step0", "campaign --n 2 --ranges 0:50:0 --out {o} --no-progress", "--ranges"),
        c("campaign-mbit", "campaign --n 2 --mbit c --out {o} --no-progress", "--mbit", "c"),
        c("campaign-deviate", "campaign --n 2 --deviate warp --out {o} --no-progress", "warp"),
        c("campaign-mbit-config", "campaign --n 2 --mbit-config {d}/nope.toml --out {o} --no-progress",
          "nope.toml"),
        c("campaign-dask-timeout", "campaign --n 2 --dask-timeout-s -1 --out {o} --no-progress",
          "--dask-timeout-s", "-1"),
        c("campaign-out-file", "campaign --n 2 --out {d}/a_file --no-progress", "--out", "a_file"),
        c("campaign-roc-from", "campaign-roc --from {d}/nope", "nope"),
        c("campaign-roc-pct", "campaign-roc --from {d} --healthy-max-pct 150", "--healthy-max-pct", "150"),
        c("campaign-roc-eps", "campaign-roc --from {d} --eps-th x:y:z", "--eps-th"),
        # shm hil serve
        c("hil-baud-neg", "hil serve --serial pty --baud -9600", "--baud", "-9600"),
        c("hil-baud-zero", "hil serve --serial pty --baud 0", "--baud", "0"),
        c("hil-unit-zero", "hil serve --modbus-tcp 127.0.0.1:0 --unit 0", "--unit", "0"),
        c("hil-unit-big", "hil serve --modbus-tcp 127.0.0.1:0 --unit 300", "--unit", "300"),
        c("hil-drop-over", "hil serve --serial pty --drop 2", "--drop", "2"),
        c("hil-drop-neg", "hil serve --serial pty --drop -0.1", "--drop", "-0.1"),
        c("hil-corrupt-nan", "hil serve --serial pty --corrupt nan", "--corrupt", "nan"),
        c("hil-latency-neg", "hil serve --serial pty --latency-ms -1", "--latency-ms", "-1"),
        c("hil-jitter-neg", "hil serve --serial pty --jitter-ms -1", "--jitter-ms", "-1"),
        c("hil-duration-neg", "hil serve --serial pty --duration -5", "--duration", "-5"),
        c("hil-status-neg", "hil serve --serial pty --status-every -1", "--status-every", "-1"),
        c("hil-disconnect-for", "hil serve --serial pty --disconnect-at 1 --disconnect-for -1", "--disconnect-for"),
        c("hil-no-endpoint", "hil serve", "endpoint"),
        c("hil-tcp-port-text", "hil serve --modbus-tcp 127.0.0.1:http", "127.0.0.1:http"),
        c("hil-tcp-port-big", "hil serve --modbus-tcp 127.0.0.1:70000", "70000"),
        c("hil-serial-bad-path", "hil serve --serial {d}/no/such/tty", "no/such/tty"),
        c("hil-scenario-unknown", "hil serve --serial pty --scenario no-such", "no-such"),
        c("hil-params-bad", "hil serve --serial pty --params {d}/p_nan.toml", "p_nan.toml"),
        c("hil-noise-syntax", "hil serve --serial pty --noise z3", "--noise", "z3"),
        c("hil-deviation-text", "hil serve --serial pty --deviation k3=lots", "k3", "lots"),
        c("hil-stuck-chan", "hil serve --serial pty --stuck flux", "flux"),
        c("hil-effect", "hil serve --serial pty --effect warp_drive", "warp_drive"),
        c("hil-summary-dir", "hil serve --serial pty --summary {d}", "--summary"),
        # shm compare / diagnose / fit / health / calibrate options
        c("compare-missing", "compare {d}/nope.csv --out {o}", "nope.csv", "not found"),
        c("compare-level", "compare {d}/good.csv --level 2 --out {o}", "--level", "2"),
        c("compare-level-zero", "compare {d}/good.csv --level 0 --out {o}", "--level", "0"),
        c("compare-lags", "compare {d}/good.csv --lags 0 --out {o}", "--lags", "at least 1"),
        c("compare-decimate", "compare {d}/good.csv --decimate 0 --out {o}", "--decimate", "at least 1"),
        c("compare-skip-neg", "compare {d}/good.csv --skip-s -1 --out {o}", "--skip-s", ">= 0"),
        c("compare-sigma", "compare {d}/good.csv --threshold-sigma -3 --out {o}", "--threshold-sigma"),
        c("compare-window", "compare {d}/good.csv --window-s 0 --out {o}", "--window-s", "0"),
        c("compare-horizon", "compare {d}/good.csv --horizon-s nan --out {o}", "--horizon-s", "nan"),
        c("compare-interval", "compare {d}/good.csv --interval-s -0.01 --out {o}", "--interval-s"),
        c("compare-add", "compare {d}/good.csv --add warp_drive --out {o}", "warp_drive"),
        c("compare-set", "compare {d}/good.csv --set k3=abc --out {o}", "k3", "abc"),
        c("compare-eq4", "compare {d}/good.csv --eq4 z3=x --out {o}", "--eq4"),
        c("compare-out-file", "compare {d}/good.csv --out {d}/a_file", "--out", "a_file"),
        c("discover-max-terms", "discover {d}/good.csv --max-terms 0 --out {o}", "--max-terms", "0"),
        c("discover-refit", "discover {d}/good.csv --refit -2 --out {o}", "--refit", "-2"),
        c("discover-blocks-odd", "discover {d}/good.csv --blocks 3 --out {o}", "--blocks", "3"),
        c("discover-rate", "discover {d}/good.csv --max-rate-hz -5 --out {o}", "--max-rate-hz", "-5"),
        c("discover-add-unknown", "discover {d}/good.csv --add warp_drive --out {o}", "warp_drive"),
        c("discover-emit-dir", "discover {d}/good.csv --emit {d} --out {o}", "--emit"),
        c("discover-emit-not-py", "discover {d}/good.csv --emit {o}/effect.txt --out {o}", "--emit", ".py"),
        c("discover-params", "discover {d}/good.csv --params {d}/nope.toml --out {o}", "nope.toml"),
        c("discover-missing-record", "discover {d}/nope.csv --out {o}", "nope.csv"),
        c("discover-out-file", "discover {d}/good.csv --out {d}/a_file", "--out", "a_file"),
        c("diagnose-blocks-odd", "diagnose {d}/good.csv --blocks 3 --out {o}", "--blocks", "3"),
        c("diagnose-blocks-zero", "diagnose {d}/good.csv --blocks 0 --out {o}", "--blocks", "0"),
        c("diagnose-fit-top", "diagnose {d}/good.csv --fit-top -1 --out {o}", "--fit-top", ">= 0"),
        c("diagnose-rate", "diagnose {d}/good.csv --max-rate-hz 0 --out {o}", "--max-rate-hz", "0"),
        c("diagnose-min-red", "diagnose {d}/good.csv --min-reduction -1 --out {o}", "--min-reduction"),
        c("diagnose-workers", "diagnose {d}/good.csv --workers 0 --out {o}", "--workers", "0"),
        c("diagnose-candidates", "diagnose {d}/good.csv --candidates warp_drive --out {o}", "warp_drive"),
        c("diagnose-out-file", "diagnose {d}/good.csv --out {d}/a_file", "--out", "a_file"),
        c("fit-free-unknown", "fit {d}/good.csv --free warp --save {o}/x.toml", "warp"),
        c("fit-free-range", "fit {d}/good.csv --free k3:30:10 --save {o}/x.toml", "k3"),
        c("fit-nfev", "fit {d}/good.csv --free k3 --max-nfev 0 --save {o}/x.toml", "--max-nfev", "0"),
        c("fit-blocks", "fit {d}/good.csv --free k3 --blocks -2 --save {o}/x.toml", "--blocks", "-2"),
        c("fit-save-dir", "fit {d}/good.csv --free k3 --save {d}", "--save"),
        c("fit-save-under-file", "fit {d}/good.csv --free k3 --save {d}/a_file/x.toml", "--save", "a_file"),
        c("health-as-of", "health {d}/good.csv --as-of -5 --out {o}", "--as-of", "-5"),
        c("health-workers", "health {d}/good.csv --workers 0 --out {o}", "--workers", "0"),
        c("health-missing", "health {d}/nope_dir --out {o}", "nope_dir"),
        c("health-out-file", "health {d}/good.csv --out {d}/a_file", "--out", "a_file"),
        c("calibrate-claims", "calibrate --claims {d}/nope.toml --out {o}", "nope.toml"),
        c("calibrate-claims-bad", "calibrate --claims {d}/p_syntax.toml --out {o}", "p_syntax.toml"),
        c("calibrate-damping", "calibrate --min-damping -1 --out {o}", "--min-damping", "-1"),
        c("calibrate-free", "calibrate --free warp --out {o}", "warp"),
        c("calibrate-out-file", "calibrate --out {d}/a_file", "--out", "a_file"),
        # files that are not text at all, and empty names
        c("run-scenario-latin1", f"run --scenario {{d}}/latin1.toml --quiet {out}", "latin1.toml", "utf-8"),
        c("run-params-random", f"run --params {{d}}/random.toml --quiet {out}", "random.toml", "utf-8"),
        c("run-board-random", f"run --board-config {{d}}/random.toml --quiet {out}", "random.toml", "utf-8"),
        c("model-info-params-latin1", "model info --params {d}/latin1.toml", "latin1.toml", "utf-8"),
        c("campaign-mbit-config-random", "campaign --n 2 --mbit-config {d}/random.toml --out {o} --no-progress",
          "random.toml", "utf-8"),
        c("campaign-monitor-config-bad", "campaign --n 2 --monitor-config {d}/p_syntax.toml --out {o} --no-progress",
          "p_syntax.toml", "toml"),
        c("run-params-empty", ["run", "--params", "", "--quiet", "--out", "{o}"], "--params", "empty"),
        c("run-scenario-empty", ["run", "--scenario", " ", "--quiet", "--out", "{o}"], "--scenario", "empty"),
        c("campaign-ranges-billion", "campaign --n 2 --ranges 0:1e9:1 --out {o} --no-progress", "--ranges", "1e+09",
          "at most"),
        c("calibrate-name-empty", ["calibrate", "--name", "", "--out", "{o}"], "--name", "empty"),
        c("calibrate-save-under-file", "calibrate --save {d}/a_file/x.toml --out {o}", "--save", "a_file"),
        c("synth-frf-extreme-freq", "synth --test frf --f0-hz 1e-300 --f1-hz 1e300 --out {o}/x.csv", "--f0-hz",
          "1e-300"),
        c("synth-freq-over-table1", "synth --test sine --freq-hz 20000 --out {o}/x.csv", "--freq-hz", "10 kHz"),
        c("log-table-empty", ["log", "show", "--db", "{d}/finished_run/usage.db", "--table", ""], "usage.db"),
        c("run-out-empty", ["run", "--quiet", "--out", ""], "--out", "empty"),
        c("synth-out-empty", ["synth", "--test", "step", "--out", ""], "--out", "empty"),
        c("model-out-devnull", "model frf --out /dev/null", "--out", "not a directory"),
        c("hil-noise-negative", "hil serve --serial pty --noise z3=-1 --duration 0.2", "--noise", "z3"),
        c("hil-deviation-low", "hil serve --serial pty --deviation k3=-5 --duration 0.2", "--deviation", "k3"),
        c("campaign-deviate-twice", "campaign --n 2 --deviate k3,k3 --out {o} --no-progress", "--deviate", "twice"),
        c("campaign-roc-from-csv", "campaign-roc --from {d}/good.csv", "good.csv"),
        c("fit-save-suffix", "fit {d}/good.csv --free k3 --save {o}/x.txt", "--save", "x.txt"),
        c("compare-set-negative", "compare {d}/good.csv --set k3=-5 --out {o}", "k3", "-5"),
        c("compare-params-csv", "compare {d}/good.csv --params {d}/good.csv --out {o}", "good.csv", "toml"),
        c("run-scenario-is-params", "run --scenario {d}/p_nan.toml --quiet --out {o}", "p_nan.toml", "meta"),
        c("run-board-is-scenario", "run --board-config {d}/s_neg_seed.toml --quiet --out {o}", "s_neg_seed.toml",
          "phase"),
        c("fit-seed-negative", "fit {d}/good.csv --free k3 --seed -1 --save {o}/x.toml", "--seed", "-1"),
        c("diagnose-seed-negative", "diagnose {d}/good.csv --seed -1 --out {o}", "--seed", "-1"),
        c("campaign-seed-huge", "campaign --n 2 --seed 99999999999999999999 --out {o} --no-progress", "--seed",
          "99999999999999999999"),
        c("health-seed-huge", "health {d}/good.csv --seed 99999999999999999999 --out {o}", "--seed"),
        # argparse itself
        c("no-command", [], "command"),
        c("unknown-command", "frobnicate", "frobnicate"),
        c("unknown-option", "model info --frobnicate", "--frobnicate"),
    ]


def all_cases() -> list[Case]:
    cases = _file_cases() + _option_cases()
    ids = [c.id for c in cases]
    dup = {i for i in ids if ids.count(i) > 1}
    assert not dup, dup
    return cases


def one_line_error(err: str) -> str:
    """The error output with progress bars and blank lines removed (what the user reads)."""
    lines = [ln for ln in re.split(r"[\r\n]+", err) if ln.strip()]
    return "\n".join(lines)
