"""Comparing the results of two runs (tests/studies/test_scale_out_*.py): wall and CPU seconds differ from run to run,
nothing else may."""

from __future__ import annotations

from typing import Any

#: the keys that hold timings (besides every ``*_wall_s``)
TIMING_KEYS = ("timings_s", "wall_s", "load_s", "integrator_s", "cost")


def timeless(doc: Any) -> Any:
    """The JSON document ``doc`` without its timings (at any depth)."""
    if isinstance(doc, dict):
        return {k: timeless(v) for k, v in doc.items() if not (k in TIMING_KEYS or k.endswith("_wall_s"))}
    if isinstance(doc, list):
        return [timeless(v) for v in doc]
    return doc
