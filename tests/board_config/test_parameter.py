"""The one parameter type (board_config.parameter): bounds, fit ranges, the core schema that drives the plant's
layout and core effects, and the one place a relative deviation is validated (ParameterVector.with_deviations)."""

from __future__ import annotations

import math

import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from board_config import (
    CORE_INDEX,
    CORE_PARAMETER_NAMES,
    CORE_PARAMETERS,
    CORE_SCHEMA,
    DEVIATION_RANGE,
    ConfigError,
    FitRange,
    InputError,
    Parameter,
    ParameterError,
    ParameterVector,
    deviation_problem,
    load_parameter_set,
)
from board_config.parameter import freed


def test_the_core_schema_is_the_one_declaration_of_names_units_bounds_and_indices():
    import plant.effects  # noqa: F401  (registers the core effects)
    import plant.layout as L
    from plant.effect import registered_effects

    assert CORE_PARAMETER_NAMES == tuple(p.name for p in CORE_PARAMETERS) and len(CORE_PARAMETERS) == 17
    assert [p.core_index for p in CORE_PARAMETERS] == list(range(17)) == [CORE_INDEX[n] for n in CORE_PARAMETER_NAMES]
    assert (L.P_R_EP, L.P_C_EP, L.P_D_EP, L.P_M, L.P_K, L.P_C) == (0, 1, 2, 3, 6, 9)
    assert (L.P_ALPHA_H, L.P_A_H, L.P_N_H, L.P_BETA_H, L.P_GAMMA_H, L.N_CORE_PARAMS) == (12, 13, 14, 15, 16, 17)
    assert all(type(getattr(L, n)) is int for n in dir(L) if n.startswith("P_"))  # numba folds plain ints
    # the core effects declare exactly the schema's objects, each core parameter once
    core = [p for c in registered_effects().values() if c.role == "core" for p in c.parameters]
    assert sorted(p.name for p in core) == sorted(CORE_PARAMETER_NAMES)
    assert all(p is CORE_SCHEMA[p.name] for p in core)
    # values come from the parameter set, checked against the schema's units and bounds
    assert all(math.isnan(p.default) for p in CORE_PARAMETERS)
    assert load_parameter_set("table2")["k3"] == 21.28
    assert CORE_SCHEMA["k3"].unit == "N/m" and CORE_SCHEMA["k3"].describe_range() == "(0, +inf)"
    assert CORE_SCHEMA["alpha_h"].describe_range() == "[0, 1]"


def test_parameter_bounds_open_and_closed():
    k = Parameter("k", "N/m", 2.0, 0.0, 10.0, lower_open=True)
    assert k.value == 2.0 and k.check(10, "here") == 10.0
    with pytest.raises(ParameterError, match=r"here: parameter 'k' = 0\.0 N/m outside its bounds \(0, 10\] N/m"):
        k.check(0.0, "here")
    with pytest.raises(ParameterError, match="must be finite"):
        k.check(math.nan, "here")
    assert not k.in_bounds(math.inf) and k.in_bounds(1e-300)
    assert k.quantity.lower == 0.0 and k.quantity.lower_open and k.quantity.upper == 10.0
    assert Parameter("a", "1").quantity.lower is None  # unbounded stays unbounded in a TOML schema


def test_the_plant_parameter_is_the_one_type_and_keeps_its_keywords():
    from plant.effect import EffectError
    from plant.effect import Parameter as EffectParameter

    p = EffectParameter(name="g", unit="1", default=0.5, lower=0.0, upper=1.0, description="gain", core_index=None)
    assert isinstance(p, Parameter) and p.description == "gain"
    with pytest.raises(EffectError, match=r"'g' = 2\.0 1 outside its bounds \[0, 1\]"):
        p.check(2.0, "effect 'x'")
    freed_p = p.free()
    assert isinstance(freed_p, EffectParameter) and freed_p.vary and (freed_p.lower, freed_p.upper) == (0.0, 1.0)


