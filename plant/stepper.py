"""The plant's one integration seam: every call of a composition's compiled batch integrator goes through here.

* :class:`Integrator` — the only caller of the compiled ``run_chunk`` / ``run_chunk_stats`` (kernel source in
  :mod:`plant.integrate`). It owns the integrator's constants (``h_min``, the step budget), the absolute tolerances
  and the status buffers, and reports a failed interval as :class:`~plant.integrate.IntegrationFailed` (a
  ``FloatingPointError`` carrying the :class:`~plant.integrate.IntegrationStatus`, the batch member and the time)
  instead of a raw status code. ``batch`` runs a whole batch (threads, rejection counts; statuses are returned
  per member, as :meth:`plant.PlantModel.simulate` reports them); ``interval`` integrates one interval into
  caller-owned buffers with no allocation (a rig, a stepper, an observer: one call per tick).
* :class:`PlantStepper` — a batch of trajectories advanced interval by interval, keeping its state between calls.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from types import ModuleType
from typing import Any, Protocol

import numpy as np

from plant import layout as L
from plant.compose import announce_if_cold
from plant.integrate import IntegrationFailed, IntegrationStatus


class ComposedModel(Protocol):
    """What the integration seam needs of a model (:class:`plant.PlantModel` is one): its compiled kernel module,
    sizes, state scales (set the absolute tolerances) and nominal parameters and start state."""

    n_states: int
    n_outputs: int
    state_scales: np.ndarray
    p_nominal: np.ndarray
    x0_nominal: np.ndarray

    def kernels(self) -> ModuleType: ...

#: smallest step (s) before an integration stops with ``STEP_TOO_SMALL``
H_MIN = 1e-14
#: attempted steps per trajectory and call before an integration stops with ``TOO_MANY_STEPS``
MAX_STEPS = 50_000_000
#: smallest batch integrated by the lane integrator (groups of ``LANES`` members sharing a step size, SIMD across
#: members); smaller batches, and compositions whose hooks have no lane form, go member by member
LANE_MIN_BATCH = 16
#: work items per thread when a batch is split over threads (a thread that finishes early takes the next item)
ITEMS_PER_THREAD = 4


def default_threads() -> int:
    """Threads used to integrate a batch (``$MFC_SHM_THREADS``, else the number of CPUs)."""
    env = os.environ.get("MFC_SHM_THREADS")
    return max(1, int(env)) if env else max(1, os.cpu_count() or 1)


@dataclass
class BatchRun:
    """What :meth:`Integrator.batch` produced: outputs ``y[b, k, j]`` at the output times, the recorded states and
    bus (or ``None``), and per member the status code, attempted and rejected steps."""

    y: np.ndarray
    states: np.ndarray | None
    bus: np.ndarray | None
    status: np.ndarray
    n_steps: np.ndarray
    n_rejected: np.ndarray


def work_items(batch: int, n_items: int, unit: int = 1) -> list[int]:
    """Edges of at most ``n_items`` contiguous work items covering ``0 .. batch``, each a multiple of ``unit``
    members (but the last), as even as that allows."""
    n_units = -(-batch // unit)
    n_items = max(1, min(n_items, n_units))
    edges = [min(batch, unit * int(e)) for e in np.linspace(0, n_units, n_items + 1).round()]
    return sorted(set(edges))


class Integrator:
    """The compiled batch integrator of one composition, at relative tolerance ``rtol`` and absolute tolerances
    ``atol`` per state (default: the model's state scales × ``rtol``)."""

    def __init__(self, model: ComposedModel, rtol: float = 1e-6, atol: np.ndarray | None = None,
                 max_steps: int = MAX_STEPS) -> None:
        kernels = model.kernels()
        self._kernels = kernels
        self._run = kernels.run_chunk
        self._run_stats = kernels.run_chunk_stats
        self._run_lanes: Any = kernels.run_lanes if getattr(kernels, "HAS_LANES", False) else None
        self.lanes = int(getattr(kernels, "LANES", 1))
        self.n_states = model.n_states
        self.n_outputs = model.n_outputs
        self.rtol = float(rtol)
        self.atol = np.array(model.state_scales * rtol if atol is None else
                             np.broadcast_to(np.asarray(atol, float), (model.n_states,)), dtype=float, order="C")
        self.max_steps = int(max_steps)
        self._status = np.zeros(1, dtype=np.int64)
        self._nsteps = np.zeros(1, dtype=np.int64)
        self._no_bus = np.zeros((1, 1, 1))

    def uses_lanes(self, batch: int, lanes: bool | None = None) -> bool:
        """Whether a batch of ``batch`` members goes to the lane integrator (``lanes``: force on/off; None: when
        the composition has a lane form and ``batch >= LANE_MIN_BATCH``)."""
        if self._run_lanes is None or lanes is False:
            return False
        return bool(lanes) or batch >= LANE_MIN_BATCH

    def batch(self, x0: np.ndarray, p: np.ndarray, u: np.ndarray, u_t0: float, u_dt: float, t_out: np.ndarray,
              h_max: float, *, record_states: bool = False, record_bus: bool = False, threads: int = 1,
              lanes: bool | None = None) -> BatchRun:
        """Integrate ``batch = p.shape[0]`` trajectories (``x0`` (batch, n_states), ``p`` (batch, n_params), C
        order; inputs ``u`` (1 or batch, samples, 3) on the grid ``u_t0 + k u_dt``) to the output times ``t_out``
        (``t_out[0]`` is the start), split over ``threads`` threads. A failed member has its status set and NaN
        outputs from where it stopped; nothing is raised (see :func:`failure_of`). ``lanes`` selects the lane
        integrator (:meth:`uses_lanes`): members in groups sharing a step size, at least as accurate as alone."""
        batch = p.shape[0]
        y = np.empty((batch, t_out.size, self.n_outputs))
        xs = np.empty((batch, t_out.size, self.n_states)) if record_states else np.empty((1, 1, 1))
        bs = np.empty((batch, t_out.size, L.N_BUS)) if record_bus else np.empty((1, 1, 1))
        status = np.zeros(batch, dtype=np.int64)
        nsteps = np.zeros(batch, dtype=np.int64)
        nrej = np.zeros(batch, dtype=np.int64)
        use_lanes = self.uses_lanes(batch, lanes)
        if use_lanes:
            announce_if_cold(self._kernels, "run_lanes")  # its first call compiles for tens of seconds
        run = self._run_lanes if use_lanes else self._run_stats
        args = (x0, p, u, float(u_t0), float(u_dt), t_out, self.rtol, self.atol, float(h_max), H_MIN,
                self.max_steps, y, xs, bs, bool(record_states), bool(record_bus), status, nsteps, nrej)
        unit = self.lanes if use_lanes else 1
        n_threads = min(threads, -(-batch // unit))
        if n_threads <= 1:
            run(0, batch, *args)
        else:
            edges = work_items(batch, n_threads * ITEMS_PER_THREAD, unit)
            with ThreadPoolExecutor(n_threads) as pool:
                list(pool.map(lambda k: run(int(edges[k]), int(edges[k + 1]), *args), range(len(edges) - 1)))
        return BatchRun(y, xs if record_states else None, bs if record_bus else None, status, nsteps, nrej)

    def interval(self, x0: np.ndarray, p: np.ndarray, u: np.ndarray, u_t0: float, u_dt: float, t_out: np.ndarray,
                 h_max: float, y: np.ndarray, xs: np.ndarray, bs: np.ndarray | None = None, *,
                 what: str = "plant") -> int:
        """Integrate the batch ``p.shape[0]`` from ``x0`` over ``t_out`` into ``y`` (batch, len(t_out),
        n_outputs) and ``xs`` (batch, len(t_out), n_states) (and the bus into ``bs`` if given); the states at
        ``t_out[-1]`` are exact (ready to continue from). Returns the attempted steps; raises
        :class:`IntegrationFailed` (naming ``what``) if a member stops early."""
        n = p.shape[0]
        if self._status.shape[0] != n:
            self._status = np.zeros(n, dtype=np.int64)
            self._nsteps = np.zeros(n, dtype=np.int64)
        status = self._status
        nsteps = self._nsteps
        self._run(0, n, x0, p, u, u_t0, u_dt, t_out, self.rtol, self.atol, h_max, H_MIN, self.max_steps, y, xs,
                  self._no_bus if bs is None else bs, True, bs is not None, status, nsteps)
        if n == 1:
            if status[0] != 0:
                raise _failed(what, 0, int(status[0]), float(t_out[0]))
            return int(nsteps[0])
        if np.any(status != 0):
            bad = int(np.flatnonzero(status)[0])
            raise _failed(what, bad, int(status[bad]), float(t_out[0]))
        return int(nsteps.sum())


def _failed(what: str, member: int, code: int, t: float) -> IntegrationFailed:
    status = IntegrationStatus(code)
    return IntegrationFailed(f"{what} integration failed at t={t:.6g} s for batch member {member}: {status.message} "
                             f"(status {code})", status, member, t)


def failure_of(status: np.ndarray, t_out: np.ndarray, y: np.ndarray, message: str) -> IntegrationFailed | None:
    """The :class:`IntegrationFailed` of a batch run's first failed member (``None`` if all succeeded), with
    ``message``; its time is the last output time the member reached."""
    bad = np.flatnonzero(status)
    if bad.size == 0:
        return None
    b = int(bad[0])
    finite = np.flatnonzero(np.all(np.isfinite(y[b]), axis=-1)) if y.shape[0] > b else np.zeros(0, dtype=int)
    reached = int(finite[-1]) if finite.size else 0
    return IntegrationFailed(message, int(status[b]), b, float(t_out[min(reached, t_out.size - 1)]))


class PlantStepper:
    """Advance a (batch of) trajectories interval by interval with low per-call overhead.

    ``advance(u, dt)`` integrates from the current time over ``dt`` seconds with the inputs ``u`` sampled
    uniformly across the interval (shape ``(samples, 3)`` or ``(batch, samples, 3)``, at least two
    samples: the start and end values; inputs in SI units ``v_ch1`` V, ``v_ch2`` V, ``z0dd`` m/s^2) and
    returns the outputs at the end, shape ``(batch, n_outputs)``. A failed interval (non-finite state, step below
    ``H_MIN``, more than ``max_steps`` attempted steps in it) raises :class:`~plant.integrate.IntegrationFailed` (a
    ``FloatingPointError``).
    """

    def __init__(self, model: ComposedModel, params: np.ndarray | None = None, x0: np.ndarray | None = None,
                 rtol: float = 1e-6, h_max: float = 5e-3, max_steps: int = MAX_STEPS) -> None:
        self.model = model
        p = model.p_nominal[None] if params is None else np.atleast_2d(np.asarray(params, dtype=float))
        self.p = np.array(p, dtype=float, order="C")
        batch = self.p.shape[0]
        xs = model.x0_nominal[None] if x0 is None else np.atleast_2d(np.asarray(x0, dtype=float))
        self.x = np.array(np.broadcast_to(xs, (batch, model.n_states)), dtype=float, order="C")
        self.t = 0.0
        self.rtol = float(rtol)
        self.h_max = float(h_max)
        self._integrator = Integrator(model, rtol, max_steps=max_steps)
        self._y = np.zeros((batch, 2, model.n_outputs))
        self._xs = np.zeros((batch, 2, model.n_states))
        self._bs = np.zeros((batch, 2, L.N_BUS))
        self.total_steps = 0

    @property
    def batch(self) -> int:
        return self.p.shape[0]

    def outputs(self) -> np.ndarray:
        """Outputs at the current time, shape (batch, n_outputs) (for the last advanced interval)."""
        return self._y[:, -1, :].copy()

    def bus(self) -> np.ndarray:
        """Signal bus at the end of the last interval, shape (batch, N_BUS)."""
        return self._bs[:, -1, :].copy()

    def advance(self, u: np.ndarray, dt: float) -> np.ndarray:
        u = np.asarray(u, dtype=float)
        if u.ndim == 2:
            u = u[None]
        if u.ndim != 3 or u.shape[2] != L.N_INPUTS or u.shape[1] < 2 or u.shape[0] not in (1, self.batch):
            raise ValueError(f"inputs must have shape (samples>=2, {L.N_INPUTS}) or (batch, samples, "
                             f"{L.N_INPUTS}); got {u.shape}")
        if not dt > 0:
            raise ValueError(f"dt must be positive, got {dt!r}")
        u = np.ascontiguousarray(u)
        t_out = np.array([self.t, self.t + dt])
        u_dt = dt / (u.shape[1] - 1)
        self.total_steps += self._integrator.interval(self.x, self.p, u, self.t, u_dt, t_out, min(self.h_max, dt),
                                                      self._y, self._xs, self._bs)
        self.x[:] = self._xs[:, -1, :]
        self.t += dt
        return self._y[:, -1, :]
