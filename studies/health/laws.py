"""Degradation laws: the truth plant's relative parameter deviations against operating time (pure functions).

A scenario's ``[life]`` gives per parameter (core or effect) one or more terms (:class:`board_config.scenario.LifeLaw`)
that add up: constant, linear, exponential, power law, step. ``truth = nominal × (1 + d(h))`` as for ``[rig]
deviations``, which stay as a constant baseline under the laws.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping

from board_config.parameter import DEVIATION_RANGE
from board_config.scenario import LifeLaw

#: relative deviations are kept inside the accepted range (board_config.DEVIATION_RANGE)
D_MIN, D_MAX = DEVIATION_RANGE


def law_value(law: LifeLaw, hours: float) -> float:
    """Relative deviation contributed by one term at ``hours`` of operating time (h)."""
    if law.kind == "constant":
        return law.value
    if law.kind == "step":
        return law.size if hours >= law.at else 0.0
    x = max(0.0, hours - law.start)
    if law.kind == "linear":
        return law.rate * x
    if law.kind == "exponential":
        return law.amplitude * math.expm1(x / law.time_constant)
    if law.kind == "power":
        return law.amplitude * (x / law.reference) ** law.exponent
    raise ValueError(f"unknown law kind {law.kind!r}")


def deviations_at(laws: Iterable[LifeLaw], hours: float, base: Mapping[str, float] | None = None
                  ) -> dict[str, float]:
    """Every parameter's relative deviation at ``hours``: ``base`` plus the sum of its law terms, clipped to
    [-0.95, 5]."""
    out = {k: float(v) for k, v in (base or {}).items()}
    for law in laws:
        out[law.parameter] = out.get(law.parameter, 0.0) + law_value(law, hours)
    return {k: min(D_MAX, max(D_MIN, v)) for k, v in out.items()}
