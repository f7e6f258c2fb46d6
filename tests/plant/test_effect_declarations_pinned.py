"""The library effects' workbench declarations are the same after they moved onto the parameters (issue 30 point 1).

Before, each library effect declared its neutral values, fit ranges and challenge strengths in class tables
(``neutral``, ``fit_ranges``, ``extra_ranges``, ``challenge_strengths``) beside its parameters. The table below was
captured from those class tables (and from ``workbench.fit._effect_library.effect_free_parameters``, ``library_order``,
``short_name``) on main before the move; every value is read here only through the typed declaration that now holds
it — the parameter's ``neutral``, ``fit``, ``fit_by_default`` and ``challenge`` — and the readers every consumer uses.
"""

from __future__ import annotations

import re
from typing import NamedTuple

import pytest

from plant import registered_effects
from plant.effect import PhysicalEffect, library_effects
from workbench.challenges.hidden_effect import STRENGTHS
from workbench.fit import effect_free_parameters

#: (name, lower, upper, log, linthresh) of a fit range
Range = tuple[str, float, float, bool, float | None]


class Declared(NamedTuple):
    order: int
    short: str
    neutral: dict[str, float]
    fitted: list[Range]  # fitted by default, in this order
    on_request: list[Range]  # declared range, fitted only when asked
    strengths: tuple[dict[str, float], ...]  # weak, medium, strong


BEFORE: dict[str, Declared] = {
    'piezo_creep': Declared(
        order=1, short='creep', neutral={'gamma_creep': 0.0},
        fitted=[('gamma_creep', 0.0, 0.5, False, 0.001), ('tau_creep', 0.03, 100.0, True, None)],
        on_request=[],
        strengths=({'gamma_creep': 0.01, 'tau_creep': 0.5}, {'gamma_creep': 0.03, 'tau_creep': 1.0},
                   {'gamma_creep': 0.1, 'tau_creep': 2.0})),
    'geometric_stiffening': Declared(
        order=2, short='stiffening', neutral={'kappa_nl': 0.0},
        fitted=[('kappa_nl', -10000.0, 200000.0, False, 100.0)],
        on_request=[],
        strengths=({'kappa_nl': 2000.0}, {'kappa_nl': 10000.0}, {'kappa_nl': 50000.0})),
    'air_damping': Declared(
        order=3, short='air_damp', neutral={'c_air': 0.0},
        fitted=[('c_air', 0.0, 1.0, False, 0.001)],
        on_request=[],
        strengths=({'c_air': 0.02}, {'c_air': 0.08}, {'c_air': 0.3})),
    'dielectric_leakage': Declared(
        order=4, short='leakage', neutral={'G_leak': 0.0},
        fitted=[('G_leak', 0.0, 0.002, False, 1e-07)],
        on_request=[],
        strengths=({'G_leak': 2e-06}, {'G_leak': 1e-05}, {'G_leak': 5e-05})),
    'amplifier_current_limit': Declared(
        order=5, short='amp_limit', neutral={'I_max': 10.0},
        fitted=[('I_max', 0.001, 10.0, True, None)],
        on_request=[],
        strengths=({'I_max': 0.2}, {'I_max': 0.05}, {'I_max': 0.008})),
    'laser_sensor': Declared(
        order=6, short='laser', neutral={'z_offset': 0.0, 'spot_offset': 0.0, 'tau_sensor': 0.0},
        fitted=[('z_offset', -0.002, 0.002, False, 1e-07), ('tau_sensor', 0.0, 0.02, False, 0.0001)],
        on_request=[('spot_offset', 0.0, 0.5, False, None)],
        strengths=({'z_offset': 5e-06, 'tau_sensor': 0.001}, {'z_offset': 2e-05, 'tau_sensor': 0.003},
                   {'z_offset': 0.0001, 'tau_sensor': 0.01})),
    'root_compliance': Declared(
        order=7, short='root_compl', neutral={'clamp_compliance': 0.0},
        fitted=[('clamp_compliance', 0.0001, 0.02, True, None)],
        on_request=[],
        strengths=({'clamp_compliance': 0.001}, {'clamp_compliance': 0.004}, {'clamp_compliance': 0.015})),
    'thermal_drift': Declared(
        order=8, short='thermal', neutral={'dT_dt': 0.0},
        fitted=[('dT_dt', -2.0, 2.0, False, 0.001)],
        on_request=[],
        strengths=({'dT_dt': 0.05}, {'dT_dt': 0.2}, {'dT_dt': 1.0})),
}


def _range(cls: type[PhysicalEffect], name: str) -> Range:
    rng = cls.fit_range(name)
    return (name, rng.lower, rng.upper, rng.log, rng.linthresh)


def test_the_library_and_its_order_are_unchanged():
    assert library_effects()[:len(BEFORE)] == tuple(BEFORE)


@pytest.mark.parametrize("name", list(BEFORE))
def test_declarations_are_the_ones_of_the_class_tables(name):
    cls = registered_effects()[name]
    want = BEFORE[name]
    assert (cls.library_order, cls.short_name) == (want.order, want.short)
    assert cls.neutral_values() == want.neutral
    assert [_range(cls, n) for n in cls.default_fit_names()] == want.fitted
    assert [_range(cls, n) for n in cls.on_request_fit_names()] == want.on_request
    assert cls.challenge_strengths() == want.strengths
    assert STRENGTHS[name] == want.strengths  # what the hidden-effect challenge hides it at
    # what diagnose and fit free by default: the same parameters over the same ranges, owned by the effect
    freed = effect_free_parameters(cls)
    assert [(p.name, p.lower, p.upper, p.log, p.linthresh) for p in freed] == want.fitted
    assert all(p.vary and p.owner == name for p in freed)


@pytest.mark.parametrize("name", list(BEFORE))
def test_no_class_table_is_left_beside_the_parameters(name):
    cls = registered_effects()[name]
    for table in ("neutral", "fit_ranges", "extra_ranges"):
        assert not hasattr(cls, table), (name, table)
    assert callable(cls.challenge_strengths)  # the reader, not a table


@pytest.mark.parametrize(("table", "value", "keyword"), [
    ("neutral", {"k_x": 0.0}, "neutral=VALUE"),
    ("fit_ranges", {"k_x": (0.0, 1.0)}, "fit=FitRange"),
    ("extra_ranges", {"k_x": (0.0, 1.0)}, "fit_by_default=False"),
    ("challenge_strengths", ({"k_x": 0.1}, {"k_x": 0.2}, {"k_x": 0.3}), "challenge=(WEAK, MEDIUM, STRONG)"),
])
def test_a_class_table_beside_the_parameters_is_refused_naming_the_keyword(table, value, keyword):
    from plant import EffectError, Parameter, resolve_effect

    def rates(t, x, p, bus, dx, X, P, B):
        bus[B.fm3] -= p[P.k_x] * bus[B.z3]

    cls = type("OldStyle", (PhysicalEffect,), {"name": "old_style", "rates": staticmethod(rates), table: value,
                                               "parameters": (Parameter("k_x", "N/m", 0.0, 0.0, 1.0, "spring"),)})
    with pytest.raises(EffectError, match=rf"OldStyle.*'{table}' as a class table.*{re.escape(keyword)}"):
        resolve_effect(cls)
