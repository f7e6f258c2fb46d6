"""A re-estimation on a record that moves its parameter's switching signal one way only (issue 26 point 1).

A step test (MBIT.b) charges the patches to one polarity and bends every section one way. On such a record a patch
whose authority fell only for positive patch voltage (a partly depolarised patch) reads exactly as a lower d_ep,
and a section that lost stiffness only for δ > 0 (a breathing crack) as a lower k: "d_ep is wrong — re-estimate it"
reaches the noise floor either way. The verdict then says so in its first sentence — the damage reading is as
good as the parameter one, and a record that drives both polarities or bends the section both ways would tell them
apart. Pure: the traces come in (the nominal model's simulated outputs, by name)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

#: the simulated outputs whose sign would switch each core parameter's one-sided reading
SWITCHED_BY: dict[str, tuple[str, ...]] = {
    "d_ep": ("v_patch1", "v_patch2", "v_patch3"),
    **{f"k{i}": (f"delta{i}",) for i in (1, 2, 3)},
    **{f"c{i}": (f"delta{i}",) for i in (1, 2, 3)},
}
#: samples smaller than this share of a signal's largest magnitude are at rest (neither side)
AT_REST_SHARE = 0.02
#: a signal is one-sided when its other side holds less than this share of the samples away from rest
MINORITY_SHARE = 0.02


def side_of(values: np.ndarray) -> int:
    """+1 or −1 when ``values`` (one signal over a record) stay on that side of zero, away from rest; 0 otherwise
    (both sides visited, or the signal never moves)."""
    v = np.asarray(values, float)
    v = v[np.isfinite(v)]
    peak = float(np.max(np.abs(v))) if v.size else 0.0
    if not peak > 0.0:
        return 0
    moving = v[np.abs(v) > AT_REST_SHARE * peak]
    pos = float(np.mean(moving > 0.0))
    if pos >= 1.0 - MINORITY_SHARE:
        return 1
    if pos <= MINORITY_SHARE:
        return -1
    return 0


def _reading(param: str, side: int) -> tuple[str, str]:
    """(the one-sided reading in words, the signal staying on its side in words)."""
    sign = "positive" if side > 0 else "negative"
    if param == "d_ep":
        return (f"all three patches' authority changed only for {sign} patch voltage (polarisation-dependent "
                "coupling: partly depolarised patches)", f"the patch voltage stays {sign} throughout")
    i = param[1:]
    what = "stiffness" if param.startswith("k") else "damping"
    rel = ">" if side > 0 else "<"
    crack = ": a breathing crack" if what == "stiffness" else ""
    return (f"section {i} with its {what} changed only for δ{i} {rel} 0 (one side of its deflection{crack})",
            f"δ{i} stays {sign} throughout")


def one_sided_twin(param: str, traces: Sequence[Mapping[str, np.ndarray]]) -> str | None:
    """The words for a re-estimated ``param`` whose switching signals stay on one side over every record
    (``traces``: per record, output name → values), or None (not a switched parameter, a signal missing, or a
    record that visits both sides)."""
    names = SWITCHED_BY.get(param)
    if not names or not traces:
        return None
    sides = set()
    for record in traces:
        for n in names:
            if n not in record:
                return None
            sides.add(side_of(record[n]))
    if len(sides) != 1 or 0 in sides:
        return None
    reading, stays = _reading(param, sides.pop())
    return (f"these records cannot tell it from {reading}: {stays} (a record that drives both polarities and "
            "bends the sections both ways would)")
