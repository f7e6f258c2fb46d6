"""The bad-input corpus of the newer workbench commands and effect files (issue 33): what a careless or unlucky user
gives ``shm discover``, ``fit``, ``synth``, ``compare``, ``diagnose`` and ``hil serve --effect``. Used by
``tests/shm_cli/test_bad_inputs_newer_workbench.py``.

Cases are :class:`bad_inputs_corpus.Case` (``{d}`` the corpus directory, ``{o}`` the case's own output directory,
``{shipped}`` the shipped configuration); the files are written by :func:`write_newer_files`. Every case ends during
validation with exit 2 and one ``error:`` line naming the file, option or key and the reason; none may change a file
that was there before it ran.
"""

from __future__ import annotations

import os
from pathlib import Path

from bad_inputs_corpus import Case, _record, _rows, case, case_table, unique_ids

# ------------------------------------------------------------------------------------------------------------
# effect files
_HEAD = "import math\nfrom plant.effect import Parameter, PhysicalEffect\nfrom plant.layout import B_FM, B_ZD\n\n"
_DAMPING = 'Parameter("c_x", "N*s/m", 0.01, 0.0, 1.0, "extra tip damping")'
_RATES = ("    @staticmethod\n    def rates(t, x, p, bus, dx, so, po):\n"
          "        bus[B_FM + 2] -= p[po] * bus[B_ZD + 2]\n")


def _effect(name: str, params: str = _DAMPING, *, before: str = "", body: str = _RATES, base: str = "PhysicalEffect",
            cls: str = "Extra", extra: str = "") -> str:
    """An effect file: the header, ``before`` (module code at import), one class, ``extra`` (more module code)."""
    return (f"{_HEAD}{before}class {cls}({base}):\n    name = {name!r}\n    parameters = ({params},)\n\n{body}"
            f"{extra}")


def _param(unit: str = "N*s/m", default: str = "0.01", lower: str = "0.0", upper: str = "1.0", **kw: str) -> str:
    more = "".join(f", {k}={v}" for k, v in kw.items())
    return f'Parameter("c_x", {unit!r}, {default}, {lower}, {upper}, "extra tip damping"{more})'


_GUESS_NAN = ("    @classmethod\n    def guess(cls, data=None):\n        return {'c_x': math.nan}\n\n" + _RATES)
_NAN_RATES = ("    @staticmethod\n    def rates(t, x, p, bus, dx, so, po):\n"
              "        bus[B_FM + 2] -= p[po] * math.sqrt(-1.0 - abs(bus[B_ZD + 2]))\n")
_BAD_ARITY = "    @staticmethod\n    def rates(t, x, p):\n        pass\n"

