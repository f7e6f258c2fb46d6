"""The physical-effect seam: the docs' worked example, a user's effect by dotted path, and the errors."""

from __future__ import annotations

import re
import sys
from pathlib import Path

import numpy as np
import pytest

from plant import EffectError, Parameter, PhysicalEffect, PlantModel, resolve_effect, sine_drive, step_drive
from plant.layout import B_FM, B_Z
from plant.linear import linearise, modal_summary, static_tip_gain

DOCS = Path(__file__).parents[2] / "docs" / "effects.md"


@pytest.fixture(scope="module")
def docs_example_module(tmp_path_factory):
    """The python block of docs/effects.md, written to a module on sys.path (exactly as a user would)."""
    text = DOCS.read_text()
    block = re.search(r"```python\n# my_effects\.py\n(.*?)```", text, re.S)
    assert block, "docs/effects.md lost its worked example"
    d = tmp_path_factory.mktemp("user_effects")
    (d / "my_effects.py").write_text(block.group(1))
    sys.path.insert(0, str(d))
    yield "my_effects"
    sys.path.remove(str(d))
    sys.modules.pop("my_effects", None)


def test_docs_worked_example_loads_by_dotted_path_and_acts(docs_example_module, table2_model):
    k_tip = 5.0
    model = PlantModel("table2", effects=["my_effects:TipSupportSpring"], effect_params={"k_tip": k_tip})
    assert model.effect_names[-1] == "tip_support"
    assert "k_tip" in model.param_names
    lin = linearise(model)
    # closed form: every section carries F = k_tip z3, so z3 = 3 d κ v_a / (1 + k_tip Σ 1/k_i)
    kappa = 0.605 + (1 - 0.605) * -1.0
    flex = sum(1 / model.param_value(f"k{i}") for i in (1, 2, 3))
    assert static_tip_gain(lin) == pytest.approx(3 * 1.37e-5 * kappa / (1 + k_tip * flex), rel=1e-6)
    f_nominal = modal_summary(linearise(table2_model)).modes[0]["frequency_Hz"]
    assert modal_summary(lin).modes[0]["frequency_Hz"] > f_nominal * 1.05


def test_neutral_user_effect_equals_nominal_bit_for_bit(docs_example_module, table2_model):
    model = PlantModel("table2", effects=["my_effects:TipSupportSpring"])  # k_tip default 0
    inp = step_drive(300.0, 0.5, t_step=0.05)
    a = table2_model.simulate(inp, dt_out=1e-3)
    b = model.simulate(inp, dt_out=1e-3)
    np.testing.assert_array_equal(a.y, b.y)


def test_effect_defined_in_a_function_compiles_in_memory(table2_model):
    class Drag(PhysicalEffect):
        name = "local_drag"
        parameters = (Parameter("c_air", "N*s/m", 0.0, 0.0, 10.0, "viscous drag at the tip"),)

        @staticmethod
        def rates(t, x, p, bus, dx, so, po):
            bus[B_FM + 2] -= p[po] * bus[B_Z + 2 + 3]  # B_ZD + 2: tip velocity

    m = PlantModel("table2", effects=[Drag], effect_params={"c_air": 0.2})
    zeta_nom = modal_summary(linearise(table2_model)).modes[0]["damping_ratio"]
    assert modal_summary(linearise(m)).modes[0]["damping_ratio"] > zeta_nom


def test_effect_errors_are_named():
    with pytest.raises(EffectError, match="unknown effect 'nope'"):
        resolve_effect("nope")
    with pytest.raises(EffectError, match=r"cannot import module 'no_such_pkg\.mod'"):
        resolve_effect("no_such_pkg.mod:Thing")
    with pytest.raises(EffectError, match="has no attribute 'Nothing'"):
        resolve_effect("plant.effects.laminate:Nothing")
    with pytest.raises(EffectError, match="not a PhysicalEffect"):
        resolve_effect("numpy:ndarray")

    class NoHooks(PhysicalEffect):
        name = "no_hooks"

    with pytest.raises(EffectError, match="defines none of the hooks"):
        resolve_effect(NoHooks)

    class Clash(PhysicalEffect):
        name = "clash"
        parameters = (Parameter("k3", "N/m", 0.0),)

        @staticmethod
        def rates(t, x, p, bus, dx, so, po):
            pass

    with pytest.raises(EffectError, match=r"parameter .k3. of effect .clash. clashes"):
        PlantModel("table2", effects=[Clash])

    class Bounded(PhysicalEffect):
        name = "bounded"
        parameters = (Parameter("g", "1", 0.0, 0.0, 1.0),)

        @staticmethod
        def rates(t, x, p, bus, dx, so, po):
            pass

    with pytest.raises(EffectError, match=r"'g' = 2\.0 1 outside its bounds \[0, 1\]"):
        PlantModel("table2", effects=[Bounded], effect_params={"g": 2.0})
    with pytest.raises(EffectError, match="which no effect of the model declares"):
        PlantModel("table2", effect_params={"nothing": 1.0})
    with pytest.raises(EffectError, match="is a terminal"):
        PlantModel("table2", effects=["open_circuit"])


def test_hook_that_numba_cannot_compile_names_the_effect():
    class Broken(PhysicalEffect):
        name = "broken"

        @staticmethod
        def rates(t, x, p, bus, dx, so, po):
            bus[0] += {"a": object()}["a"]  # not compilable

    with pytest.raises(EffectError, match=r"effect .broken..*hook .rates. does not compile"):
        PlantModel("table2", effects=[Broken]).simulate(sine_drive(1.0, 1.0, 0.1))
