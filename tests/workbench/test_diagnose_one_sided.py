"""A re-estimation on a record that moves its parameter's switching signal one way only says, in its first
sentence, which one-sided damage reading the record cannot rule out (issue 26 point 1): on an MBIT.b step a patch
weaker only for positive charge was told "d_ep is wrong (−25 %) — re-estimate it" and nothing else — the step never
charges a patch negative, so a depolarised patch reads exactly as a lower d_ep."""

from __future__ import annotations

import numpy as np
import workbench_unseen_damage as unseen
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from workbench.challenges.discovery import KINDS, case_record, first_sentence
from workbench.diagnose import diagnose
from workbench.diagnose._one_sided import one_sided_twin, side_of
from workbench.simulation import synth_test

T = np.linspace(0.0, 3.0, 3001)


def test_a_signal_on_one_side_away_from_rest_is_one_sided_and_a_swinging_one_is_not():
    step = 300.0 * (1.0 - np.exp(-T / 0.1))  # a patch charged to +300 V (at rest at the start)
    assert side_of(step) == 1 and side_of(-step) == -1
    ring = 1e-3 * (1.0 - np.exp(-T) * np.cos(20 * T))  # overshoots below zero only at rest level: still one-sided
    assert side_of(ring) == 1
    assert side_of(np.sin(2 * np.pi * T)) == 0
    assert side_of(np.zeros_like(T)) == 0


@given(arrays(np.float64, st.integers(1, 200), elements=st.floats(-1e3, 1e3)))
def test_the_side_of_a_signal_flips_with_its_sign(v):
    assert side_of(-v) == -side_of(v)


def test_the_twin_names_the_reading_for_the_parameter_and_the_side():
    charged = {f"v_patch{i}": 300.0 * (1.0 - np.exp(-T / 0.1)) for i in (1, 2, 3)}
    words = one_sided_twin("d_ep", [charged])
    assert words is not None and "positive patch voltage" in words and "depolarised" in words
    bent = {"delta2": -1e-3 * (1.0 - np.exp(-T / 0.05))}
    words = one_sided_twin("k2", [bent])
    assert words is not None and "δ2 < 0" in words and "breathing crack" in words
    # swinging signals, parameters with no one-sided reading, signals not simulated: no twin
    assert one_sided_twin("d_ep", [{f"v_patch{i}": np.sin(2 * np.pi * T) for i in (1, 2, 3)}]) is None
    assert one_sided_twin("m3", [charged]) is None
    assert one_sided_twin("k1", [charged]) is None
    # every record must stay on the same side
    assert one_sided_twin("k2", [bent, {"delta2": -bent["delta2"]}]) is None


def test_a_patch_weak_for_positive_charge_on_a_step_is_named_in_the_first_sentence(tmp_path):
    cls = unseen.UNSEEN["patch_positive_charge"][0]
    spec = synth_test("mbit-b", **KINDS.get("mbit-b", {}))
    rec, _ = case_record(spec, cls, unseen.truth_values("patch_positive_charge", spec.duration_s), 2e-6, 1)
    d = diagnose([rec], "table2", emit_dir=None)
    first = first_sentence(d.message)
    assert first.startswith("d_ep is wrong") and "re-estimate it" in first, first
    assert "positive patch voltage" in first and "cannot tell it from" in first, first


def test_each_member_of_a_pair_is_read_on_its_own_side():
    """MBIT.b's tip crack opened by the mid section's bend was "Two things at once: k3 is wrong (−10 %); d_ep is
    wrong (+4 %)" — a step bends section 3 one way and charges the patches one way: each member has its one-sided
    reading, said after it; a tied group and an effect's parameter have none."""
    from types import SimpleNamespace

    from workbench.diagnose._verdict import one_sided_twins
    from workbench.fit import CandidateSpec
    from workbench.fit._candidates import ParameterCandidate

    names = ("v_patch1", "v_patch2", "v_patch3", "delta3", "delta1")
    full = np.stack([300.0 * (1.0 - np.exp(-T / 0.1))] * 3 + [1e-3 * (1.0 - np.exp(-T / 0.05)), np.sin(T * 9)], 1)
    d = SimpleNamespace(baseline_sim=SimpleNamespace(full=[full[None]]),
                        targets=[SimpleNamespace(model=SimpleNamespace(output_names=names))])
    spec = CandidateSpec(params=(ParameterCandidate("k3", ("k3",)), ParameterCandidate("d_ep", ("d_ep",)),
                                 ParameterCandidate("k1", ("k1",)), ParameterCandidate("ks", ("k3", "k1"), True)))
    twins = one_sided_twins(d, SimpleNamespace(spec=spec))
    assert set(twins) == {"k3", "d_ep"}  # δ1 swings both ways; a tied group is no one parameter
    assert "section 3" in twins["k3"] and "crack" in twins["k3"] and "δ3 > 0" in twins["k3"]
    assert "positive patch voltage" in twins["d_ep"]
    assert one_sided_twins(SimpleNamespace(baseline_sim=None, targets=[]), SimpleNamespace(spec=spec)) == {}
