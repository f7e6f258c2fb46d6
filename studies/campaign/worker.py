"""One campaign task: simulate a batch of degraded units through every MBIT and run the monitor on them.

:func:`run_batch` is a module-level function of plain picklable arguments, so the same call runs in-process, in a
local process pool or on a Dask worker. The model is rebuilt from the parameter set's TOML text (no shared file
system needed) and cached per process, as are the MBIT sequences and the nominal predictions.

Per MBIT: the nominal model's ``z3`` (the prediction ``z3_md``) and each degraded unit's ``z3_meas`` (the
"hardware" response, as its laser reports it; plus optional white noise) are sampled at the monitor rate
``f_mon``; Eq. 11 gives the normalised error and the vectorised monitor (``condition_monitor.evaluate``) the
verdict. All units' trajectories of one MBIT are one batched integration (``PlantModel.simulate``).
"""

from __future__ import annotations

import hashlib
import os
import socket
import tempfile
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from board_config import MbitDefinition, load_parameter_set
from firmware_sim.condition_monitor import evaluate, normalised_error
from firmware_sim.mbit import MbitSequence, generate_mbit
from plant import PlantModel
from studies.campaign.spec import BatchSpec, CampaignSpec, draw_deviations, noise_generator

_LOCK = threading.Lock()
_MODELS: dict[str, PlantModel] = {}
_SEQUENCES: dict[MbitDefinition, MbitSequence] = {}
_NOMINAL: dict[tuple, tuple[np.ndarray, np.ndarray]] = {}


@dataclass
class BatchResult:
    """A finished batch: named arrays (see :func:`run_batch`) plus where and how long it ran."""

    key: str
    arrays: dict[str, np.ndarray]
    elapsed_s: float  # wall time of the task (s)
    worker: str
    cpu_s: float = 0.0  # CPU time of the task's process (s; all its threads)


def model_from_toml(text: str) -> PlantModel:
    """The plant model of a serialised parameter set (cached per process; kernels loaded)."""
    digest = hashlib.sha256(text.encode()).hexdigest()
    with _LOCK:
        model = _MODELS.get(digest)
        if model is None:
            with tempfile.TemporaryDirectory(prefix="mfc-shm-campaign-") as tmp:
                path = Path(tmp) / "params.toml"
                path.write_text(text)
                model = PlantModel(load_parameter_set(path))
            model.kernels()
            _MODELS[digest] = model
    return model


def mbit_sequence(defn: MbitDefinition) -> MbitSequence:
    """The clamped command sequence of an MBIT (the clamp report is surfaced by the campaign runner)."""
    with _LOCK:
        seq = _SEQUENCES.get(defn)
        if seq is None:
            seq = generate_mbit(defn, on_clamp="report")
            _SEQUENCES[defn] = seq
    return seq


def nominal_prediction(spec: CampaignSpec, defn: MbitDefinition) -> tuple[np.ndarray, np.ndarray]:
    """Monitor sample times (s) and the nominal model's ``z3`` (m) for an MBIT."""
    key = (hashlib.sha256(spec.params_toml.encode()).hexdigest(), defn, spec.monitor.f_mon, spec.rtol)
    with _LOCK:
        hit = _NOMINAL.get(key)
    if hit is None:
        model = model_from_toml(spec.params_toml)
        res = model.simulate(mbit_sequence(defn).to_inputs(), dt_out=1.0 / spec.monitor.f_mon, rtol=spec.rtol,
                             threads=1)
        res.raise_on_failure(f"nominal {defn.label} simulation failed: ")
        hit = (res.t.copy(), res["z3"][0].copy())
        with _LOCK:
            _NOMINAL[key] = hit
    return hit


def run_batch(batch: BatchSpec, threads: int | None = 1) -> BatchResult:
    """Simulate and monitor runs ``[run_start, run_stop)`` of one deviation range for every MBIT.

    Arrays (``n`` runs, ``T`` monitor samples; per MBIT ``m`` the prefix is ``mbit_<m>_``):
    ``run_index`` (n), ``rel_dev`` (n, P) relative deviations, ``values`` (n, P) deviated parameter values (SI),
    ``<m>t_s`` (T), ``<m>z3_model_m`` (T), ``<m>z3_meas_m`` (n, T), ``<m>eps`` (n, T), ``<m>fault`` (n),
    ``<m>fault_time_s`` (n, NaN if none), ``<m>max_count`` (n), ``<m>max_eps`` (n), ``<m>status`` (n; 0 = ok).
    """
    t0 = time.perf_counter()
    c0 = time.process_time()
    spec = batch.campaign
    model = model_from_toml(spec.params_toml)
    runs = np.arange(batch.run_start, batch.run_stop, dtype=np.int64)
    rel = draw_deviations(spec.seed, batch.range, runs, len(spec.deviated), spec.sign)
    nominal = np.array([model.param_value(n) for n in spec.deviated])
    values = nominal[None, :] * (1.0 + rel)
    params = model.param_batch(n=runs.size, **{name: values[:, j] for j, name in enumerate(spec.deviated)})
    arrays: dict[str, np.ndarray] = {"run_index": runs, "range_index": np.full(runs.size, batch.range_index),
                                     "rel_dev": rel, "values": values}
    for defn in spec.mbits:
        t, z3_model = nominal_prediction(spec, defn)
        res = model.simulate(mbit_sequence(defn).to_inputs(), dt_out=1.0 / spec.monitor.f_mon, params=params,
                             rtol=spec.rtol, threads=threads)
        z3_meas = np.array(res["z3_meas"], dtype=float)
        if spec.noise_std > 0:
            for row, i in enumerate(runs):
                rng = noise_generator(spec.seed, batch.range, int(i), defn.key)
                z3_meas[row] += rng.normal(0.0, spec.noise_std, z3_meas.shape[1])
        eps = normalised_error(z3_model[None, :], z3_meas, spec.monitor.e0z, spec.monitor.kerr_z)
        trace = evaluate(eps, spec.monitor, t)
        p = f"mbit_{defn.key}_"
        arrays.update({
            p + "t_s": t, p + "z3_model_m": z3_model, p + "z3_meas_m": z3_meas, p + "eps": eps,
            p + "fault": trace.detected, p + "fault_time_s": trace.fault_time, p + "max_count": trace.max_count,
            p + "max_eps": np.max(np.where(np.isfinite(eps), eps, 0.0), axis=1, initial=0.0),
            p + "status": res.status.astype(np.int64),
        })
    return BatchResult(batch.key, arrays, time.perf_counter() - t0, f"{socket.gethostname()}:{os.getpid()}",
                       time.process_time() - c0)
