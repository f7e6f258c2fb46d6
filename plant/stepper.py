"""Step a plant through time in short intervals (a rig or a board tick), keeping its state between calls."""

from __future__ import annotations

import numpy as np

from plant import layout as L
from plant.model import PlantModel


class PlantStepper:
    """Advance a (batch of) trajectories interval by interval with low per-call overhead.

    ``advance(u, dt)`` integrates from the current time over ``dt`` seconds with the inputs ``u`` sampled
    uniformly across the interval (shape ``(samples, 3)`` or ``(batch, samples, 3)``, at least two
    samples: the start and end values; inputs in SI units ``v_ch1`` V, ``v_ch2`` V, ``z0dd`` m/s^2) and
    returns the outputs at the end, shape ``(batch, n_outputs)``.
    """

    def __init__(self, model: PlantModel, params: np.ndarray | None = None, x0: np.ndarray | None = None,
                 rtol: float = 1e-6, h_max: float = 5e-3) -> None:
        self.model = model
        p = model.p_nominal[None] if params is None else np.atleast_2d(np.asarray(params, dtype=float))
        self.p = np.array(p, dtype=float, order="C")
        batch = self.p.shape[0]
        xs = model.x0_nominal[None] if x0 is None else np.atleast_2d(np.asarray(x0, dtype=float))
        self.x = np.array(np.broadcast_to(xs, (batch, model.n_states)), dtype=float, order="C")
        self.t = 0.0
        self.rtol = float(rtol)
        self.h_max = float(h_max)
        self._atol = np.array(model.state_scales * rtol, dtype=float, order="C")
        self._y = np.zeros((batch, 2, model.n_outputs))
        self._xs = np.zeros((batch, 2, model.n_states))
        self._bs = np.zeros((batch, 2, L.N_BUS))
        self._status = np.zeros(batch, dtype=np.int64)
        self._nsteps = np.zeros(batch, dtype=np.int64)
        self._run = model.kernels().run_chunk
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
        self._run(0, self.batch, self.x, self.p, u, self.t, u_dt, t_out, self.rtol, self._atol,
                  min(self.h_max, dt), 1e-14, 10_000_000, self._y, self._xs, self._bs, True, True,
                  self._status, self._nsteps)
        if np.any(self._status != 0):
            bad = int(np.flatnonzero(self._status)[0])
            raise FloatingPointError(f"plant integration failed at t={self.t:.6g} s for batch member {bad} "
                                     f"(status {int(self._status[bad])})")
        self.x[:] = self._xs[:, -1, :]
        self.t += dt
        self.total_steps += int(self._nsteps.sum())
        return self._y[:, -1, :]
