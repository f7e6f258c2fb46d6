"""The second blind damage set (tests/workbench_blind_damage_2.py): its cases are well formed (fast), and, as a
measurement, each case through the one-command walk (heavy: the lead runs it; some are expected to fail)."""

from __future__ import annotations

import pytest
from workbench_blind_damage_2 import BLIND2, run_blind2


def test_every_blind_case_has_a_check_for_its_physics():
    for label, (cls, values, groups, timing) in BLIND2.items():
        assert len(groups) >= 2, label
        names = {p.name for p in cls.parameters}
        assert {k.removesuffix("_frac") for k in values} == names, label
        assert timing is None or timing[0] in names, label


@pytest.mark.heavy
@pytest.mark.parametrize("kind", ["sweep", "mbit-a"])
@pytest.mark.parametrize("label", sorted(BLIND2))
def test_blind_case_is_named_and_fixed(label: str, kind: str, tmp_path) -> None:
    r = run_blind2(label, kind=kind, workdir=str(tmp_path))
    assert r["named"], (label, kind, r["sentence"], r["missing"])
    assert r["passed"], (label, kind, r["held_before"], r["held_fix"], r["fix"])
