"""The one TOML writer: values, keys and simple documents as TOML text that :mod:`tomllib` reads back.

Used by parameter sets (``ParameterSet.to_toml``) and by record headers (``workbench.records._io.meta_to_toml``).
The text it writes is stable (campaign stores and caches hash serialised parameter sets), so a change here is a
change of every such hash: floats are written with ``repr`` (shortest round-tripping form), strings as basic
strings with control characters escaped, keys bare when TOML allows it.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping
from typing import Any

_BARE_KEY = frozenset("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_-")
_ESCAPES = {"\\": "\\\\", '"': '\\"', "\b": "\\b", "\n": "\\n", "\f": "\\f", "\r": "\\r"}


def toml_string(text: str) -> str:
    """``text`` as a TOML basic string (quotes, backslashes and control characters escaped)."""
    out = []
    for ch in text:
        if ch in _ESCAPES:
            out.append(_ESCAPES[ch])
        elif (ord(ch) < 32 and ch != "\t") or ord(ch) == 127:
            out.append(f"\\u{ord(ch):04x}")
        else:
            out.append(ch)
    return '"' + "".join(out) + '"'


def toml_key(key: str) -> str:
    """``key`` bare where TOML allows it (letters, digits, ``_`` and ``-``), quoted otherwise."""
    return key if key and _BARE_KEY.issuperset(key) else toml_string(key)


def toml_value(value: Any) -> str:
    """One TOML value: bool, integer, float (``nan``/``inf`` included), string, array or inline table.

    numpy scalars count as their Python kind. ``TypeError`` for anything else.
    """
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return toml_string(value)
    if isinstance(value, numbers.Integral):
        return str(int(value))
    if isinstance(value, numbers.Real):
        x = float(value)
        if math.isnan(x):
            return "nan"
        if math.isinf(x):
            return "inf" if x > 0 else "-inf"
        return repr(x)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(toml_value(x) for x in value) + "]"
    if isinstance(value, Mapping):
        return "{ " + ", ".join(f"{toml_key(k)} = {toml_value(x)}" for k, x in value.items()) + " }"
    raise TypeError(f"cannot write {type(value).__name__} {value!r} as TOML")


def toml_document(data: Mapping[str, Any]) -> str:
    """A TOML document: top-level scalars and arrays first, then each table as a ``[name]`` section (its tables one
    level down as ``[name.sub]``, deeper ones inline), then arrays of tables as ``[[name]]`` sections. No trailing
    newline."""
    lines: list[str] = []
    tables: list[tuple[str, Mapping[str, Any]]] = []
    arrays: list[tuple[str, list[Mapping[str, Any]]]] = []
    for k, v in data.items():
        if isinstance(v, Mapping):
            tables.append((k, v))
        elif isinstance(v, list) and v and all(isinstance(x, Mapping) for x in v):
            arrays.append((k, v))
        else:
            lines.append(f"{toml_key(k)} = {toml_value(v)}")
    for name, tab in tables:
        plain = {k: v for k, v in tab.items() if not isinstance(v, Mapping)}
        subs = {k: v for k, v in tab.items() if isinstance(v, Mapping)}
        if plain or not subs:
            lines.append(f"[{toml_key(name)}]")
            lines += [f"{toml_key(k)} = {toml_value(v)}" for k, v in plain.items()]
        for k, v in subs.items():
            lines.append(f"[{toml_key(name)}.{toml_key(k)}]")
            lines += [f"{toml_key(k2)} = {toml_value(v2)}" for k2, v2 in v.items()]
    for name, arr in arrays:
        for item in arr:
            lines.append(f"[[{toml_key(name)}]]")
            lines += [f"{toml_key(k)} = {toml_value(v)}" for k, v in item.items()]
    return "\n".join(lines)
