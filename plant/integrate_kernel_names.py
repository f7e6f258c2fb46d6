"""The names a composition's generated kernel module defines, as the integrator templates see them.

The integrators (:mod:`plant.integrate_steps`, :mod:`plant.integrate_scalar`, :mod:`plant.integrate_lanes`) are
ordinary functions that ruff and mypy read. :mod:`plant.compose` copies their source into the kernel module it
generates for a composition, next to what only the composition knows: its right-hand side and outputs (``rhs``,
``out``, their lane forms ``rhs_lanes``, ``out_lanes``), its sizes and the rows of the lane work array. Those names
are declared here — with their types, so that the templates type-check — and bound for real in the generated
module, where numba compiles the copied functions against them. Nothing here is ever called: the declarations
raise, the sizes are those of no composition (0).
"""

from __future__ import annotations

from typing import Final

import numpy as np
from numpy.typing import NDArray

#: float64 arrays of one, two and three dimensions; int64 and bool vectors
Vector = NDArray[np.float64]
Matrix = NDArray[np.float64]
Array3 = NDArray[np.float64]
IntVector = NDArray[np.int64]
BoolVector = NDArray[np.bool_]
#: a batch member's index (numba passes ``np.int64``)
Index = int | np.int64

#: batch members integrated together by the lane integrator (one SIMD register of float64 on AVX-512); the same
#: for every composition
LANES: Final = 16

# --- bound per composition by plant.compose ----------------------------------------------------------------------
#: numba's on-disk cache on/off (off for a composition compiled in memory)
CACHE: Final = False
#: states, signal-bus entries, parameters and outputs of the composition
N_STATES: Final = 0
N_BUS: Final = 0
N_PARAMS: Final = 0
N_OUTPUTS: Final = 0
#: rows of the lane work array ``W`` (row r, lane l at ``W[r * LANES + l]``) and where each block of rows starts:
#: states, parameters, bus, derivatives, outputs, inputs, absolute tolerances, the step's start state, the seven
#: stages, the 5th-order solution, the error norm and state sum per lane, the lane's alive mask
W_ROWS: Final = 0
ROW_x: Final = 0
ROW_p: Final = 0
ROW_bus: Final = 0
ROW_dx: Final = 0
ROW_y: Final = 0
ROW_u: Final = 0
ROW_atol: Final = 0
ROW_xc: Final = 0
ROW_k1: Final = 0
ROW_k2: Final = 0
ROW_k3: Final = 0
ROW_k4: Final = 0
ROW_k5: Final = 0
ROW_k6: Final = 0
ROW_k7: Final = 0
ROW_xn: Final = 0
ROW_err: Final = 0
ROW_tot: Final = 0
ROW_alive: Final = 0


def _bound_in_the_kernel_module() -> RuntimeError:
    return RuntimeError("bound by plant.compose in a composition's generated kernel module, not callable here")


def rhs(t: float, x: Vector, p: Vector, u: Vector, bus: Vector, dx: Vector) -> None:
    """The composed right-hand side: ``dx`` (and the bus) at time ``t`` (s), state ``x``, parameters ``p``,
    inputs ``u``."""
    raise _bound_in_the_kernel_module()


def out(t: float, x: Vector, p: Vector, u: Vector, bus: Vector, dx: Vector, y: Vector) -> None:
    """The composed outputs ``y`` at one state (after the right-hand side)."""
    raise _bound_in_the_kernel_module()


def rhs_lanes(t: float, W: Vector) -> None:
    """The right-hand side of ``LANES`` members at the states in the ``ROW_x`` rows, into the ``ROW_dx`` rows."""
    raise _bound_in_the_kernel_module()


def out_lanes(t: float, W: Vector) -> None:
    """The outputs of ``LANES`` members into the ``ROW_y`` rows."""
    raise _bound_in_the_kernel_module()
