"""What the damage-discovery tests share (tests/workbench/test_discover_damage_*.py): a sweep whose truth is damage
written outside the dictionary (``tests/workbench_damage_effects.py``), and the one term ``discover`` finds for it."""

from __future__ import annotations

from pathlib import Path
from typing import Any

DAMAGE = Path(__file__).parent / "workbench_damage_effects.py"


def discover_one_damage(cls: str, values: dict[str, float], key: str, words: tuple[str, ...], *, duration_s: float,
                        seed: int) -> tuple[Any, Any, Any]:
    """A ``duration_s`` sweep (z3 noise 2 µm, ``seed``) whose truth is the damage class ``cls`` at ``values``;
    ``discover`` with one term must find it, as the term ``key`` described with every one of ``words``. The
    record, the discovery and its term."""
    from workbench.discover import discover
    from workbench.simulation import synth_record, synth_test, truth_model

    rec = synth_record(synth_test("sweep", duration_s=duration_s),
                       truth_model("table2", [f"{DAMAGE}:{cls}"], values), noise={"z3": 2e-6}, seed=seed)
    d = discover([rec], "table2", max_terms=1)
    assert d.verdict == "found", d.message
    found = d.terms[0]
    assert found.term.key == key, d.message
    assert all(w in found.words for w in words), found.words
    return rec, d, found
