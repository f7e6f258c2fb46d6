"""The recipes of docs/architecture.md work as written: the effect file registers itself from its package, the link
skeleton is a complete link class reading its URL options, the study runs, the command registers and parses."""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

import numpy as np
import pytest

from board_config.errors import InputError

DOC = Path(__file__).parents[1] / "docs" / "architecture.md"


def _block(first_line: str) -> str:
    """The python block of the doc whose first line is ``first_line``."""
    for block in re.findall(r"```python\n(.*?)```", DOC.read_text(encoding="utf-8"), flags=re.S):
        if block.startswith(first_line + "\n"):
            return block
    raise AssertionError(f"docs/architecture.md lost the block starting {first_line!r}")


@pytest.fixture
def on_path(tmp_path, monkeypatch):
    monkeypatch.syspath_prepend(str(tmp_path))
    yield tmp_path
    for name in [m for m in sys.modules if m.startswith(("recipe_effects", "recipe_links", "recipe_studies"))]:
        del sys.modules[name]


def test_effect_recipe_is_one_file_registered_from_its_package(on_path):
    from plant import PlantModel
    from plant.effect import library_effects, register_effect_package, unregister_effect

    pkg = on_path / "recipe_effects"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "tip_support.py").write_text(_block("# plant/effects/tip_support.py"))
    try:
        register_effect_package("recipe_effects", library=True)
        assert "tip_support" in library_effects()
        model = PlantModel("table2", effects=["tip_support"], effect_params={"k_tip": 5.0})
        assert model.effect_names[-1] == "tip_support"
        assert model.param_value("k_tip") == 5.0
    finally:
        unregister_effect("tip_support")


def test_link_recipe_is_a_complete_link_reading_its_options(on_path):
    from drivers import Link

    pkg = on_path / "recipe_links"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "can_link.py").write_text(_block("# drivers/can_link.py"))
    from recipe_links.can_link import CanLink

    link = CanLink("can:vcan0?timeout=0.02")  # every abstract hook is implemented: it instantiates
    assert isinstance(link, Link)
    assert (link.iface, link.timeout, link.reopen_after, link.is_open) == ("vcan0", 0.02, 3, False)
    with pytest.raises(InputError, match="baud"):
        CanLink("can:vcan0?baud=9600")
    with pytest.raises(InputError, match="timeout"):
        CanLink("can:vcan0?timeout=100")


def test_study_and_command_recipes_run(on_path, capsys):
    pkg = on_path / "recipe_studies" / "step_response"
    pkg.mkdir(parents=True)
    (on_path / "recipe_studies" / "__init__.py").write_text("")
    setup_src = _block("# studies/step_response/setup.py")
    run_src = _block("# studies/step_response/run.py").replace("studies.step_response", "recipe_studies.step_response")
    (pkg / "setup.py").write_text(setup_src)
    (pkg / "run.py").write_text(run_src)
    (pkg / "__init__.py").write_text("from recipe_studies.step_response.run import run_steps\n"
                                     "from recipe_studies.step_response.setup import StepSetup\n")
    from recipe_studies.step_response import StepSetup, run_steps

    z = run_steps(StepSetup())
    assert z.shape == (2,) and 0 < z[0] < z[1]  # a larger step bends the tip further
    with pytest.raises(InputError, match="1500"):
        run_steps(StepSetup(amplitudes_v=(2000.0,)))

    cmd_src = _block("# shm_cli/step_cmd.py").replace("studies.step_response", "recipe_studies.step_response")
    namespace: dict = {}
    exec(compile(cmd_src, "step_cmd.py", "exec"), namespace)
    parser = argparse.ArgumentParser(prog="shm")
    namespace["register"](parser.add_subparsers(dest="command"))
    args = parser.parse_args(["step", "--amplitude-v", "100", "--amplitude-v", "300", "--out", str(on_path / "o")])
    assert args.func(args) == 0
    printed = np.array(capsys.readouterr().out.strip("[] \n").split(), dtype=float)
    np.testing.assert_allclose(printed, z, rtol=1e-3)  # as numpy prints it
