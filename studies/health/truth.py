"""The truth of a life, when its records carry it: true parameter changes per visit and the true first FAULT.

A simulated life (``shm run --scenario aging``) logs each visit's true deviations in ``usage.db``
(``life_visits.truth_json``, relative to the rig's nominal set); a synthetic record (``shm synth``) carries the
truth plant's values in its header (``provenance.truth_values``, SI, with ``truth_params`` its nominal set). Both
are turned into relative changes against the *assessment's* nominal set, the quantity ``shm health`` estimates.

The true first FAULT (the event a prognosis predicts) is the board's own first FAULT verdict when the log holds the
board's verdicts; otherwise — synthetic records — the board's monitor applied to the true (k3, α_h, β_h) of each
visit through the trip boundary (:mod:`.trip`), seen at the first visit where it trips.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass
from functools import cache
from typing import TYPE_CHECKING, Any

import numpy as np

from studies.health.estimate import Visit
from studies.health.trip import HEALTH_PARAMS, TripBoundary

if TYPE_CHECKING:
    from plant import PlantModel


@cache
def _nominal(params: str, name: str) -> float:
    return float(_model(params).param_value(name))


@cache
def _model(params: str) -> PlantModel:
    from plant import PlantModel

    return PlantModel(params, terminal="amplifier")


def truth_relative(visit: Visit, params: str, names: Sequence[str]) -> dict[str, float] | None:
    """The visit's true relative change of each of ``names`` against ``params``' nominal values (None: no truth)."""
    t = visit.truth
    if t is None:
        return None
    out: dict[str, float] = {}
    for n in names:
        if t.relative is not None:
            value = _nominal(t.params, n) * (1.0 + float(t.relative.get(n, 0.0)))
        else:
            value = float((t.values or {}).get(n, _nominal(t.params, n)))
        out[n] = value / _nominal(params, n) - 1.0
    return out


@dataclass(frozen=True)
class TrueFirstFault:
    """The true first FAULT of a life, the event a prognosis predicts (``health.json``'s ``truth.first_fault``)."""

    visit: int | None
    """The visit's number (1 = entry into service) when the source numbers its visits; None: no FAULT here."""
    operating_hours: float | None
    """Operating hours (h) of the first FAULT; None: no FAULT in the visits searched."""
    source: str
    """Where the truth comes from, in words (the board's verdicts, or its monitor on the records' true values)."""

    def to_json(self) -> dict[str, Any]:
        """``{"visit", "operating_hours", "source"}`` as written to ``health.json``."""
        return asdict(self)


def true_first_fault(visits: Sequence[Visit], params: str, boundary: TripBoundary | None) -> TrueFirstFault | None:
    """The true first FAULT (None: not known; ``operating_hours`` None: never in these visits, and ``source`` says
    which source was searched)."""
    if any(v.verdict for v in visits):
        first = next((v for v in visits if v.verdict == "FAULT"), None)
        return TrueFirstFault(first.visit if first else None, first.operating_hours if first else None,
                              "the board's own verdicts (usage.db)")
    truths = [truth_relative(v, params, HEALTH_PARAMS) for v in visits]
    if boundary is None or any(t is None for t in truths):
        return None
    devs = np.array([[t[n] for n in HEALTH_PARAMS] for t in truths if t is not None])
    faults = boundary.fault(devs)
    k = int(np.argmax(faults)) if faults.any() else None
    return TrueFirstFault(visits[k].visit if k is not None else None,
                          visits[k].operating_hours if k is not None else None,
                          "the board's monitor (trip boundary) on the records' true k3, alpha_h, beta_h")


def truth_document(visits: Sequence[Visit], params: str, names: Sequence[str],
                   first_fault: TrueFirstFault | None) -> dict[str, Any] | None:
    """``truth`` of health.json: the true relative changes at the visits used and the true first FAULT (None when
    the sources carry no truth at all)."""
    rows = []
    for v in visits:
        t = truth_relative(v, params, names)
        if t is not None:
            rows.append({"operating_hours": v.operating_hours, "relative": t})
    if not rows and first_fault is None:
        return None
    return {"visits": rows, "first_fault": first_fault.to_json() if first_fault is not None else None}
