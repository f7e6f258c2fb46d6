"""Batched, compiled integration: Dormand–Prince 5(4) with step-size control, one trajectory per
batch member (or ``LANES`` members sharing a step size), batch members in parallel threads.

Inputs are sampled on a uniform grid and linearly interpolated (held constant outside it). Outputs
between steps come from the method's 4th-order dense output, so the step size is set by accuracy and stability,
not by the output rate; the last step lands exactly on the final time. Each trajectory has its
own step size; a trajectory that produces a non-finite state or needs a step below ``h_min`` stops
with a status code, filling the rest of its outputs with NaN, without affecting the others.

The integrators are ordinary functions, read by ruff and mypy: the step both take (:mod:`plant.integrate_steps`),
member by member (:mod:`plant.integrate_scalar`) and in lanes (:mod:`plant.integrate_lanes`). They call what only a
composition knows (its right-hand side, its sizes: :mod:`plant.integrate_kernel_names`), so :mod:`plant.compose`
copies their source (:func:`kernel_source`) into the module it generates for each composition beside its
right-hand side; numba then caches the compiled machine code on disk (a composition compiles once per machine,
not once per process).
"""

from __future__ import annotations

import inspect
import textwrap
from collections.abc import Callable, Mapping, Sequence
from enum import IntEnum
from typing import Any

from plant import integrate_lanes, integrate_scalar, integrate_steps
from plant.integrate_kernel_names import LANES
from plant.integrate_splice import spliced_source
from plant.integrate_steps import TABLEAU_NAMES


class IntegrationStatus(IntEnum):
    OK = 0
    DIVERGED = 1  # a state became NaN or infinite
    STEP_TOO_SMALL = 2  # the step-size controller hit h_min
    TOO_MANY_STEPS = 3

    @property
    def message(self) -> str:
        return {
            0: "ok",
            1: "the state became non-finite (the model diverged)",
            2: "the step size fell below its minimum (stiff or discontinuous dynamics)",
            3: "the step budget was exhausted",
        }[int(self)]


class IntegrationFailed(FloatingPointError):
    """An integration stopped early: ``status`` (an :class:`IntegrationStatus`), the first failing batch
    ``member`` and ``t``, the start (s) of the interval in which it stopped (for a batch simulation: the last output
    time it reached). A ``FloatingPointError``, so ``except FloatingPointError`` catches it."""

    def __init__(self, message: str, status: IntegrationStatus | int, member: int, t: float) -> None:
        super().__init__(message)
        self.status = IntegrationStatus(int(status))
        self.member = int(member)
        self.t = float(t)

    def __reduce__(self) -> tuple[type[IntegrationFailed], tuple[str, int, int, float]]:
        # pickled whole (a worker process reports it to the campaign's parent)
        return type(self), (str(self), int(self.status), self.member, self.t)


#: the options every compiled integrator function gets (``CACHE``: numba's on-disk cache, set per kernel module)
NJIT_OPTIONS = 'cache=CACHE, nogil=True, error_model="numpy"'


def kernel_source(functions: Sequence[Callable[..., Any]], inline: Sequence[Callable[..., Any]] = (),
                  spliced: Mapping[Callable[..., Any], Sequence[Callable[..., Any]]] | None = None) -> str:
    """The source of ``functions`` as numba functions of a generated kernel module: each function's own text
    (annotations are not evaluated: the module starts with ``from __future__ import annotations``) under
    ``@numba.njit`` with :data:`NJIT_OPTIONS`, ``inline="always"`` for those in ``inline``; a function in
    ``spliced`` has the bodies of its helpers written in place of their calls
    (:func:`plant.integrate_splice.spliced_source`)."""
    parts = []
    for fn in functions:
        options = NJIT_OPTIONS + (', inline="always"' if fn in inline else "")
        helpers = (spliced or {}).get(fn)
        text = spliced_source(fn, helpers) if helpers else textwrap.dedent(inspect.getsource(fn))
        parts.append(f"@numba.njit({options})\n{text}")
    return "\n\n".join(parts)


#: the member-by-member integrator with the step functions it shares with the lane integrator (entry points
#: ``run_chunk``, ``run_chunk_stats``); :func:`plant.compose.generate_source` puts it in every kernel module
INTEGRATOR_SOURCE = kernel_source(integrate_steps.FUNCTIONS + integrate_scalar.FUNCTIONS,
                                  integrate_steps.INLINE + integrate_scalar.INLINE, integrate_scalar.SPLICED)
#: the lane integrator (entry point ``run_lanes``), after :data:`INTEGRATOR_SOURCE` in a kernel module with a lane
#: form
LANE_INTEGRATOR_SOURCE = kernel_source(integrate_lanes.FUNCTIONS, integrate_lanes.INLINE, integrate_lanes.SPLICED)

__all__ = ["INTEGRATOR_SOURCE", "LANES", "LANE_INTEGRATOR_SOURCE", "TABLEAU_NAMES", "IntegrationFailed",
           "IntegrationStatus", "kernel_source"]
