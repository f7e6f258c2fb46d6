"""Calibrate a parameter set to the paper's stated numbers (resonances, RC pole, harvesting gains, and the
quasi-static actuation gain that Table 2 already fits).

The targets are scalar claims, so the model is compared through its linearisation (:mod:`plant.linear`): modal
frequencies of the actuated model, the stored-voltage/base-acceleration gain of the open-circuit model at its own
first and second resonance, and the quasi-static tip gain z3/v_a. Only parameters that the paper identified by model
error minimisation (Table 2, method MEM) are free by default — masses, R_ep and C_ep were measured (TM) and stay.
The fit is a bounded, weighted least-squares problem in log space (scipy ``least_squares``); every residual is a
relative (log) error, so a weight of 10 means "ten times more important than a 1 % miss of a weight-1 target".
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from board_config import ParameterSet
from board_config.errors import InputError
from plant import G0, PlantModel
from plant.linear import linearise, modal_summary, static_tip_gain

CLAIMS_FILE = Path(str(resources.files("board_config") / "reference" / "paper_claims.toml"))

#: parameters the paper identified by model error minimisation (free by default)
DEFAULT_FREE: tuple[str, ...] = ("k1", "k2", "k3", "c1", "c2", "c3", "d_ep")


@dataclass(frozen=True)
class ClaimTarget:
    """One stated number: name, value, unit, weight in the fit, and where the paper states it."""

    name: str
    value: float
    unit: str
    weight: float
    source: str


@dataclass
class ModelFigures:
    """The numbers of a parameter vector that the claims speak to (SI units)."""

    first_resonance_Hz: float
    second_resonance_Hz: float
    rc_pole_Hz: float
    harvest_gain_first_V_per_g: float
    harvest_gain_second_V_per_g: float
    static_tip_gain_m_per_V: float
    damping_ratios: tuple[float, ...]

    def value(self, name: str) -> float:
        return float(getattr(self, name))


@dataclass
class CalibrationResult:
    params: ParameterSet
    start: ModelFigures
    final: ModelFigures
    targets: list[ClaimTarget]
    free: tuple[str, ...]
    history: list[float] = field(default_factory=list)
    success: bool = True
    message: str = ""

    def table(self) -> list[dict[str, Any]]:
        rows = []
        for tg in self.targets:
            start, final = self.start.value(tg.name), self.final.value(tg.name)
            rows.append({"claim": tg.name, "paper": tg.value, "unit": tg.unit, "start": start, "calibrated": final,
                         "rel_error_start": start / tg.value - 1.0, "rel_error_calibrated": final / tg.value - 1.0,
                         "weight": tg.weight, "source": tg.source})
        return rows


def load_claim_targets(path: str | Path = CLAIMS_FILE, static_gain_m_per_v: float | None = None,
                       weights: Mapping[str, float] | None = None) -> list[ClaimTarget]:
    """The calibration targets from ``paper_claims.toml`` (plus the quasi-static actuation gain to keep)."""
    path = Path(path)
    with path.open("rb") as fh:
        claims = tomllib.load(fh)
    fr = claims["frequency_response"]
    w = {"first_resonance_Hz": 100.0, "second_resonance_Hz": 100.0, "rc_pole_Hz": 1.0,
         "harvest_gain_first_V_per_g": 1.0, "harvest_gain_second_V_per_g": 1.0, "static_tip_gain_m_per_V": 100.0}
    w.update(weights or {})
    targets = [
        ClaimTarget("first_resonance_Hz", fr["first_bending_resonance_Hz"], "Hz", w["first_resonance_Hz"],
                    "Sec. 3.2, Fig. 6"),
        ClaimTarget("second_resonance_Hz", fr["second_bending_resonance_Hz"], "Hz", w["second_resonance_Hz"],
                    "Sec. 3.2, Fig. 6"),
        ClaimTarget("rc_pole_Hz", fr["rc_real_pole_Hz"], "Hz", w["rc_pole_Hz"], "Sec. 3.2"),
        ClaimTarget("harvest_gain_first_V_per_g", fr["harvest_gain_first_resonance_V_per_g"], "V/g",
                    w["harvest_gain_first_V_per_g"], "Sec. 3.2, Fig. 6b, Sec. 5"),
        ClaimTarget("harvest_gain_second_V_per_g", fr["harvest_gain_second_resonance_V_per_g"], "V/g",
                    w["harvest_gain_second_V_per_g"], "Sec. 3.2, Fig. 6b, Sec. 5"),
    ]
    if static_gain_m_per_v is not None:
        targets.append(ClaimTarget("static_tip_gain_m_per_V", static_gain_m_per_v, "m/V", w["static_tip_gain_m_per_V"],
                                   "kept from the starting set (the paper validated actuation, Fig. 7)"))
    return targets


def model_figures(act: PlantModel, oc: PlantModel, p: np.ndarray) -> ModelFigures:
    """Resonances, RC pole, harvesting gains at the model's own first/second resonance, static tip gain."""
    lin = linearise(act, params=p)
    modal = modal_summary(lin)
    if len(modal.modes) < 2 or not modal.real_poles:
        raise InputError(f"the model has {len(modal.modes)} oscillating modes and {len(modal.real_poles)} real poles;"
                         " calibration needs two modes and the RC pole")
    f1, f2 = modal.modes[0]["frequency_Hz"], modal.modes[1]["frequency_Hz"]
    lin_oc = linearise(oc, params=p)

    def peak_gain(f0: float) -> float:
        f = f0 * np.linspace(0.9, 1.1, 81)
        return float(np.max(np.abs(lin_oc.frf(f, "v_stored", "z0dd"))) * G0)

    rc = float(np.median([rp["frequency_Hz"] for rp in modal.real_poles]))
    return ModelFigures(f1, f2, rc, peak_gain(f1), peak_gain(f2), static_tip_gain(lin),
                        tuple(m["damping_ratio"] for m in modal.modes))


