"""Where the board's own monitor trips: P(FAULT | deviations) from the campaign's machinery, as a boundary.

The campaign (``studies.campaign``) simulates MBIT.a and MBIT.b for a batch of parameter deviations and runs the
board's monitor (Eq. 11, Table 3 thresholds from ``board_config/monitor.toml``, the +2/−1 counter) on each: a FAULT
if either MBIT latches. :func:`fault_batch` is that, for any deviation vectors (k3, α_h, β_h relative deviations).

With table2 the verdict is set almost entirely by α_h (docs/monitor.md): at fixed (k3, β_h) the laminate passes for
α_h inside an interval and faults outside it. :class:`TripBoundary` finds that interval's ends by batched bisection
(12 halvings: 0.015 % of α_h) at every node of a (k3, β_h) grid, caches them on disk (keyed by the parameter set,
the MBITs and the monitor settings) and interpolates between nodes. A forecast then asks, for thousands of sampled
parameter paths, whether the boundary is crossed — without thousands of simulations.
"""

from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

HEALTH_PARAMS: tuple[str, ...] = ("k3", "alpha_h", "beta_h")
K3_GRID = (-0.6, -0.45, -0.3, -0.15, 0.0, 0.15, 0.3)
BETA_GRID = (-0.6, -0.3, 0.0, 0.3, 0.6)
ALPHA_SPAN = (-0.6, 0.6)
N_HALVINGS = 12
NOISE_STD_M = 2e-6  # the rig's laser noise (1 sigma), as the board sees it
# The MBIT batches integrate on the threads every batch uses (``threads=None``: ``$MFC_SHM_THREADS``, else the CPU
# count), not a fixed 2: inside a Dask task a worker is one core and its warm-up sets one thread per task
# (studies.batch.warm), so two threads there competed with the next worker's task for the same core.


def _cache_dir() -> Path:
    base = os.environ.get("MFC_SHM_CACHE") or os.path.join(os.path.expanduser("~"), ".cache", "mfc-shm")
    return Path(base) / "health"


def fault_batch_values(params: str, columns: dict[str, np.ndarray], effects: tuple[str, ...] = (), seed: int = 1
                       ) -> np.ndarray:
    """The board monitor's verdict (True = FAULT) for truth plants given by parameter ``columns`` (SI values by
    name, core parameters or the parameters of the added ``effects``; the rest nominal), through the campaign's MBIT
    simulation and monitor. The monitor's own model is the nominal ``params`` (it knows no added effect)."""
    from firmware_sim.condition_monitor import evaluate, normalised_error
    from plant import PlantModel
    from studies.campaign.build import build_spec
    from studies.campaign.worker import mbit_sequence, nominal_prediction

    spec = build_spec(params, mbits="both", ranges="0:10:10", n_runs=1, seed=seed, noise_std=NOISE_STD_M)
    model = PlantModel(params, effects=list(effects))
    n = len(next(iter(columns.values())))
    batch = model.param_batch(n=n, **{k: np.asarray(v, float) for k, v in columns.items()})
    rng = np.random.default_rng(seed)
    fault = np.zeros(n, bool)
    for defn in spec.mbits:
        t, z3_model = nominal_prediction(spec, defn)
        res = model.simulate(mbit_sequence(defn).to_inputs(), dt_out=1.0 / spec.monitor.f_mon, params=batch,
                             rtol=spec.rtol, threads=None)
        z3 = np.array(res["z3_meas"], dtype=float) + rng.normal(0.0, NOISE_STD_M, (n, t.size))
        eps = normalised_error(z3_model[None, :], z3, spec.monitor.e0z, spec.monitor.kerr_z)
        fault |= evaluate(eps, spec.monitor, t).detected & (res.status == 0)
    return fault


