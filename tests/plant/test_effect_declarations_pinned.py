"""The library effects' workbench declarations are the same after they moved onto the parameters (issue 30 point 1).

Before, each library effect declared its neutral values, fit ranges and challenge strengths in class tables
(``neutral``, ``fit_ranges``, ``extra_ranges``, ``challenge_strengths``) beside its parameters. The table
``tests/data/effect_declarations_before.json`` was captured from those class tables (and from
``workbench.fit._effect_library.effect_free_parameters``, ``library_order``, ``short_name``) on main before the move;
every value is read here only through the typed declaration that now holds it — the parameter's ``neutral``, ``fit``,
``fit_by_default`` and ``challenge`` — and the readers every consumer uses.
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import NamedTuple

import pytest

from plant import registered_effects
from plant.effect import PhysicalEffect, library_effects
from workbench.challenges.hidden_effect import STRENGTHS
from workbench.fit import effect_free_parameters

PINNED = Path(__file__).parents[1] / "data" / "effect_declarations_before.json"
#: (name, lower, upper, log, linthresh) of a fit range
Range = tuple[str, float, float, bool, float | None]


class Declared(NamedTuple):
    order: int
    short: str
    neutral: dict[str, float]
    fitted: list[Range]  # fitted by default, in this order
    on_request: list[Range]  # declared range, fitted only when asked
    strengths: tuple[dict[str, float], ...]  # weak, medium, strong


#: the pinned table, in library order
BEFORE: dict[str, Declared] = {
    name: Declared(d["order"], d["short"], d["neutral"], [tuple(r) for r in d["fitted"]],
                   [tuple(r) for r in d["on_request"]], tuple(d["strengths"]))
    for name, d in json.loads(PINNED.read_text(encoding="utf-8")).items()}


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