def calibrate(base: ParameterSet, targets: Sequence[ClaimTarget], free: Sequence[str] = DEFAULT_FREE,
              bounds_factor: float = 50.0, name: str = "calibrated", min_damping_ratio: float = 0.01,
              on_iteration: Callable[[int, float], None] | None = None) -> CalibrationResult:
    """Fit the ``free`` core parameters (log-scaled, within ×/÷ ``bounds_factor`` of the start) to ``targets``.

    ``min_damping_ratio`` keeps every bending mode at least that damped (a soft floor with weight 100): without it the
    optimiser buys harvesting gain with implausibly light damping (0.1 % for a bonded composite laminate).
    """
    act = PlantModel(base)
    oc = PlantModel(base, terminal="open_circuit")
    for f in free:
        if f not in act.param_names:
            raise InputError(f"free parameter '{f}' is not a parameter of the model ({', '.join(act.param_names)})")
        if not act.param_value(f) > 0:
            raise InputError(f"free parameter '{f}' must be positive to be fitted in log space "
                             f"(is {act.param_value(f)})")
    idx = [act.param_index(f) for f in free]
    p0 = act.p_nominal.copy()
    x0 = np.log(p0[idx])
    history: list[float] = []

    def params_of(xlog: np.ndarray) -> np.ndarray:
        p = p0.copy()
        p[idx] = np.exp(xlog)
        return p

    def residuals(xlog: np.ndarray) -> np.ndarray:
        try:
            figs = model_figures(act, oc, params_of(xlog))
        except (ValueError, np.linalg.LinAlgError):
            return np.full(len(targets) + 3, 1e3)
        r = [tg.weight * math.log(max(figs.value(tg.name), 1e-300) / tg.value) for tg in targets]
        zetas = ([*list(figs.damping_ratios), 1.0, 1.0, 1.0])[:3]
        # the soft damping floor (none at min_damping_ratio = 0, a documented value: log(0) is undefined)
        r += [100.0 * max(0.0, math.log(min_damping_ratio / max(z, 1e-12))) if min_damping_ratio > 0 else 0.0
              for z in zetas]
        res = np.array(r)
        cost = float(0.5 * res @ res)
        history.append(cost)
        if on_iteration is not None:
            on_iteration(len(history), cost)
        return res

    lo = x0 - math.log(bounds_factor)
    hi = x0 + math.log(bounds_factor)
    sol = least_squares(residuals, x0, bounds=(lo, hi), x_scale=1.0, diff_step=1e-4, max_nfev=400)
    p_fit = params_of(sol.x)
    changes = {f: float(p_fit[i]) for f, i in zip(free, idx)}
    fitted = base.with_values(name=name, **changes)
    fitted = replace(fitted, meta={
        "name": name,
        "description": f"{base.name} recalibrated to the paper's stated numbers (shm calibrate)",
        "source": f"shm calibrate from {base.name}; targets: " + ", ".join(t.name for t in targets),
    })
    return CalibrationResult(fitted, model_figures(act, oc, p0), model_figures(act, oc, p_fit), list(targets),
                             tuple(free), history, bool(sol.success), str(sol.message))