#: effect files: name -> (content, needles of the error)
EFFECTS: dict[str, tuple[str, tuple[str, ...]]] = {
    "e_syntax.py": (_effect("e_syntax").replace("class Extra(", "class Extra(("), ("e_syntax.py", "syntaxerror")),
    "e_no_class.py": (_HEAD + "X = 1\n", ("e_no_class.py", "exactly one physicaleffect", "found: none")),
    "e_two_classes.py": (_effect("e_two_a") + "\n\n" + _effect("e_two_b", cls="Other").replace(_HEAD, ""),
                         ("e_two_classes.py", "exactly one", "Extra, Other")),
    "e_wrong_base.py": (_effect("e_wrong_base", base="object"), ("e_wrong_base.py", "exactly one physicaleffect")),
    "e_sys_exit.py": ("import sys\nsys.exit()\n" + _effect("e_sys_exit"), ("e_sys_exit.py", "sys.exit()")),
    "e_sys_exit_3.py": (_effect("e_sys_exit_3", before="import sys\nsys.exit(3)\n"),
                        ("e_sys_exit_3.py", "sys.exit(3)")),
    "e_raise_exit.py": ("raise SystemExit('bye')\n", ("e_raise_exit.py", "sys.exit('bye')")),
    "e_keyboard.py": ("raise KeyboardInterrupt\n", ("e_keyboard.py", "keyboardinterrupt")),
    "e_base_exception.py": ("class Stop(BaseException):\n    pass\n\nraise Stop('stop here')\n",
                            ("e_base_exception.py", "raised stop", "stop here")),
    "e_prints.py": (_effect("e_prints", before="print('loading my effect')\n"),
                    ("e_prints.py", "printed to standard output", "loading my effect")),
    "e_import_error.py": ("import no_such_module_xyz\n" + _effect("e_import_error"),
                          ("e_import_error.py", "no_such_module_xyz")),
    "e_raises.py": (_effect("e_raises", before="raise RuntimeError('half written')\n"),
                    ("e_raises.py", "runtimeerror", "half written")),
    "e_nan_default.py": (_effect("e_nan_default", _param(default="math.nan")), ("e_nan_default", "c_x", "finite")),
    "e_inf_default.py": (_effect("e_inf_default", _param(default="math.inf", upper="math.inf")),
                         ("e_inf_default", "c_x", "finite")),
    "e_nan_lower.py": (_effect("e_nan_lower", _param(lower="math.nan")), ("e_nan_lower", "c_x", "nan", "bounds")),
    "e_nan_upper.py": (_effect("e_nan_upper", _param(upper="math.nan")), ("e_nan_upper", "c_x", "nan", "bounds")),
    "e_bounds_order.py": (_effect("e_bounds_order", _param(default="0.5", lower="1.0", upper="0.0")),
                          ("e_bounds_order", "c_x", "lower < upper")),
    "e_default_out.py": (_effect("e_default_out", _param(default="5.0")), ("e_default_out", "c_x", "outside")),
    "e_neutral_nan.py": (_effect("e_neutral_nan", _param(neutral="math.nan")), ("e_neutral_nan", "c_x", "neutral")),
    "e_neutral_out.py": (_effect("e_neutral_out", _param(neutral="7.0")), ("e_neutral_out", "c_x", "neutral")),
    "e_unit_typo.py": (_effect("e_unit_typo", _param(unit="Ns/mm")), ("e_unit_typo", "c_x", "Ns/mm", "si unit")),
    "e_unit_prefixed.py": (_effect("e_unit_prefixed", _param(unit="mN")), ("e_unit_prefixed", "c_x", "'mN'", "si")),
    "e_unit_word.py": (_effect("e_unit_word", _param(unit="newton seconds per metre")),
                       ("e_unit_word", "c_x", "newton", "si unit")),
    "e_unit_empty.py": (_effect("e_unit_empty", _param(unit="")), ("e_unit_empty", "c_x", "unit")),
    "e_dup_param.py": (_effect("e_dup_param", _DAMPING + ", " + _DAMPING), ("e_dup_param", "c_x", "twice")),
    "e_no_hooks.py": (_effect("e_no_hooks", body="    pass\n"), ("e_no_hooks", "none of the hooks")),
    "e_bad_arity.py": (_effect("e_bad_arity", body=_BAD_ARITY), ("e_bad_arity", "rates", "arguments")),
    "e_bad_name.py": (_effect("not an identifier"), ("e_bad_name", "'name' must be a python identifier")),
    "e_no_params.py": (_effect("e_no_params", "").replace("parameters = (,)", "parameters = ()"),
                       ("e_no_params", "no parameters of its own")),
    "e_dup_a.py": (_effect("same_name"), ()),
    "e_dup_b.py": (_effect("same_name", cls="Another"), ("same_name", "share the name")),
    "e_nan_guess.py": (_effect("e_nan_guess", body=_GUESS_NAN), ("e_nan_guess", "guess()", "c_x", "finite")),
    "e_nan_sim.py": (_effect("e_nan_sim", body=_NAN_RATES), ("e_nan_sim.py", "nan", "probe simulation")),
    "effect.txt": (_effect("e_txt"), ("effect.txt", "python")),
    "e_binary.py": ("\x00\x01\x02 not python at all \x00", ("e_binary.py", "null bytes")),
}


def write_newer_files(d: Path) -> None:
    """Write every file the cases use into ``d``: the effect files, records, a finished run of each kind, files an
    output could clobber and a directory named like an effect file."""
    d.mkdir(parents=True, exist_ok=True)
    for name, (content, _) in EFFECTS.items():
        (d / name).write_text(content, encoding="utf-8")
    good = _record(_rows(400))
    (d / "good.csv").write_text(good)
    (d / "good_copy.csv").write_text(good)
    (d / "victim.py").write_text("# an unrelated module the user keeps here\nANSWER = 42\n")
    (d / "myscen.toml").write_text('[scenario]\nname = "mine"\n')
    (d / "dir_effect.py").mkdir(exist_ok=True)
    if not (d / "dangling.py").is_symlink():
        os.symlink(d / "no_such_target.py", d / "dangling.py")
    for folder, markers in {"run_done": ("summary.json", "usage.db", "report.html"),
                            "diagnose_done": ("diagnosis.json", "diagnosis.html"),
                            "health_done": ("health.json", "report.html"),
                            "fit_done": ("fit.json", "fit.html")}.items():
        (d / folder).mkdir(exist_ok=True)
        for m in markers:
            (d / folder / m).write_text(f"{folder}/{m}: a finished run's file\n")
    (d / "busy").mkdir(exist_ok=True)  # the test holds its --out lock


