"""The hooks of an effect: their names, the two signatures a hook may have (slot tables by name, or the older
offsets seam), and how to tell them apart (:func:`hook_style`). See :mod:`plant.effect` for what each hook does."""

from __future__ import annotations

import inspect
from collections.abc import Callable

from plant.effect_declarations import EffectError

Hook = Callable[..., None]
HOOKS: tuple[str, ...] = ("pre", "rates", "post", "output")
#: positional arguments of a hook with slot tables (named) and of one written against the offsets seam
NAMED_ARGS: dict[str, tuple[str, ...]] = {
    **{h: ("t", "x", "p", "bus", "dx", "X", "P", "B") for h in ("pre", "rates", "post")},
    "output": ("t", "x", "p", "bus", "y", "X", "P", "B", "Y"),
}
OFFSET_ARGS: dict[str, tuple[str, ...]] = {
    **{h: ("t", "x", "p", "bus", "dx", "so", "po") for h in ("pre", "rates", "post")},
    "output": ("t", "x", "p", "bus", "y", "so", "po", "yo"),
}


def hook_function(cls: type, hook: str) -> Callable[..., None] | None:
    """The plain Python function of ``cls``'s hook (a numba dispatcher's ``py_func``), or None."""
    fn = getattr(cls, hook, None)
    return getattr(fn, "py_func", fn)


def hook_style(cls: type, hook: str) -> str:
    """``"named"`` (slot tables X, P, B[, Y]) or ``"offsets"`` (the seam before them: so, po[, yo])."""
    fn = hook_function(cls, hook)
    if fn is None:
        return "named"
    try:
        params = list(inspect.signature(fn).parameters.values())
    except (TypeError, ValueError):
        return "named"
    n = len(params)
    if any(p.kind in (p.VAR_POSITIONAL, p.VAR_KEYWORD) for p in params):
        n = -1
    if n == len(NAMED_ARGS[hook]):
        return "named"
    if n == len(OFFSET_ARGS[hook]):
        return "offsets"
    raise EffectError(
        f"effect {cls.__module__}.{cls.__qualname__}: hook '{hook}' takes {n if n >= 0 else 'a variable number of'} "
        f"arguments; write it as {hook}({', '.join(NAMED_ARGS[hook])}) and use the slot tables by name "
        f"(p[P.my_parameter], bus[B.fm3], x[X.my_state], docs/effects.md) — the older form "
        f"{hook}({', '.join(OFFSET_ARGS[hook])}) is still accepted")
