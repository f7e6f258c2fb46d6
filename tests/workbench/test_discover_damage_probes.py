"""The screen's damage probes (issue 26, point 7): a damage term changes a parameter by tens of percent, where the
linearised coefficient misleads (it cannot move a resonance), so each parameter's best state-gated damage terms are
also probed on the full model at fixed relative changes; the crack is then refitted first instead of after ~50
refits of forces on the masses."""

from __future__ import annotations

import pytest

from workbench.discover._dictionary import Term
from workbench.discover._results import ScreenRow
from workbench.discover._search import (
    DAMAGE_PROBED_PER_PARAM,
    DAMAGE_PROBES,
    GROWN_PROBES,
    MAX_HARD_PROBED,
    MAX_MULTIPLIED,
    damage_probed,
    probe_plan,
)


def _row(term: Term) -> ScreenRow:
    return ScreenRow(term, 0.01, 10.0, 10.0)


def test_each_parameter_gets_its_best_state_gated_damage_terms_probed():
    k3 = [Term("damage", 2, sig, form, param="k") for sig, form in
          (("delta3", "on_neg"), ("delta3", "on_pos"), ("ddelta3", "on_neg"), ("delta3", "on_gap"),
           ("ddelta3", "on_pos"))]
    k2 = [Term("damage", 1, "delta2", "on_neg", param="k")]
    force = Term("force_mass", 2, "z3", "cube")
    step = Term("damage", 2, "one", "on_step", param="k")  # probed at the residual's onset instead
    d_ep = Term("damage", -1, "va", "on_neg", param="d_ep")
    rows = [_row(t) for t in (force, step, k3[0], k3[1], k2[0], k3[2], k3[3], k3[4], d_ep)]
    chosen = damage_probed(rows)
    assert chosen == {2, 3, 4, 8}  # k3's first two, k2's one, d_ep's one
    assert sum(1 for j in chosen if rows[j].term.param == "k" and rows[j].term.index == 2) == DAMAGE_PROBED_PER_PARAM


def test_damage_terms_do_not_take_the_forces_multiples():
    """Strong tip friction on an MBIT.b step linearises behind ~200 damage terms of hard (sign-gated) forms; its
    force term must still be probed at ×0.1 … ×10 (its stick is nowhere in the linearisation), and the damage terms
    at relative changes instead."""
    gated = [Term("damage", i % 3, f"delta{i % 3 + 1}", ("on_pos", "on_neg", "on_gap")[i % 3], param=p)
             for i in range(60) for p in ("k", "c")]
    friction = Term("force_mass", 2, "zd3", "sign")
    rows = [_row(t) for t in gated] + [_row(friction)]
    plan = dict(probe_plan(rows))
    assert len(plan[len(rows) - 1]) == 7  # the friction: its coefficient and six multiples
    assert min(plan[len(rows) - 1]) == pytest.approx(0.001) and max(plan[len(rows) - 1]) == pytest.approx(0.1)
    for j, row in enumerate(rows[:-1]):
        extra = plan[j][1:]
        assert extra in ([], list(DAMAGE_PROBES), list(DAMAGE_PROBES + GROWN_PROBES)), row.term.key
        assert extra == [] or (len(extra) > len(DAMAGE_PROBES)) == (row.term.param == "c")
        assert extra == [] or j in damage_probed(rows)
    forces = [_row(Term("force_mass", i % 3, "zd3", "sign")) for i in range(MAX_MULTIPLIED + 5)]
    plan = dict(probe_plan(forces))
    assert [len(plan[j]) for j in range(len(forces))] == (
        [7] * MAX_HARD_PROBED + [3] * (MAX_MULTIPLIED - MAX_HARD_PROBED) + [1] * 5)  # ×1, ×3, ×10 further down
    stops = [_row(Term("force_mass", i % 3, "z3", "pos")) for i in range(MAX_HARD_PROBED + 5)]
    assert [len(c) for _, c in probe_plan(stops)] == [7] * MAX_HARD_PROBED + [1] * 5  # a stop: the first few only


# A crack whose linearised screen misleads is refitted first: checked on the discovery run of
# test_discover_event_plausibility.py::test_a_crack_on_a_sweep_is_not_named_as_an_event (the same crack, one run).