def effect_trip_limit(params: str, effect: str, parameter: str, upper: float, *, use_cache: bool = True) -> float:
    """The value of an added effect's ``parameter`` (SI, from 0 up to ``upper``) at which the monitor first trips,
    the laminate otherwise nominal (12 halvings; inf when ``upper`` does not trip). Cached like the boundary."""
    key = hashlib.sha256((_key(params) + effect + parameter + repr(upper)).encode()).hexdigest()[:16]
    path = _cache_dir() / f"trip-effect-{key}.json"
    if use_cache and path.exists():
        v = json.loads(path.read_text())["limit"]
        return float("inf") if v is None else float(v)
    lo, hi = 0.0, float(upper)
    limit = float("inf")
    if fault_batch_values(params, {parameter: np.array([hi])}, (effect,))[0]:
        for _ in range(N_HALVINGS):
            mid = 0.5 * (lo + hi)
            if fault_batch_values(params, {parameter: np.array([mid])}, (effect,))[0]:
                hi = mid
            else:
                lo = mid
        limit = 0.5 * (lo + hi)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps({"limit": None if not np.isfinite(limit) else limit, "effect": effect,
                                    "parameter": parameter, "params": params}))
    except OSError:
        pass
    return limit


def fault_batch(params: str, devs: np.ndarray, seed: int = 1) -> np.ndarray:
    """The board monitor's verdict (True = FAULT by MBIT.a or MBIT.b) for each row of relative deviations
    ``devs`` (n, 3) of (k3, α_h, β_h), through the campaign worker's simulation and monitor."""
    from firmware_sim.condition_monitor import evaluate, normalised_error
    from studies.campaign.build import build_spec
    from studies.campaign.worker import mbit_sequence, model_from_toml, nominal_prediction

    spec = build_spec(params, mbits="both", ranges="0:10:10", n_runs=1, seed=seed, noise_std=NOISE_STD_M)
    model = model_from_toml(spec.params_toml)
    devs = np.atleast_2d(np.asarray(devs, dtype=float))
    nominal = np.array([model.param_value(n) for n in HEALTH_PARAMS])
    values = nominal[None, :] * (1.0 + devs)
    batch = model.param_batch(n=devs.shape[0], **{n: values[:, j] for j, n in enumerate(HEALTH_PARAMS)})
    rng = np.random.default_rng(seed)
    fault = np.zeros(devs.shape[0], bool)
    for defn in spec.mbits:
        t, z3_model = nominal_prediction(spec, defn)
        res = model.simulate(mbit_sequence(defn).to_inputs(), dt_out=1.0 / spec.monitor.f_mon, params=batch,
                             rtol=spec.rtol, threads=None)
        z3 = np.array(res["z3_meas"], dtype=float) + rng.normal(0.0, NOISE_STD_M, (devs.shape[0], t.size))
        eps = normalised_error(z3_model[None, :], z3, spec.monitor.e0z, spec.monitor.kerr_z)
        fault |= evaluate(eps, spec.monitor, t).detected & (res.status == 0)
    return fault


#: points interpolated at once by :meth:`TripBoundary.fault`: a forecast asks for 3 million (2000 paths × 1500
#: times); in slices the interpolation's temporaries are a few MB, not ~0.5 GB that a fresh process (each Dask
#: worker's first board) faults in page by page, and stay in the CPU's cache beside another worker's task — each
#: point's result is the same (the interpolation is point by point)
FAULT_SLICE = 1 << 16