def test_free_uses_the_declared_range_else_one_from_the_bounds():
    declared = Parameter("tau", "s", 0.1, 0.0, math.inf, fit=FitRange(0.03, 100.0, log=True), neutral=0.0)
    f = declared.free(owner="creep")
    assert f.vary and f.owner == "creep" and (f.lower, f.upper, f.log) == (0.03, 100.0, True)
    assert f.describe() == "tau in [0.03, 100] s (log)"
    assert f.free(0.01, 10.0).log  # a new interval keeps the declared scaling
    auto = Parameter("c", "N*s/m", 0.0, 0.0, math.inf).free()
    assert (auto.lower, auto.upper, auto.log) == (0.0, 10.0, False)
    wide = Parameter("g", "S", 1e-6, 1e-9, 1e-3).free()
    assert wide.log and wide.fit == FitRange(1e-9, 1e-3, True)
    with pytest.raises(ParameterError, match=r"parameter 'g' \(S\): .*lower < upper"):
        wide.free(2.0, 1.0)
    with pytest.raises(ParameterError, match="no fit range"):
        Parameter("x", "1").to_unit(0.0)
    with pytest.raises(InputError, match="positive lower bound"):
        FitRange(-1.0, 1.0, log=True)
    with pytest.raises(InputError, match="linthresh > 0"):
        FitRange(-1.0, 1.0, linthresh=0.0)


def test_library_support_fit_range_is_the_same_type():
    from plant.effects.library_support import FitRange as LibraryFitRange

    assert LibraryFitRange is FitRange


def _vector() -> ParameterVector:
    return load_parameter_set("table2").core_vector()


def test_with_deviations_applies_truth_equals_nominal_times_one_plus_d():
    v = _vector()
    d = v.with_deviations({"k3": -0.3, "alpha_h": 0.2}, "test")
    assert d["k3"] == pytest.approx(21.28 * 0.7) and d["alpha_h"] == pytest.approx(0.605 * 1.2)
    assert d["k1"] == v["k1"] and v["k3"] == 21.28  # a copy; the nominal is unchanged
    assert d.names == CORE_PARAMETER_NAMES and list(d.array()) == list(d.values)


@pytest.mark.parametrize(("deviations", "needles"), [
    ({"k9": 0.1}, ["scenario.toml: rig.deviations", "no such model parameter 'k9'", "k3"]),
    ({"k3": -1.0}, ["scenario.toml: rig.deviations", "'k3'", "outside the allowed range [-0.95, 5]", "× 0"]),
    ({"k3": 5.5}, ["'k3'", "outside the allowed range"]),
    ({"k3": math.nan}, ["'k3'", "nan"]),
    ({"k3": "lots"}, ["'k3'", "must be a number"]),
    ({"alpha_h": 1.0}, ["gives alpha_h = 1.21", "outside its bounds [0, 1]"]),
])
def test_a_bad_deviation_names_the_parameter_and_where_it_came_from(deviations, needles):
    with pytest.raises(ParameterError) as exc:
        _vector().with_deviations(deviations, "scenario.toml: rig.deviations")
    assert isinstance(exc.value, InputError)
    for n in needles:
        assert n in str(exc.value), (n, str(exc.value))
    assert exc.value.where == "scenario.toml: rig.deviations" and exc.value.name == next(iter(deviations))


def test_every_deviation_site_uses_the_one_rule():
    """Scenario files, --deviation of shm hil (TruthChanges) and the rig refuse the same deviation."""
    from board_config.scenario import load_scenario, parse_scenario, read_toml
    from hil_stub.faults import TruthChanges

    lo, hi = DEVIATION_RANGE
    assert deviation_problem("k3", lo) is None and deviation_problem("k3", hi) is None
    bad = hi + 0.5
    assert "outside the allowed range" in (deviation_problem("k3", bad) or "")
    data = read_toml(load_scenario("faults").source)
    data["rig"]["deviations"] = {"k3": bad}
    with pytest.raises(ConfigError, match=r"rig\.deviations\.k3.*outside the allowed range"):
        parse_scenario(data, "bad.toml")
    with pytest.raises(ParameterError, match=r"--deviation k3=5\.5: .*outside the allowed range"):
        TruthChanges(deviations={"k3": bad})


