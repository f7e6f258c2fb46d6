"""The dictionary effect for a set of records: signal scales along the nominal run, the generated effect (one
compiled kernel per dictionary), and the step sizes of the sensitivity batch."""

from __future__ import annotations

import hashlib
import time
from collections.abc import Sequence

import numpy as np

from plant import PhysicalEffect, PlantModel
from plant import layout as L
from plant.compose import kernel_dir
from plant.effect import load_effect_file
from workbench.discover._dictionary import Term, form_values
from workbench.discover._results import DiscoverError
from workbench.fit import Objective, Target

#: relative size of the switched-on coefficient in the sensitivity batch (of the placement's reference magnitude)
EPS_REL = 2e-3


def signal_scales(targets: Sequence[Target]) -> tuple[dict[str, float], dict[str, list[np.ndarray]]]:
    """99th percentile of |signal| along the records (nominal free run) and the signals themselves."""
    sig: dict[str, list[np.ndarray]] = {}
    for tg in targets:
        res = tg.model.simulate(tg.inputs, t_out=tg.t, record_states=True, record_bus=True,
                                max_steps=Objective.max_steps(tg))
        if not res.ok:
            raise DiscoverError(f"{tg.name}: the starting model fails to integrate on the record "
                                f"({'; '.join(res.failures())})")
        assert res.bus is not None and res.states is not None  # recorded above
        bus, xs = res.bus[0], res.states[0]
        for j in range(3):
            sig.setdefault(f"z{j + 1}", []).append(bus[:, L.B_Z + j])
            sig.setdefault(f"zd{j + 1}", []).append(bus[:, L.B_ZD + j])
            sig.setdefault(f"delta{j + 1}", []).append(xs[:, L.X_DELTA + j])
            sig.setdefault(f"ddelta{j + 1}", []).append(xs[:, L.X_DDELTA + j])
        sig.setdefault("vc", []).append(bus[:, L.B_VC])
        sig.setdefault("va", []).append(bus[:, L.B_VA_DEMAND])
        sig.setdefault("ic", []).append(bus[:, L.B_IR])
        sig.setdefault("one", []).append(np.ones(tg.t.size))
    scales = {k: float(np.percentile(np.abs(np.concatenate(v)), 99)) for k, v in sig.items()}
    scales["t"] = max(float(tg.t[-1]) for tg in targets)  # the longest record's duration (s): the time gates' span
    return scales, sig


def generated_effect(source: str, stem: str) -> type[PhysicalEffect]:
    """Write generated effect source to the kernel cache (content-addressed) and load it as a file effect."""
    d = kernel_dir() / "discover"
    d.mkdir(parents=True, exist_ok=True)
    path = d / f"{stem}_{hashlib.sha256(source.encode()).hexdigest()[:16]}.py"
    if not path.exists() or path.read_text() != source:
        tmp = path.with_suffix(f".{time.time_ns()}.tmp")
        tmp.write_text(source)
        tmp.replace(path)
    mod = load_effect_file(path)
    return next(o for o in vars(mod).values() if isinstance(o, type) and issubclass(o, PhysicalEffect)
                and o.__module__ == mod.__name__)


def reference_magnitudes(model: PlantModel, scales: dict[str, float]) -> dict[str, float]:
    """A small magnitude per placement (SI) whose effect on the tip is ~EPS_REL of its motion."""
    k3 = model.param_value("k3")
    r = model.param_value("R_ep")
    z3 = max(scales.get("z3", 0.0), 1e-9)
    va = max(scales.get("va", 0.0), scales.get("vc", 0.0), 1e-3)
    return {"force_mass": EPS_REL * k3 * z3, "force_section": EPS_REL * k3 * z3, "current": EPS_REL * va / r,
            "drive": EPS_REL * va, "measurement": EPS_REL * z3, "damage": EPS_REL}


def term_scale(term: Term, sig: dict[str, list[np.ndarray]], targets: Sequence[Target]) -> float:
    """RMS of the form's value along the records (for the sensitivity step; a damage term's gate)."""
    vals = []
    for s, tg in zip(sig[term.signal], targets):
        dt = float(np.median(np.diff(tg.t))) if tg.t.size > 1 else 1.0
        shaped = term.shape > 0 or term.shape_range is not None  # a switching point may be 0 (or below)
        vals.append(form_values(term.form, s, term.shape if shaped else 1.0, tg.t, dt))
    v = np.concatenate(vals)
    return float(np.sqrt(np.mean(v * v)))
