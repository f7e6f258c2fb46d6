"""Loading a user's effect file (issue 33): what its import does beyond defining an effect is one EffectError
naming the file — but a real Ctrl-C during the import is still the user's Ctrl-C; an own parameter's unit is an SI
unit expression."""

from __future__ import annotations

from pathlib import Path

import pytest

from plant.effect import EffectError, load_effect_file
from plant.effect_declarations import unit_problem


def test_a_real_sigint_during_the_import_stays_a_keyboard_interrupt(tmp_path: Path) -> None:
    f = tmp_path / "slow_import.py"
    f.write_text("import os, signal\nos.kill(os.getpid(), signal.SIGINT)\nimport time\ntime.sleep(5)\n")
    with pytest.raises(KeyboardInterrupt):
        load_effect_file(f)


@pytest.mark.parametrize(("source", "needle"), [
    ("raise KeyboardInterrupt\n", "raised KeyboardInterrupt"),
    ("import sys\nsys.exit(4)\n", "sys.exit(4)"),
    ("print('hi')\n", "printed to standard output while imported ('hi')"),
    ("class B(BaseException):\n    pass\nraise B()\n", "raised B while imported"),
])
def test_an_import_that_ends_or_prints_is_one_effect_error(tmp_path: Path, source: str, needle: str, capsys) -> None:
    f = tmp_path / "bad_import.py"
    f.write_text(source)
    with pytest.raises(EffectError, match=r"bad_import\.py") as info:
        load_effect_file(f)
    assert needle in str(info.value)
    assert capsys.readouterr().out == ""  # nothing reached standard output


@pytest.mark.parametrize("unit", ["1", "N*s/m", "m^-2", "C^-n", "N/(m/s)^2", "1/K", "V*s", "A/(V)^3", "ohm", "kg/m"])
def test_si_unit_expressions_are_accepted(unit: str) -> None:
    assert unit_problem(unit) is None


@pytest.mark.parametrize("unit", ["Ns/mm", "mm", "mN", "Nm", "N s", "N/", "(m", "m)", "m^", "", "newton", "N/m^xy"])
def test_unit_typos_are_refused_naming_the_unit(unit: str) -> None:
    why = unit_problem(unit)
    assert why is not None and (repr(unit) in why or "non-empty" in why)
