"""The effect seam by name (issue 13 point 6): slot tables instead of offset arithmetic, signals the composer
allocates, instances with a prefix, the library taken from the registry (a new library effect is one file), a
kernel cache key that covers the modules an effect imports, and the older offsets seam still working."""

from __future__ import annotations

import importlib
import importlib.util
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from plant import EffectError, PlantModel, step_drive
from plant import layout as L
from plant.composition import build_composition
from plant.effect import library_effects, register_effect_package, registered_effects, resolve_effect, unregister_effect

STEP = step_drive(300.0, 0.4, t_step=0.05, dt=1e-3)

USER_EFFECTS = '''
from plant import OutputSpec, Parameter, PhysicalEffect, SignalSpec, StateSpec
from plant.layout import B_USER


class TipSpringNamed(PhysicalEffect):
    name = "tip_spring_named"
    parameters = (Parameter("k_tip", "N/m", 0.0, 0.0, 1e4, "tip-to-frame stiffness"),)

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        bus[B.fm3] -= p[P.k_tip] * bus[B.z3]


class SpringForce(PhysicalEffect):
    """Publishes the spring force as a signal; another effect applies it."""

    name = "spring_force"
    parameters = (Parameter("k_sig", "N/m", 0.0, 0.0, 1e4, "stiffness"),)
    signals = (SignalSpec("f_spring", "N", "spring force on the tip"),)

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        bus[B.f_spring] = -p[P.k_sig] * bus[B.z3]


class ApplyForce(PhysicalEffect):
    name = "apply_force"
    reads = ("f_spring",)

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        bus[B.fm3] += bus[B.f_spring]


class ByHand(PhysicalEffect):
    """Writes B_USER by hand (the old way to add a signal)."""

    name = "by_hand"

    @staticmethod
    def pre(t, x, p, bus, dx, so, po):
        bus[B_USER] = 1.0


class ManySignals(PhysicalEffect):
    name = "many_signals"
    signals = tuple(SignalSpec(f"s_{k}", "1") for k in range(17))

    @staticmethod
    def pre(t, x, p, bus, dx, X, P, B):
        pass


class Stateful(PhysicalEffect):
    """A first-order lag of z3 with its own state and output."""

    name = "stateful"
    parameters = (Parameter("tau_lag", "s", 0.01, 1e-4, 1.0, "lag"),)
    states = (StateSpec("z_lag", "m", 1e-3),)
    outputs = (OutputSpec("z3_lagged", "m"),)

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        dx[X.z_lag] += (bus[B.z3] - x[X.z_lag]) / p[P.tau_lag]

    @staticmethod
    def output(t, x, p, bus, y, X, P, B, Y):
        y[Y.z3_lagged] = x[X.z_lag]
'''


@pytest.fixture(scope="module")
def user_module(tmp_path_factory):
    d = tmp_path_factory.mktemp("slot_effects")
    (d / "slot_user_effects.py").write_text(USER_EFFECTS)
    sys.path.insert(0, str(d))
    yield "slot_user_effects"
    sys.path.remove(str(d))
    sys.modules.pop("slot_user_effects", None)


def test_named_and_offsets_hooks_give_the_same_model(user_module):
    named = PlantModel("table2", effects=[f"{user_module}:TipSpringNamed"], effect_params={"k_tip": 4.0})
    # the same spring against the seam before the slot tables (offset arithmetic)
    old = PlantModel("table2", effects=["tip_effects_support:TipSpring"], effect_params={"k_tip": 4.0})
    a = named.simulate(STEP, dt_out=1e-3)
    b = old.simulate(STEP, dt_out=1e-3)
    np.testing.assert_array_equal(a.y, b.y)
    assert a["z3"][0, -1] < PlantModel("table2").simulate(STEP, dt_out=1e-3)["z3"][0, -1]


def test_signals_are_allocated_from_b_user_and_read_by_name(user_module):
    pub, use = f"{user_module}:SpringForce", f"{user_module}:ApplyForce"
    model = PlantModel("table2", effects=[pub, use], effect_params={"k_sig": 4.0})
    assert model.composition.signals == {"f_spring": L.B_USER}
    res = model.simulate(STEP, dt_out=1e-3, record_bus=True)
    ref = PlantModel("table2", effects=[f"{user_module}:TipSpringNamed"], effect_params={"k_tip": 4.0})
    np.testing.assert_allclose(res.y, ref.simulate(STEP, dt_out=1e-3).y, rtol=0, atol=1e-15)
    np.testing.assert_allclose(res["f_spring"][0], -4.0 * res["z3"][0], rtol=1e-12, atol=1e-18)


