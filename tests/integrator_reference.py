"""Reference runs of the compiled batch integrators, stored in ``tests/data/integrator_reference.npz``.

Issue 30 (point 3) rewrote the integrators from source text into ordinary functions; they must give bit for bit what
the string-literal integrators gave: outputs, recorded states and bus, status codes, attempted and rejected steps.
The fixture was written with the integrators as they were before that rewrite (commit before "integrators as code")
and is kept: any later change to the integrators that moves a bit fails ``tests/plant/test_integrator_reference.py``.

Each case calls a kernel entry point (``run_chunk_stats``, ``run_chunk``, ``run_lanes``) directly with its stored
inputs, so the fixture depends on nothing but the integrator and the composed right-hand side: the member-by-member
and the lane integrator, shared and per-member inputs, a one-sample input, non-uniform output times, a padded lane
group, a work item that starts inside the batch, a parameter branch that differs between members, and every
failure status (diverged, step too small, step budget, with the lane group's rerun alone).

Regenerate (only on purpose, when the integrator's numbers are meant to change):
``.venv/bin/python tests/integrator_reference.py`` (writes the fixture).
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import numpy as np

FIXTURE = Path(__file__).parent / "data" / "integrator_reference.npz"
#: compositions: name -> (extra library effects on table2, their parameters away from neutral)
COMPOSITIONS: dict[str, tuple[tuple[str, ...], dict[str, float]]] = {
    "nominal": ((), {}),
    "piezo_creep": (("piezo_creep",), {"gamma_creep": 0.1, "tau_creep": 0.05}),  # six more states
}
INPUT_FIELDS = ("x0", "p", "u", "t_out", "settings")
OUTPUT_FIELDS = ("y", "xs", "bs", "status", "nsteps", "nrej")


def _deviated(model: Any, rng: np.random.Generator, n: int) -> np.ndarray:
    dev = rng.uniform(-0.4, 0.4, size=(n, 3))
    extra = COMPOSITIONS[model.reference_name][1]
    return model.param_batch(k3=21.28 * (1 + dev[:, 0]), alpha_h=0.605 * (1 + dev[:, 1]),
                             beta_h=8.307 * (1 + dev[:, 2]), **extra)


def _drive(t_end: float, dt: float, amplitudes: np.ndarray, freq_hz: float = 3.0) -> np.ndarray:
    """(members, samples, 3) differential sine drives (V) with a small base acceleration (m/s^2)."""
    t = np.arange(round(t_end / dt) + 1) * dt
    u = np.zeros((amplitudes.size, t.size, 3))
    u[:, :, 0] = amplitudes[:, None] * np.sin(2 * np.pi * freq_hz * t)[None]
    u[:, :, 1] = -u[:, :, 0]
    u[:, :, 2] = 0.5 * np.sin(2 * np.pi * 7.0 * t)[None]
    return u


def cases(model: Any) -> dict[str, dict[str, Any]]:
    """The inputs of every case for ``model``: arrays and a settings row
    ``(entry, lo, hi, u_t0, u_dt, rtol, h_max, h_min, max_steps, record_x, record_bus)`` (entry 0 run_chunk_stats,
    1 run_chunk, 2 run_lanes)."""
    rng = np.random.default_rng(30)
    n = model.n_states
    c3 = model.param_index("c3")
    out: dict[str, dict[str, Any]] = {}

    def add(name: str, entry: int, p: np.ndarray, u: np.ndarray, t_out: np.ndarray, *, x0: np.ndarray | None = None,
            lo: int = 0, hi: int | None = None, u_dt: float = 1e-3, rtol: float = 1e-6, h_max: float = 0.01,
            h_min: float = 1e-14, max_steps: int = 50_000_000, record_x: bool = True, record_bus: bool = True
            ) -> None:
        b = p.shape[0]
        x0 = np.tile(model.x0_nominal, (b, 1)) if x0 is None else x0
        settings = np.array([entry, lo, b if hi is None else hi, 0.0, u_dt, rtol, h_max, h_min, max_steps,
                             record_x, record_bus], dtype=float)
        out[name] = {"x0": np.ascontiguousarray(x0, dtype=float), "p": np.ascontiguousarray(p, dtype=float),
                     "u": np.ascontiguousarray(u, dtype=float), "t_out": np.ascontiguousarray(t_out, dtype=float),
                     "settings": settings}

    uniform = np.arange(16) * 0.02

    def add_failures(name: str, entry: int, members: int, *, negative_c3: int, blown_up: int) -> None:
        """``members`` deviated members, one with a negative c3 and one starting at 1e200: both must fail."""
        p = _deviated(model, rng, members)
        p[negative_c3, c3] = -50.0
        x0 = np.tile(model.x0_nominal, (members, 1))
        x0[blown_up, 0] = 1e200
        add(name, entry, p, _drive(0.3, 1e-3, np.array([600.0])), uniform, x0=x0, max_steps=20_000,
            record_bus=False)

    add("scalar_shared_input", 0, _deviated(model, rng, 3), _drive(0.3, 1e-3, np.array([600.0])), uniform)
    t_rand = np.concatenate([[0.0], np.sort(rng.uniform(0.0, 0.3, 17)), [0.3]])
    add("scalar_member_inputs_nonuniform_out", 0, _deviated(model, rng, 2),
        _drive(0.3, 1e-3, np.array([600.0, 250.0])), t_rand, record_bus=False)
    add("scalar_one_sample_input", 0, _deviated(model, rng, 1), np.array([[[300.0, -300.0, 0.2]]]), uniform,
        record_x=False, record_bus=False)
    add("run_chunk_entry", 1, _deviated(model, rng, 2), _drive(0.3, 1e-3, np.array([400.0])), uniform)
    add_failures("scalar_failures", 0, 3, negative_c3=1, blown_up=2)
    add("scalar_step_too_small", 0, _deviated(model, rng, 2), _drive(0.3, 1e-3, np.array([600.0])), uniform,
        rtol=1e-13, h_min=1e-3, record_bus=False)
    p = _deviated(model, rng, 20)
    p[::2, model.param_index("n_h")] = 2.0
    add("lanes_padded_member_inputs_branches", 2, p, _drive(0.3, 5e-3, np.linspace(100.0, 600.0, 20)), uniform,
        u_dt=5e-3)
    add("lanes_work_item_inside_batch", 2, _deviated(model, rng, 21), np.array([[[300.0, -300.0, 0.2]]]), uniform,
        lo=16, hi=21, record_bus=False)
    add_failures("lanes_failures_and_rerun", 2, 16, negative_c3=3, blown_up=5)
    add("lanes_step_too_small", 2, _deviated(model, rng, 16), _drive(0.3, 1e-3, np.array([600.0])), uniform,
        rtol=1e-13, h_min=1e-3, record_x=False, record_bus=False)
    assert all(v["x0"].shape[1] == n for v in out.values())
    return out


def run_case(kernels: Any, atol: np.ndarray, n_outputs: int, case: dict[str, Any]) -> dict[str, np.ndarray]:
    """Call the case's kernel entry point; its outputs by :data:`OUTPUT_FIELDS`."""
    entry, lo, hi, u_t0, u_dt, rtol, h_max, h_min, max_steps, record_x, record_bus = case["settings"].tolist()
    x0, p, u, t_out = case["x0"], case["p"], case["u"], case["t_out"]
    b, n_out = p.shape[0], t_out.size
    y = np.full((b, n_out, n_outputs), -1.0)
    xs = np.full((b, n_out, x0.shape[1]), -1.0) if record_x else np.zeros((1, 1, 1))
    bs = np.full((b, n_out, kernels.N_BUS), -1.0) if record_bus else np.zeros((1, 1, 1))
    status = np.full(b, -1, dtype=np.int64)
    nsteps = np.full(b, -1, dtype=np.int64)
    nrej = np.full(b, -1, dtype=np.int64)
    args = (x0, p, u, u_t0, u_dt, t_out, rtol, atol, h_max, h_min, int(max_steps), y, xs, bs, bool(record_x),
            bool(record_bus), status, nsteps)
    if entry == 0:
        kernels.run_chunk_stats(int(lo), int(hi), *args, nrej)
    elif entry == 1:
        kernels.run_chunk(int(lo), int(hi), *args)
    else:
        kernels.run_lanes(int(lo), int(hi), *args, nrej)
    return {"y": y, "xs": xs, "bs": bs, "status": status, "nsteps": nsteps, "nrej": nrej}


def model_of(name: str) -> Any:
    from plant import PlantModel

    extra = COMPOSITIONS[name][0]
    model = PlantModel("table2", effects=list(extra)) if extra else PlantModel("table2")
    model.reference_name = name  # type: ignore[attr-defined]
    return model


def compute(name: str) -> dict[str, np.ndarray]:
    """Every case of composition ``name``, inputs and outputs, flat as ``<case>/<field>``."""
    model = model_of(name)
    kernels = model.kernels()
    atol = np.ascontiguousarray(model.state_scales * 1e-6)
    flat: dict[str, np.ndarray] = {}
    for case_name, case in cases(model).items():
        result = run_case(kernels, atol, model.n_outputs, case)
        for key in INPUT_FIELDS:
            flat[f"{name}/{case_name}/{key}"] = case[key]
        for key, value in result.items():
            flat[f"{name}/{case_name}/{key}"] = value
    return flat


if __name__ == "__main__":
    everything: dict[str, np.ndarray] = {}
    for comp in COMPOSITIONS:
        everything.update(compute(comp))
    FIXTURE.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(FIXTURE, **everything)
    print(f"wrote {len(everything)} arrays to {FIXTURE}", file=sys.stderr)
