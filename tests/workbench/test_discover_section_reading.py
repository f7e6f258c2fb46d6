"""A one-sided force on a mass read as a section's own switched stiffness (issue 26 point 3,
``workbench/discover/_section_reading.py``), and a reading of another kind named among the twins
(``_twins.place_first``). The measured case — a tip crack stiffer past a wedge at δ3 < −0.3 mm on MBIT.a, said as a
stop on mass 3 with the other masses' stops its twins — is the third blind set's heavy ``tip_crack_wedged``."""

from __future__ import annotations

import pytest

from workbench.discover._dictionary import Term
from workbench.discover._section_reading import ONE_SIDED, mapped_point
from workbench.discover._twins import MAX_TWINS, place_first


def _twin(key: str, placement: str, index: int) -> dict:
    return {"key": key, "placement": placement, "index": index, "held_rms_sigma": 1.0}


def test_the_switching_point_follows_the_force_s_side_scaled_to_the_deflection():
    # a stop met at z3 < −0.9 mm (tip scale 3 mm), read on δ3 (scale 1 mm): the section switches at δ3 < −0.3 mm
    assert mapped_point("neg", 9e-4, 3e-3, 1e-3) == pytest.approx(-3e-4)
    assert mapped_point("pos", 1.8e-3, 3e-3, 1e-3) == pytest.approx(6e-4)
    assert ONE_SIDED == {"pos": "on_pos", "neg": "on_neg"}


def test_a_reading_of_another_kind_is_named_beside_the_two_twins():
    stop = Term("force_mass", 2, "z3", "neg", 9e-4)
    masses = [_twin("m1_neg_z1", "force_mass", 0), _twin("m2_neg_z2", "force_mass", 1)]
    crack = _twin("k3_neg_delta3", "damage", 2)
    named = place_first(stop, [*masses, crack])
    assert named == [*masses, crack]  # the crack in section 3 said, the two stops kept
    # a reading of another kind among the two already: nothing added
    assert place_first(stop, [masses[0], crack, masses[1]]) == [masses[0], crack]
    # none of another kind: the two
    assert place_first(stop, masses) == masses and len(place_first(stop, [*masses, *masses])) == MAX_TWINS
