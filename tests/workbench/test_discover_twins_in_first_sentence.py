"""A finding whose place the records leave open says so in the sentence that states it (issue 26 point 1): on a
quasi-static MBIT.a a root crack open for δ1 > 0 was named "a breathing crack in section 2 …" and only the next
sentence said the records could not tell it from section 1's — the verdict's first sentence put the damage in the
wrong section with no doubt attached."""

from __future__ import annotations

from workbench.challenges.discovery import first_sentence
from workbench.discover._dictionary import Term
from workbench.discover._results import FoundTerm


def _crack(index: int) -> Term:
    return Term("damage", index, f"delta{index + 1}", "on_pos", 0.0, "k")


def test_the_twins_of_a_finding_are_in_its_first_sentence():
    twin = {"key": "k1_pos_delta1", "placement": "damage", "index": 0, "signal": "delta1", "form": "on_pos",
            "held_rms_sigma": 0.99, "judged_by": "refitted",
            "words": "a breathing crack in section 1 that opens for δ1 > 0: stiffness k1 lower by 25.1 % on that side"}
    found = FoundTerm(_crack(1), -0.2, 0.0, 1e-3,
                      "a breathing crack in section 2 that opens for δ2 > 0: stiffness k2 lower by 20 % on that side",
                      twins=[twin])
    first = first_sentence("Found beyond the library: " + found.description + ". Held-out error 114 σ → 0.98 σ.")
    assert "section 2" in first and "section 1" in first and "cannot tell it from" in first


def test_a_finding_without_twins_reads_as_before():
    found = FoundTerm(_crack(1), -0.2, 0.0, 1e-3, "a breathing crack in section 2 that opens for δ2 > 0")
    assert found.description == "a breathing crack in section 2 that opens for δ2 > 0"
