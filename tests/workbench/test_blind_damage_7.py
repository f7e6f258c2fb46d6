"""The seventh blind damage set (tests/workbench_blind_damage_7.py: twelve damages in forms the earlier sets did not
use, written from the effect seam alone): its cases are well formed (fast), and, as a measurement, the cases that
pass through the one-command walk (heavy)."""

from __future__ import annotations

import pytest
from workbench_blind_damage_7 import BLIND7, run_blind7
from workbench_unseen_damage import check_cases


def test_every_blind_case_has_a_check_for_its_physics():
    check_cases(BLIND7)


#: the cases that pass the walk (first sentence names the physics, the fix ≤ 1.5 σ held out), by record kind, measured
#: on the first contact (352a320, 2026-11-29 14:53–15:40 UTC, one thread per case, two at a time; docs/workbench.md,
#: "A seventh blind set"): sweep 6 of 12, MBIT.a 4 of 12, MBIT.b 3 of 9 counted (larger than 3 σ) — 13 of 33 (39 %).
#: Since then: the best two damage-like kinds refitted when the kept event is no damage (a2a72cd) — MBIT.a's
#: tip_loss_grows_to_end (re-run 15:37 UTC); a kept switch tried in its other shapes beside the set (109c9cd) — the
#: sweep's tip_crack_open_up_damps (re-run 16:47 UTC, 0.98 σ): 15 of 33 (45 %). A kept step tried on one side from its
#: instant (2520645 … 2793505, session of 17:19 UTC) — the sweep's patch3_weak_positive_from_instant (re-run 19:49
#: UTC, 0.99 σ, "… 30 % lower while the patch voltage is above −13.6 V … from t = 5.988 s on"). Lost with the same
#: commits: MBIT.b's patch2_weak_above_magnitude (re-run 19:52 UTC) — the new gap on |v_c| lets every patch's loss
#: above ±171 V explain it (1.36 σ, below the 3 σ where the one-patch step looks), so patch 2 goes unnamed: 15 of 33.
#: Two dictionary forms (76192aa, session of 20:34 UTC): a coupling lost linearly past a voltage magnitude and a crack
#: whose share grows with the square of its opening — won the sweep's patch2_weak_above_magnitude (0.97 σ) and
#: mid_crack_down_quadratic (0.97 σ) and MBIT.b's patch2_weak_above_magnitude (1.01 σ, patch 2 named again); lost the
#: sweep's tip_crack_open_up_damps (round 1 now keeps the square law, 189.1 σ against the linear 190.2 σ, and round 2
#: then adds section 2's damping instead of section 3's: 73.5 σ): 17 of 33 (52 %). A kept switch tried in the other
#: places (10529be, session of 23:39 UTC) — won back the sweep's tip_crack_open_up_damps (the damping moved to section
#: 3, then both shapes swapped: 0.98 σ, re-run 01:06 UTC) and won MBIT.b's patch2_weak_charge_falls (1.00 σ, patch 2
#: named, patch 1 as its twin; re-run 00:35 UTC): 19 of 33 (58 %).
PASSING7: dict[str, tuple[str, ...]] = {
    "sweep": ("root_crack_past_preload_up", "root_loss_two_steps", "mid_loss_exponential", "tip_loss_grows_to_end",
              "patch1_weak_root_down", "patch2_weak_charge_falls", "patch3_weak_positive_from_instant",
              "patch2_weak_above_magnitude", "mid_crack_down_quadratic", "tip_crack_open_up_damps"),
    "mbit-a": ("mid_crack_on_tip_bend_down", "tip_crack_open_up_damps", "patch1_weak_root_down",
               "patch2_weak_charge_falls", "tip_loss_grows_to_end"),
    "mbit-b": ("root_crack_past_preload_up", "root_loss_two_steps", "patch2_weak_above_magnitude",
               "patch2_weak_charge_falls"),
}


@pytest.mark.heavy
@pytest.mark.parametrize(("kind", "label"), [(k, lab) for k, labels in PASSING7.items() for lab in labels])
def test_blind_case_is_named_and_fixed(label: str, kind: str, tmp_path) -> None:
    r = run_blind7(label, kind=kind, workdir=str(tmp_path))
    assert r["named"], (label, kind, r["sentence"], r["missing"])
    assert r["passed"], (label, kind, r["held_before"], r["held_fix"], r["fix"])


def test_the_passing_lists_name_cases_of_the_set():
    assert all(set(labels) <= set(BLIND7) for labels in PASSING7.values())