def test_signal_errors_name_the_effects(user_module):
    with pytest.raises(EffectError, match=r"reads signal 'f_spring', which no effect of the model publishes"):
        build_composition([resolve_effect(f"{user_module}:ApplyForce")])
    with pytest.raises(EffectError, match=r"publish 17 bus signals \(many_signals: s_0, .*16 slots"):
        build_composition([resolve_effect(f"{user_module}:ManySignals")])
    with pytest.raises(EffectError, match=r"by_hand write bus slots from B_USER by hand.*spring_force"):
        build_composition([resolve_effect(f"{user_module}:ByHand"), resolve_effect(f"{user_module}:SpringForce")])
    # alone, an effect that writes B_USER by hand keeps working as before
    build_composition([resolve_effect(f"{user_module}:ByHand")])


def test_hook_of_the_wrong_arity_says_what_to_write():
    from plant import PhysicalEffect

    class Odd(PhysicalEffect):
        name = "odd"

        @staticmethod
        def rates(t, x, p, bus):
            pass

    with pytest.raises(EffectError, match=r"rates\(t, x, p, bus, dx, X, P, B\).*rates\(t, x, p, bus, dx, so, po\)"):
        resolve_effect(Odd)


def test_own_states_outputs_by_name(user_module):
    model = PlantModel("table2", effects=[f"{user_module}:Stateful"])
    res = model.simulate(STEP, dt_out=1e-3, record_states=True)
    np.testing.assert_array_equal(res["z3_lagged"][0], res["z_lag"][0])
    z3, lag = res["z3"][0], res["z3_lagged"][0]
    # a first-order lag (10 ms) of z3: its rate is (z3 - lag)/tau, and it passes the mean of the ringing
    rate = np.gradient(lag, res.t)
    assert np.max(np.abs(rate[100:] - (z3[100:] - lag[100:]) / 0.01)) < 0.05 * np.max(np.abs(rate))
    assert np.mean(lag[-100:]) == pytest.approx(np.mean(z3[-100:]), rel=0.05)


def test_two_instances_of_one_effect_coexist_and_round_trip_a_parameter_file(user_module, tmp_path):
    from board_config import load_parameter_set
    from workbench.fit._parameter_set import fitted_parameter_set

    spec = f"{user_module}:TipSpringNamed"
    model = PlantModel("table2", effects=[spec, f"{spec} as tip_spring_2"],
                       effect_params={"k_tip": 1.5, "tip_spring_2.k_tip": 2.5})
    assert model.effect_names[-2:] == ("tip_spring_named", "tip_spring_2")
    assert model.param_names[-2:] == ("k_tip", "tip_spring_2.k_tip")
    one = PlantModel("table2", effects=[spec], effect_params={"k_tip": 4.0})
    np.testing.assert_allclose(model.simulate(STEP, dt_out=1e-3).y, one.simulate(STEP, dt_out=1e-3).y,
                               rtol=1e-9, atol=1e-15)
    # the fit's parameter file names the instance and its parameters, and loads back to the same model
    saved = fitted_parameter_set(model.params, model, {"tip_spring_2.k_tip": 3.0}, "two_springs")
    path = tmp_path / "two_springs.toml"
    path.write_text(saved.to_toml())
    assert f'name = "{spec} as tip_spring_2"' in path.read_text()
    again = PlantModel(load_parameter_set(path))
    assert again.param_names == model.param_names
    assert again.param_value("tip_spring_2.k_tip") == 3.0 and again.param_value("k_tip") == 1.5


def test_instance_prefix_renames_library_declarations():
    creep = resolve_effect("piezo_creep as creep_b")
    assert creep.name == "creep_b" and creep.instance_of is registered_effects()["piezo_creep"]
    assert [p.name for p in creep.own_parameters()] == ["creep_b.gamma_creep", "creep_b.tau_creep"]
    assert creep.states[0].name == "creep_b.w_creep11"
    assert creep.default_fit_names() == ("creep_b.gamma_creep", "creep_b.tau_creep")
    assert creep.neutral_values() == {"creep_b.gamma_creep": 0.0}
    assert creep.challenge_strengths()[2] == {"creep_b.gamma_creep": 0.1, "creep_b.tau_creep": 2.0}
    assert set(creep.guess(None)) == {"creep_b.gamma_creep", "creep_b.tau_creep"}
    assert resolve_effect("piezo_creep as creep_b") is creep
    with pytest.raises(EffectError, match="identifier"):
        registered_effects()["piezo_creep"].instance("no good")


def test_kernel_cache_key_covers_the_modules_an_effect_imports(tmp_path):
    from plant.compose import _source_fingerprint

    pkg = tmp_path / "fp_pkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "constants.py").write_text("GAIN = 1.0\n")
    (pkg / "spring.py").write_text(textwrap.dedent('''
        from plant import Parameter, PhysicalEffect
        from fp_pkg.constants import GAIN


        class FpSpring(PhysicalEffect):
            name = "fp_spring"
            parameters = (Parameter("k_fp", "N/m", 0.0, 0.0, 50.0, "stiffness"),)

            @staticmethod
            def rates(t, x, p, bus, dx, X, P, B):
                bus[B.fm3] -= GAIN * p[P.k_fp] * bus[B.z3]
    '''))
    sys.path.insert(0, str(tmp_path))
    try:
        cls = resolve_effect("fp_pkg.spring:FpSpring")
        before = _source_fingerprint(cls)
        (pkg / "constants.py").write_text("GAIN = 2.0\n")
        importlib.reload(sys.modules["fp_pkg.constants"])
        assert _source_fingerprint(cls) != before
    finally:
        sys.path.remove(str(tmp_path))
        for m in ("fp_pkg", "fp_pkg.constants", "fp_pkg.spring"):
            sys.modules.pop(m, None)


