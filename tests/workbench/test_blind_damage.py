"""Damage written blind (issue 26, "we will check on damage cases you do not see"): the twelve effects of
``tests/workbench_blind_damage.py``, written by an engineer who did not read the discovery dictionary, through the
one-command walk (``diagnose`` with its discovery step, then the emitted file refitted as ``shm fit --add`` does).
The heavy cases score the first sentence and the fix on a 15 s sweep at 2 µm; the fast one checks that every case
carries a check of its physics. docs/workbench.md ("Damage written blind") gives every case's first sentence."""

from __future__ import annotations

import pytest
from workbench_blind_damage import BLIND, run_blind
from workbench_unseen_damage import check_cases

#: the blind cases that pass the walk on the sweep today (first sentence names the physics, the fix ≤ 1.5 σ held
#: out); the others, and why, are in docs/workbench.md
PASSING = ("crack_s3_pos_sharp", "crack_s2_neg_logistic", "step_s1", "two_stage_s2", "delam_s1",
           "weak_positive_drive", "freeplay_s2",
           # members of the dictionary since 900df37 (the wider switches; measured 21:03–21:11 UTC)
           "crack_s3_growing_opening", "crack_s1_tip_switch", "patch1_weak_on_strain", "patch2_weak_negative")


#: the same on the MBITs (docs/workbench.md, "What an event may be"); the MBIT.b events are said as the stiffness
#: lost since an event's kind family (they were "authority d_ep … rose"), so they run in make test too
PASSING_MBIT = {"mbit-a": ("crack_s3_pos_sharp", "crack_s2_neg_logistic", "crack_s1_tip_switch", "step_s1",
                           "weak_positive_drive", "crack_s3_growing_opening"),
                "mbit-b": ("crack_s3_pos_sharp", "weak_positive_drive")}
EVENTS_MBIT_B = ("step_s1", "two_stage_s2")


def _named_and_fixed(label: str, kind: str, tmp_path) -> None:
    r = run_blind(label, kind=kind, workdir=str(tmp_path))
    assert r["named"], (r["sentence"], r["missing"])
    assert r["passed"], (r["fix"], r["held_fix"], r["note"])


@pytest.mark.heavy
@pytest.mark.parametrize("label", PASSING)
def test_blind_damage_named_in_the_first_sentence_and_fixed(label, tmp_path):
    _named_and_fixed(label, "sweep", tmp_path)


@pytest.mark.heavy
@pytest.mark.parametrize(("kind", "label"), [(k, lab) for k, labels in PASSING_MBIT.items() for lab in labels])
def test_blind_damage_on_the_mbits(kind, label, tmp_path):
    _named_and_fixed(label, kind, tmp_path)


@pytest.mark.slow
@pytest.mark.parametrize("label", EVENTS_MBIT_B)
def test_a_stiffness_lost_during_mbit_b_is_said_as_a_stiffness_lost(label, tmp_path):
    """Section 1 losing 15 % at 1.2 s was "authority d_ep of patch 1 rose by 17.7 %"; section 2 losing 10 % twice was
    two rises of patch 2's authority (file 24.5 σ)."""
    _named_and_fixed(label, "mbit-b", tmp_path)


def test_every_blind_case_has_a_check_for_its_physics():
    check_cases(BLIND)