@dataclass
class TripBoundary:
    """α_h relative deviations at which the monitor trips, below (``lo``) and above (``hi``), on a (k3, β_h) grid."""

    k3: np.ndarray
    beta: np.ndarray
    lo: np.ndarray  # (n_k3, n_beta); -inf where no fault down to the span's end
    hi: np.ndarray  # (n_k3, n_beta); +inf where no fault up to the span's end
    key: str

    def _interp(self, grid: np.ndarray, k3: np.ndarray, beta: np.ndarray) -> np.ndarray:
        from scipy.interpolate import RegularGridInterpolator

        g = np.where(np.isfinite(grid), grid, np.sign(grid) * 10.0)
        f = RegularGridInterpolator((self.k3, self.beta), g, bounds_error=False, fill_value=None)
        pts = np.column_stack([np.clip(k3, self.k3[0], self.k3[-1]), np.clip(beta, self.beta[0], self.beta[-1])])
        return f(pts)

    def alpha_limits(self, k3_dev: np.ndarray, beta_dev: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        k3_dev, beta_dev = np.asarray(k3_dev, float).ravel(), np.asarray(beta_dev, float).ravel()
        return self._interp(self.lo, k3_dev, beta_dev), self._interp(self.hi, k3_dev, beta_dev)

    def fault(self, devs: np.ndarray) -> np.ndarray:
        """FAULT (bool) for relative deviations (..., 3) of (k3, α_h, β_h), :data:`FAULT_SLICE` points at a time."""
        d = np.asarray(devs, float)
        flat = d.reshape(-1, 3)
        out = np.empty(flat.shape[0], bool)
        for s in range(0, flat.shape[0], FAULT_SLICE):
            part = flat[s:s + FAULT_SLICE]
            lo, hi = self.alpha_limits(part[:, 0], part[:, 2])
            out[s:s + FAULT_SLICE] = (part[:, 1] >= hi) | (part[:, 1] <= lo)
        return out.reshape(d.shape[:-1])

    def margin(self, devs: np.ndarray) -> np.ndarray:
        """Distance (relative α_h) to the nearest trip limit; negative beyond it."""
        flat = np.asarray(devs, float).reshape(-1, 3)
        lo, hi = self.alpha_limits(flat[:, 0], flat[:, 2])
        return np.minimum(hi - flat[:, 1], flat[:, 1] - lo).reshape(np.asarray(devs).shape[:-1])


def _key(params: str) -> str:
    from board_config import load_mbit_definitions, load_monitor_settings, load_parameter_set

    text = load_parameter_set(params).to_toml() + repr(load_monitor_settings()) + repr(
        sorted(load_mbit_definitions().items())) + repr((K3_GRID, BETA_GRID, ALPHA_SPAN, N_HALVINGS, NOISE_STD_M))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def trip_boundary(params: str = "table2", *, use_cache: bool = True) -> TripBoundary:
    """The monitor's α_h trip limits over the (k3, β_h) grid (computed once per parameter set, then cached)."""
    key = _key(params)
    path = _cache_dir() / f"trip-{key}.json"
    if use_cache and path.exists():
        d = json.loads(path.read_text())
        return TripBoundary(np.array(d["k3"]), np.array(d["beta"]), np.array(d["lo"], float),
                            np.array(d["hi"], float), key)
    kk, bb = np.meshgrid(np.array(K3_GRID), np.array(BETA_GRID), indexing="ij")
    nodes = np.column_stack([kk.ravel(), bb.ravel()])
    n = nodes.shape[0]
    # side 0: alpha decreasing (lo), side 1: alpha increasing (hi); bracket [inside, outside]
    inside = np.zeros(2 * n)
    outside = np.concatenate([np.full(n, ALPHA_SPAN[0]), np.full(n, ALPHA_SPAN[1])])
    both = np.concatenate([nodes, nodes])

    def rows(alpha: np.ndarray) -> np.ndarray:
        return np.column_stack([both[:, 0], alpha, both[:, 1]])

    f_in = fault_batch(params, rows(inside))
    f_out = fault_batch(params, rows(outside))
    for _ in range(N_HALVINGS):
        mid = 0.5 * (inside + outside)
        f = fault_batch(params, rows(mid))
        outside = np.where(f, mid, outside)
        inside = np.where(f, inside, mid)
    limit = np.where(f_in, 0.0, np.where(f_out, 0.5 * (inside + outside), np.sign(outside) * np.inf))
    lo = limit[:n].reshape(kk.shape)
    hi = limit[n:].reshape(kk.shape)
    tb = TripBoundary(np.array(K3_GRID), np.array(BETA_GRID), lo, hi, key)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(".tmp")
        tmp.write_text(json.dumps({"k3": list(K3_GRID), "beta": list(BETA_GRID),
                                   "lo": [[x if np.isfinite(x) else None for x in r] for r in lo.tolist()],
                                   "hi": [[x if np.isfinite(x) else None for x in r] for r in hi.tolist()],
                                   "params": params}))
        tmp.replace(path)
    except OSError:
        pass
    return tb