def test_free_of_a_vector_starts_at_its_current_values():
    v = _vector().with_deviations({"k3": 0.5}, "test")
    (k3,) = v.free("k3", ranges={"k3": FitRange(10.0, 40.0)})
    assert k3.value == pytest.approx(31.92) and (k3.lower, k3.upper) == (10.0, 40.0) and k3.vary
    with pytest.raises(ParameterError, match="no such model parameter 'k99'"):
        v.free("k99")


@settings(max_examples=200, deadline=None)
@given(name=st.sampled_from(CORE_PARAMETER_NAMES),
       d=st.floats(DEVIATION_RANGE[0], DEVIATION_RANGE[1], allow_nan=False))
def test_deviation_round_trip_and_bounds(name, d):
    """Either the deviated value is inside the parameter's bounds and the deviation comes back from it, or the
    vector refuses it naming the parameter; nothing else changes."""
    v = _vector()
    nominal = v[name]
    par = CORE_SCHEMA[name]
    try:
        dev = v.with_deviations({name: d}, "prop")
    except ParameterError as exc:
        assert not par.in_bounds(nominal * (1.0 + d)) and name in str(exc) and "prop" in str(exc)
        return
    assert par.in_bounds(dev[name])
    assert dev[name] == nominal * (1.0 + d)
    if nominal != 0.0:
        assert dev[name] / nominal - 1.0 == pytest.approx(d, abs=1e-12)
    assert all(dev[n] == v[n] for n in CORE_PARAMETER_NAMES if n != name)


@settings(max_examples=200, deadline=None)
@given(lo=st.floats(-1e6, 1e6), width=st.floats(1e-6, 1e6), x=st.floats(-2e6, 2e6),
       mode=st.sampled_from(["lin", "log", "symlog"]))
@example(lo=0.5, width=1e-6, x=1.0, mode="log")  # log10 rounding on a narrow range landed 6e-11 above 1 (CI, 24 Nov)
def test_a_freed_parameter_stays_inside_its_range(lo, width, x, mode):
    if mode == "log":
        lo = abs(lo) + 1e-6
    hi = lo + width
    if not hi > lo:
        return
    p = freed("p", "1", lo, hi, log=mode == "log", linthresh=1.0 if mode == "symlog" else None)
    u = float(p.to_unit(x))
    assert -1e-12 <= u <= 1 + 1e-12
    v = float(p.from_unit(u))
    assert p.lower <= v <= p.upper and p.in_bounds(v)
    if lo <= x <= hi:
        assert v == pytest.approx(x, rel=1e-6, abs=1e-9 * max(1.0, abs(lo), abs(hi)))


def test_an_effect_may_declare_fit_range_and_neutral_on_its_parameters():
    from plant.effect import Parameter as EffectParameter
    from plant.effect import PhysicalEffect
    from workbench.fit import effect_free_parameters
    from workbench.fit._candidates import neutral_end

    class TipSpring(PhysicalEffect):
        name = "tip_spring_declared"
        parameters = (EffectParameter("k_tip_d", "N/m", 0.0, 0.0, 1e3, "tip spring", neutral=0.0,
                                      fit=FitRange(0.0, 50.0, linthresh=0.1)),
                      EffectParameter("g_fixed", "1", 1.0, 0.0, 2.0, "a coefficient the fit leaves alone"))

        @staticmethod
        def rates(t, x, p, bus, dx, so, po):
            pass

    (fp,) = effect_free_parameters(TipSpring)  # only the parameter with a declared range is fitted by default
    assert fp.name == "k_tip_d" and (fp.lower, fp.upper, fp.linthresh) == (0.0, 50.0, 0.1)
    assert fp.owner == TipSpring.name
    assert neutral_end(fp, TipSpring) == (True, False)
    assert [p.name for p in effect_free_parameters(TipSpring, ["g_fixed"])] == ["g_fixed"]
