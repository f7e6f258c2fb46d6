"""A dictionary slot for the refit tests of ``shm discover``: the dictionary for ``scales``, the term ``key``'s index,
its (coefficient, shape, width) names and a search state keeping it at given values."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any


def kept_slot(scales: Mapping[str, float], key: str, coef: float, shape: float, width: float) -> dict[str, Any]:
    """terms, names, k (the index of ``key``), c, g, h (its parameter names) and state (it kept at the values)."""
    from workbench.discover import dictionary_parameter_names
    from workbench.discover._dictionary import build_dictionary
    from workbench.discover._dictionary_code import dictionary_width_names
    from workbench.discover._search import SearchState

    terms = build_dictionary(dict(scales))
    names = dictionary_parameter_names(terms)
    k = next(i for i, t in enumerate(terms) if t.key == key)
    c, g = names[k]
    h = dictionary_width_names(terms)[k]
    return {"terms": terms, "names": names, "k": k, "c": c, "g": str(g), "h": h,
            "state": SearchState({c: coef, str(g): shape, h: width}, [k])}
