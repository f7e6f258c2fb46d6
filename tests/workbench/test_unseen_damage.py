"""Damage forms the project never tested against (issue 26, "we will check on damage cases you do not see"): the
effects of ``tests/workbench_unseen_damage.py`` — written by hand, unlike the project's own damage cases — through
the one-command walk (``diagnose`` with its discovery step, then the emitted file refitted as ``shm fit --add``
does). The heavy cases score the verdict's first sentence and the fix's held-out error; the fast one checks that
every case carries a check of its physics."""

from __future__ import annotations

import pytest
from workbench_unseen_damage import UNSEEN, check_cases, run_unseen

#: cases that pass the walk today (first sentence names the physics, the fix ≤ 1.5 σ held out): the module docstring
#: of tests/workbench_unseen_damage.py lists the ones that do not, with what their first sentence says
PASSING = ("k1_step", "gap_s3", "crack_s3_negative", "bilinear_offset_s2", "patch_offset", "smooth_crack_root",
           "damping_step_s3", "crack_root_positive", "k3_drop", "patch_positive_charge", "root_patch_negative",
           "ramp_loss_root", "damping_rise_s3")


@pytest.mark.heavy
@pytest.mark.parametrize("label", PASSING)
def test_unseen_damage_named_in_the_first_sentence_and_fixed(label, tmp_path):
    r = run_unseen(label, workdir=str(tmp_path))
    assert r["named"], (r["sentence"], r["missing"])
    assert r["passed"], (r["fix"], r["held_fix"], r["note"])


#: on an MBIT.b step (3 s, one way): the crack and the polarity are named as what the record cannot rule out (the
#: switching family's refit; the one-sided re-estimation), the bilinear spring found by the family's refit
PASSING_MBIT_B = ("crack_root_positive", "patch_positive_charge", "bilinear_offset_s2", "k3_drop", "crack_s3_negative")


@pytest.mark.heavy
@pytest.mark.parametrize("label", PASSING_MBIT_B)
def test_unseen_damage_on_a_one_way_step_named_in_the_first_sentence_and_fixed(label, tmp_path):
    r = run_unseen(label, kind="mbit-b", workdir=str(tmp_path))
    assert r["named"], (r["sentence"], r["missing"])
    assert r["passed"], (r["fix"], r["held_fix"], r["note"])


def test_every_unseen_case_has_a_check_for_its_physics():
    check_cases(UNSEEN)