NEW_LIBRARY_EFFECT = '''
"""A spring from the tip to the rig frame (a test's one-file library effect)."""

from plant import Parameter, PhysicalEffect
from plant.effects.library_support import FitRange


class TipFrameSpring(PhysicalEffect):
    """F_m3 += -k z3: the laser target or a cable ties the tip to the frame."""

    name = "tip_frame_spring"
    description = "Spring from the tip to the frame: F_m3 += -k_frame z3"
    origin = ("A cable, the laser target or a fixture touching the laminate tip ties it elastically to the rig frame, "
              "stiffening the tip section.")
    signature = ("Static tip gain lower than modelled and the first resonance higher; the residual is in phase with "
                 "the tip deflection and opposite in sign, with no amplitude or rate dependence.")
    parameters = (Parameter("k_frame", "N/m", 0.0, 0.0, 100.0, "tip-to-frame stiffness", neutral=0.0,
                            fit=FitRange(0.0, 50.0, linthresh=0.1), challenge=(0.5, 2.0, 8.0)),)

    @classmethod
    def guess(cls, data=None):
        return {"k_frame": 1.0}

    @staticmethod
    def rates(t, x, p, bus, dx, X, P, B):
        bus[B.fm3] -= p[P.k_frame] * bus[B.z3]
'''


@pytest.fixture
def one_new_library_file(tmp_path):
    """One new file in the library package plant/effects (its directory added to the package's path, as if the
    file were copied there), registered the way plant/effects registers its files; cleaned up afterwards."""
    import plant.effects

    (tmp_path / "tip_frame_spring.py").write_text(NEW_LIBRARY_EFFECT)
    plant.effects.__path__.append(str(tmp_path))
    try:
        register_effect_package("plant.effects", library=True)
        yield "tip_frame_spring"
    finally:
        plant.effects.__path__.remove(str(tmp_path))
        unregister_effect("tip_frame_spring")
        sys.modules.pop("plant.effects.tip_frame_spring", None)


def test_a_new_library_effect_is_one_file(one_new_library_file, table2_model):
    name = one_new_library_file
    from workbench.challenges.hidden_effect import STRENGTHS, cases_of, format_confusion, run_hidden_case  # noqa: F401
    from workbench.fit import LIBRARY

    # the library, the diagnose candidates and the challenge take it from the registry
    assert library_effects()[-1] == name and name in LIBRARY
    assert library_effects()[:8] == ("piezo_creep", "geometric_stiffening", "air_damping", "dielectric_leakage",
                                     "amplifier_current_limit", "laser_sensor", "root_compliance", "thermal_drift")
    assert STRENGTHS[name][2] == {"k_frame": 8.0}
    cases = [c for c in cases_of("library") if c.label == name]
    assert [c.strength for c in cases] == ["weak", "medium", "strong"] and cases[0].expected == (name,)
    # the library tests' parametrisation, collected afresh (a new copy of the module, as a new pytest run would
    # import it), holds it, and their checks pass
    path = Path(__file__).with_name("test_effects_library.py")
    spec = importlib.util.spec_from_file_location("_fresh_test_effects_library", path)
    assert spec is not None and spec.loader is not None
    lib_tests = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(lib_tests)
    assert name in lib_tests.LIBRARY
    lib_tests.test_library_is_registered_and_documented(name)
    model = PlantModel("table2", effects=[name])
    lib_tests.test_compiles_and_is_neutral(name, {name: model}, table2_model)
    stiff = model.simulate(lib_tests.STEP, dt_out=1e-3, params=model.param_batch(k_frame=8.0))
    assert stiff["z3"][0, -1] < 0.99 * table2_model.simulate(lib_tests.STEP, dt_out=1e-3)["z3"][0, -1]


def test_library_files_register_themselves():
    # every file of plant/effects with an effect class is registered; the eight of role "effect" are the library
    here = Path(__file__).parents[2] / "plant" / "effects"
    reg = registered_effects()
    for cls in reg.values():
        if cls.__module__.startswith("plant.effects."):
            assert (here / (cls.__module__.rsplit(".", 1)[1] + ".py")).exists()
    assert {n for n, c in reg.items() if c.role == "effect" and c.__module__.startswith("plant.effects.")} == set(
        library_effects())
