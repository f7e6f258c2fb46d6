"""The second blind damage set (tests/workbench_blind_damage_2.py): its cases are well formed (fast), and, as a
measurement, the cases that pass through the one-command walk (heavy)."""

from __future__ import annotations

import pytest
from workbench_blind_damage_2 import BLIND2, run_blind2
from workbench_unseen_damage import check_cases


def test_every_blind_case_has_a_check_for_its_physics():
    check_cases(BLIND2)


#: the cases that pass the walk (first sentence names the physics, the fix ≤ 1.5 σ held out), measured on 900df37
#: (2026-11-27 21:13–21:36 UTC, one thread per case, two at a time; docs/workbench.md, "A second blind set"): sweep 6
#: of 12, MBIT.a 4 of 12; and on the changes with a time scale and the switches with an edge (2026-11-28 00:00–01:25
#: UTC, docs/workbench.md "Changes with a time scale, switches with an edge"): the S-curve, the drop that partly
#: recovers and patch 2 weaker above +80 V over a 15 V edge on the sweep — 9 of 12 there. The others, and why, are in
#: those sections.
PASSING2 = {"sweep": ("mid_crack_up_smooth", "root_crack_down", "tip_crack_gap_damped", "tip_step_loss",
                      "side1_depoled", "patch1_weak_negative_charge", "root_s_curve", "mid_drop_recover",
                      "patch2_weak_positive"),
            "mbit-a": ("root_crack_down", "mid_crack_up_smooth", "delam_root_mid_z2", "tip_step_loss")}


@pytest.mark.heavy
@pytest.mark.parametrize(("kind", "label"), [(k, lab) for k, labels in PASSING2.items() for lab in labels])
def test_blind_case_is_named_and_fixed(label: str, kind: str, tmp_path) -> None:
    r = run_blind2(label, kind=kind, workdir=str(tmp_path))
    assert r["named"], (label, kind, r["sentence"], r["missing"])
    assert r["passed"], (label, kind, r["held_before"], r["held_fix"], r["fix"])


def test_the_passing_lists_name_cases_of_the_set():
    assert all(set(labels) <= set(BLIND2) for labels in PASSING2.values())
