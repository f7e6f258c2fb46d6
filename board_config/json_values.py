"""The one JSON sanitiser: numbers and containers of numpy made plain Python, non-finite floats made ``null``; and
:class:`JsonFields`, the one ``to_dict`` of a result dataclass whose JSON form is its fields by name."""

from __future__ import annotations

import math
from dataclasses import asdict
from typing import TYPE_CHECKING, Any, cast

import numpy as np

if TYPE_CHECKING:
    from _typeshed import DataclassInstance


class JsonFields:
    """Base of a result dataclass whose JSON form is its fields by name, in declaration order (base classes'
    fields first), nested dataclasses as dicts: ``dataclasses.asdict``. Values are not sanitised
    (:func:`to_jsonable` does that at the edge)."""

    __slots__ = ()

    def to_dict(self) -> dict[str, Any]:
        """The fields by name (``dataclasses.asdict``); the subclass must be a dataclass."""
        return asdict(cast("DataclassInstance", self))


def to_jsonable(obj: Any) -> Any:
    """``obj`` with dict keys as strings, tuples as lists, numpy arrays/scalars as Python values and NaN/±inf as
    None, recursively (anything else is returned as it is)."""
    if isinstance(obj, dict):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return to_jsonable(obj.tolist())
    if isinstance(obj, float | np.floating):
        v = float(obj)
        return v if math.isfinite(v) else None
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.bool_):
        return bool(obj)
    return obj
