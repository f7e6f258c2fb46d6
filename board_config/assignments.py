"""The one parser of ``NAME=VALUE`` options: ``--set k3=21.3``, ``--noise z3=2e-6,v_patch=0.1``, ``--deviation k3=-0.3``
(several per item, comma-separated, where the option allows it).

Errors are :class:`~board_config.errors.InputError` naming the flag, the item and why it is wrong.
"""

from __future__ import annotations

from collections.abc import Iterable

from board_config.errors import InputError


def parse_number(flag: str, item: str, raw: str) -> float:
    """``raw`` (the value part of ``item``, given to ``flag``) as a float; ``InputError`` naming both otherwise."""
    try:
        return float(raw)
    except ValueError:
        raise InputError(f"{flag} {item!r}: {raw!r} is not a number") from None


def parse_assignments(flag: str, items: Iterable[str] | None, *, comma_lists: bool = True) -> dict[str, float]:
    """``["z3=2e-6", "v_patch=0.1"]`` → ``{"z3": 2e-6, "v_patch": 0.1}``; a later NAME overrides an earlier one.

    ``comma_lists``: an item may hold several assignments separated by commas (``z3=2e-6,v_patch=0.1``).
    """
    out: dict[str, float] = {}
    for item in items or []:
        parts = [p.strip() for p in item.split(",") if p.strip()] if comma_lists else [item]
        for part in parts:
            name, sep, value = part.partition("=")
            if not sep or not name.strip():
                raise InputError(f"{flag} {part!r}: expected NAME=VALUE")
            out[name.strip()] = parse_number(flag, part, value.strip())
    return out