def _effect_cases() -> list[Case]:
    c = case
    fit = "fit {d}/good.csv --add {d}/%s --save {o}/x.toml"
    synth = "synth --test step --effect {d}/%s --out {o}/x.csv"
    compare = "compare {d}/good.csv --add {d}/%s --out {o}"
    discover = "discover {d}/good.csv --add {d}/%s --out {o}"
    hil = "hil serve --serial pty --duration 0.2 --effect {d}/%s"
    where = {
        "e_syntax.py": (fit, synth), "e_no_class.py": (fit, compare), "e_two_classes.py": (synth,),
        "e_wrong_base.py": (discover,), "e_sys_exit.py": (fit, synth, compare, discover, hil),
        "e_sys_exit_3.py": (fit, hil), "e_raise_exit.py": (synth, compare), "e_keyboard.py": (fit, synth),
        "e_base_exception.py": (compare, hil), "e_prints.py": (fit, synth, hil), "e_import_error.py": (compare,),
        "e_raises.py": (fit,), "e_nan_default.py": (fit, synth), "e_inf_default.py": (compare,),
        "e_nan_lower.py": (fit, hil), "e_nan_upper.py": (synth,), "e_bounds_order.py": (fit,),
        "e_default_out.py": (discover,), "e_neutral_nan.py": (fit,), "e_neutral_out.py": (synth,),
        "e_unit_typo.py": (fit, synth, compare, hil), "e_unit_prefixed.py": (discover,),
        "e_unit_word.py": (fit,), "e_unit_empty.py": (synth,), "e_dup_param.py": (compare,),
        "e_no_hooks.py": (fit,), "e_bad_arity.py": (synth,), "e_bad_name.py": (fit,), "e_no_params.py": (fit,),
        "e_nan_sim.py": (synth, hil), "effect.txt": (fit, synth),
        "e_binary.py": (fit, synth),
    }
    cases = []
    for name, commands in where.items():
        for cmd in commands:
            word = cmd.split()[0] if cmd is not hil else "hil"
            cases.append(c(f"{word}-effect-{name}", cmd % name, *EFFECTS[name][1]))
    cases += [
        c("fit-effect-duplicate-name", "fit {d}/good.csv --add {d}/e_dup_a.py --add {d}/e_dup_b.py --save {o}/x.toml",
          *EFFECTS["e_dup_b.py"][1]),
        c("synth-effect-duplicate-name", "synth --test step --effect {d}/e_dup_a.py --effect {d}/e_dup_b.py "
          "--out {o}/x.csv", *EFFECTS["e_dup_b.py"][1]),
        c("fit-effect-directory", "fit {d}/good.csv --add {d}/dir_effect.py --save {o}/x.toml", "dir_effect.py",
          "not a file"),
        c("compare-effect-directory", "compare {d}/good.csv --add {d}/dir_effect.py --out {o}", "dir_effect.py"),
        c("synth-effect-dangling", "synth --test step --effect {d}/dangling.py --out {o}/x.csv", "dangling.py",
          "does not exist"),
        c("fit-effect-missing", "fit {d}/good.csv --add {d}/nope_effect.py --save {o}/x.toml", "nope_effect.py",
          "does not exist"),
        c("fit-effect-class-missing", "fit {d}/good.csv --add {d}/e_dup_a.py:NoSuch --save {o}/x.toml",
          "e_dup_a.py", "nosuch"),
        c("diagnose-candidate-sys-exit", "diagnose {d}/good.csv --candidates {d}/e_sys_exit.py --out {o}",
          "e_sys_exit.py", "sys.exit()"),
        c("diagnose-candidate-unit-typo", "diagnose {d}/good.csv --candidates {d}/e_unit_typo.py --out {o}",
          "e_unit_typo", "Ns/mm"),
    ]
    return cases


def _option_cases() -> list[Case]:
    return case_table("workbench_options.txt")


#: cases that compile a kernel of their own (tens of seconds on a cold cache): run with the slow tests
SLOW_CASES = (case("fit-effect-e_nan_guess.py", "fit {d}/good.csv --add {d}/e_nan_guess.py --save {o}/x.toml",
                   *EFFECTS["e_nan_guess.py"][1]),)


def all_newer_cases() -> list[Case]:
    return unique_ids(_effect_cases() + _option_cases() + list(SLOW_CASES))
