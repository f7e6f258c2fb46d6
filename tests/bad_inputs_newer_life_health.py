"""The bad-input corpus of issue 33 for ``[life]`` scenarios and ``shm health`` inputs (helper A's part).

Same form as ``tests/bad_inputs_corpus.py`` (its :class:`Case` and :func:`case` are reused): ``{d}`` is the corpus
directory (:func:`write_corpus_files`), ``{o}`` an output directory of the case's own. Every case fails during
validation in the parent, before any worker or fit starts, so the corpus takes seconds. Used by
``tests/shm_cli/test_bad_inputs_newer_life_health.py``.
"""

from __future__ import annotations

import sqlite3
from pathlib import Path

from bad_inputs_corpus import PARAMS, Case, case, case_table, unique_ids, variant
from scenario_text_support import life_scenario, linear_law

#: a valid life: 3 visits 400 h apart, alpha_h drifting (tests/studies/test_health.py's tiny life)
LIFE = life_scenario("tiny-life", 3, 400, rig='params = "table2"\n', sep="\n")

_LAW = linear_law()


def _v(old: str, new: str) -> str:
    return variant(LIFE, old, new)


def _law(text: str) -> str:
    return LIFE.replace(_LAW, text, 1)


#: [life] scenario files: name -> (content, needles of the error line)
LIVES: dict[str, tuple[str, tuple[str, ...]]] = {
    "l_unknown_param.toml": (_v('parameter = "alpha_h"', 'parameter = "nosuch"'),
                             ("l_unknown_param.toml", "life.law[0].parameter", "nosuch")),
    "l_empty_param.toml": (_v('parameter = "alpha_h"', 'parameter = ""'), ("l_empty_param.toml", "life.law[0]")),
    "l_effect_param_no_effect.toml": (_v('parameter = "alpha_h"', 'parameter = "G_leak"'),
                                      ("l_effect_param_no_effect.toml", "G_leak", "[rig] effects")),
    "l_effect_param_out_of_range.toml": (
        _v('params = "table2"', 'params = "table2"\neffects = ["dielectric_leakage"]\n'
                                'effect_params = { G_leak = 0.5 }'),
        ("l_effect_param_out_of_range.toml", "G_leak")),
    "l_unknown_effect.toml": (_v('params = "table2"', 'params = "table2"\neffects = ["warp_drive"]'),
                              ("l_unknown_effect.toml", "warp_drive")),
    "l_unknown_flight.toml": (_v("[[life.law]]", 'flight_scenario = "nosuch"\n'
                                                 'tick_flights = { value = 1, unit = "1" }\n[[life.law]]'),
                              ("l_unknown_flight.toml", "life.flight_scenario", "nosuch")),
    "l_missing_flight_file.toml": (_v("[[life.law]]", 'flight_scenario = "nope.toml"\n'
                                                      'tick_flights = { value = 1, unit = "1" }\n[[life.law]]'),
                                   ("l_missing_flight_file.toml", "life.flight_scenario", "nope.toml")),
    "l_flight_no_phases.toml": (_v("[[life.law]]", 'flight_scenario = "only_maint.toml"\n'
                                                   'tick_flights = { value = 1, unit = "1" }\n[[life.law]]'),
                                ("life.flight_scenario", "no flight phases")),
    "l_flight_not_str.toml": (_v("[[life.law]]", "flight_scenario = 3\n[[life.law]]"),
                              ("l_flight_not_str.toml", "life.flight_scenario")),
    "l_negative_rate.toml": (_v("value = 2e-4", "value = -2e-2"),
                             ("l_negative_rate.toml", "life.law[0]", "alpha_h", "outside the allowed")),
    "l_rate_too_fast.toml": (_v("value = 2e-4", "value = 5e-2"), ("l_rate_too_fast.toml", "alpha_h", "outside")),
    "l_rate_over_schema.toml": (_v("value = 2e-4", "value = 2.0"), ("l_rate_over_schema.toml", "rate")),
    "l_rate_nan.toml": (_v("value = 2e-4", "value = nan"), ("l_rate_nan.toml", "rate")),
    "l_rate_inf.toml": (_v("value = 2e-4", "value = inf"), ("l_rate_inf.toml", "rate")),
    "l_rate_string.toml": (_v("value = 2e-4", 'value = "fast"'), ("l_rate_string.toml", "rate")),
    "l_rate_unit.toml": (_v('unit = "1/h" }', 'unit = "%/h" }'), ("l_rate_unit.toml", "rate", "unit")),
    "l_rate_missing.toml": (_v("rate = { value = 2e-4, unit = \"1/h\" }", ""), ("l_rate_missing.toml", "rate")),
    "l_unknown_kind.toml": (_v('kind = "linear"', 'kind = "quadratic"'), ("l_unknown_kind.toml", "life.law[0].kind")),
    "l_law_not_array.toml": (_law("[life.law]\nparameter = \"k3\"\n"), ("l_law_not_array.toml", "life.law")),
    "l_law_entry_not_table.toml": (_v("[life]\n", "[life]\nlaw = [1, 2]\n").replace(_LAW, ""),
                                   ("l_law_entry_not_table.toml", "life.law[0]")),
    "l_law_unknown_key.toml": (_v("kind = \"linear\"\n", "kind = \"linear\"\ncolour = { value = 1, unit = \"1\" }\n"),
                               ("l_law_unknown_key.toml", "colour")),
    "l_no_maintenance.toml": (_v('kind = "maintenance"', 'kind = "ground"'),
                              ("l_no_maintenance.toml", "phase", "maintenance")),
    "l_zero_visits.toml": (_v("visits = { value = 3", "visits = { value = 0"), ("l_zero_visits.toml", "life.visits")),
    "l_many_visits.toml": (_v("visits = { value = 3", "visits = { value = 5000"),
                           ("l_many_visits.toml", "life.visits")),
    "l_fraction_visits.toml": (_v("visits = { value = 3", "visits = { value = 2.5"),
                               ("l_fraction_visits.toml", "life.visits")),
    "l_negative_interval.toml": (_v("visit_interval = { value = 400", "visit_interval = { value = -400"),
                                 ("l_negative_interval.toml", "life.visit_interval")),
    "l_zero_interval.toml": (_v("visit_interval = { value = 400", "visit_interval = { value = 0"),
                             ("l_zero_interval.toml", "life.visit_interval")),
    "l_interval_unit.toml": (_v('visit_interval = { value = 400, unit = "h"', 'visit_interval = { value = 400, '
                                                                              'unit = "fortnight"'),
                             ("l_interval_unit.toml", "life.visit_interval", "unit")),
    "l_implausible_hours.toml": (_v("visit_interval = { value = 400", "visit_interval = { value = 1e9"),
                                 ("l_implausible_hours.toml", "life.visit_interval", "plausible")),
    "l_negative_first.toml": (_v("[life]\n", "[life]\nfirst_visit = { value = -5, unit = \"h\" }\n"),
                              ("l_negative_first.toml", "life.first_visit")),
    "l_negative_flights.toml": (_v("[life]\n", "[life]\nflights_between_visits = { value = -1, unit = \"1\" }\n"),
                                ("l_negative_flights.toml", "life.flights_between_visits")),
    "l_negative_tick.toml": (_v("[life]\n", "[life]\ntick_flights = { value = -1, unit = \"1\" }\n"),
                             ("l_negative_tick.toml", "life.tick_flights")),
    "l_unknown_key.toml": (_v("[life]\n", "[life]\nwarranty = { value = 1, unit = \"1\" }\n"),
                           ("l_unknown_key.toml", "life.warranty", "unknown key")),
    "l_not_table.toml": (LIFE.split("[life]")[0] + "life = 3\n" + LIFE.split(_LAW)[1],
                         ("l_not_table.toml", "life")),
    "l_tau_zero.toml": (_law('[[life.law]]\nparameter = "k3"\nkind = "exponential"\n'
                             'amplitude = { value = -0.01, unit = "1" }\ntime_constant = { value = 0, unit = "h" }\n'),
                        ("l_tau_zero.toml", "time_constant")),
    "l_exp_blows_up.toml": (_law('[[life.law]]\nparameter = "k3"\nkind = "exponential"\n'
                                 'amplitude = { value = -0.01, unit = "1" }\n'
                                 'time_constant = { value = 20, unit = "h" }\n'),
                            ("l_exp_blows_up.toml", "life.law[0]", "k3", "outside")),
    "l_power_neg_exponent.toml": (_law('[[life.law]]\nparameter = "k3"\n'
                                       'kind = "power"\namplitude = { value = -0.1, unit = "1" }\n'
                                       'exponent = { value = -1, unit = "1" }\n'
                                       'reference = { value = 1000, unit = "h" }\n'),
                                  ("l_power_neg_exponent.toml", "exponent")),
    "l_step_negative_at.toml": (_law('[[life.law]]\nparameter = "k3"\nkind = "step"\n'
                                     'size = { value = -0.1, unit = "1" }\nat = { value = -10, unit = "h" }\n'),
                                ("l_step_negative_at.toml", "at")),
    "l_step_too_big.toml": (_law('[[life.law]]\nparameter = "k3"\nkind = "step"\nsize = { value = -1.5, unit = "1" }\n'
                                 'at = { value = 100, unit = "h" }\n'), ("l_step_too_big.toml", "size")),
    "l_constant_too_big.toml": (_law('[[life.law]]\nparameter = "k3"\nkind = "constant"\n'
                                     'value = { value = 7, unit = "1" }\n'), ("l_constant_too_big.toml", "value")),
    "l_two_laws_sum.toml": (_law('[[life.law]]\nparameter = "k3"\nkind = "constant"\n'
                                 'value = { value = -0.9, unit = "1" }\n[[life.law]]\nparameter = "k3"\n'
                                 'kind = "linear"\n'
                                 'rate = { value = -2e-4, unit = "1/h" }\n'),
                            ("l_two_laws_sum.toml", "life.law[0], life.law[1]", "k3", "outside")),
    "l_rig_dev_plus_law.toml": (_v('params = "table2"', 'params = "table2"\ndeviations = { alpha_h = 4.95 }'),
                                ("l_rig_dev_plus_law.toml", "alpha_h", "outside")),
    "l_out_of_bounds.toml": (_v("value = 2e-4", "value = 1e-3"),  # alpha_h 0.605 x 1.8 > its upper bound 1
                             ("l_out_of_bounds.toml", "life.law[0]", "visit 3", "alpha_h")),
}

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
