"""Time to full charge when a run does not get there: the cell is slow (hours) and the beam fast (seconds), so the
cycle-averaged charging current is measured at several cell voltages in one batch run (method of averaging) and
``t = integral dq / i(q)`` is integrated over the rest of the charge."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from plant.battery import TheveninBattery
from plant.effects.harvesting import N_OCV_NODES
from plant.model import PlantModel
from studies.harvest.setup import HarvestSetup, step_cap


@dataclass
class ChargeRateCurve:
    """Cycle-averaged charging at fixed cell states: ``i_mean`` (A into the cell) against ``q_d`` (C)."""

    q_d: np.ndarray  # C
    v_oc: np.ndarray  # V
    i_mean: np.ndarray  # A
    p_in_mean: np.ndarray  # W, base power in
    p_cell_mean: np.ndarray  # W, chemical power into the cell
    settle_s: float
    average_s: float

    def as_dict(self) -> dict[str, Any]:  # JSON at the edge (harvest_summary.json)
        return {"q_d_C": self.q_d, "v_oc_V": self.v_oc, "i_mean_A": self.i_mean, "p_in_mean_W": self.p_in_mean,
                "p_cell_mean_W": self.p_cell_mean, "settle_s": self.settle_s, "average_s": self.average_s}


def slowest_decay_time(model: PlantModel) -> float:
    """Time constant (s) of the slowest decaying mode or real pole of the model linearised at rest."""
    from plant.linear import linearise, modal_summary

    summary = modal_summary(linearise(model))
    rates = [m["frequency_Hz"] * 2 * math.pi * m["damping_ratio"] for m in summary.modes]
    rates += [1.0 / r["time_constant_s"] for r in summary.real_poles if r["time_constant_s"] > 0]
    rates = [r for r in rates if r > 0]
    return 1.0 / min(rates) if rates else 1.0


def charge_rate_curve(setup: HarvestSetup, q_d_points: np.ndarray, model: PlantModel | None = None,
                      battery: TheveninBattery | None = None, x_start: np.ndarray | None = None,
                      t_start: float = 0.0, rtol: float = 1e-6) -> ChargeRateCurve:
    """Cycle-averaged charging current with the cell *held* at each state of ``q_d_points`` (C).

    One batch run, a member per state: the member's cell is an ideal source at that state's open-circuit voltage
    (all OCV nodes set to it), so the measurement does not drift however fast the cell would charge. Members start
    from ``x_start`` at ``t_start`` (e.g. the end of a run, where the beam is already in its steady motion; default:
    rest at t = 0), settle for five time constants of the slowest mode (at least 2 s, or 4 s from rest) and are
    then averaged over whole periods.
    """
    if model is None or battery is None:
        model, battery, _ = setup.build()
    q = np.asarray(q_d_points, dtype=float)
    v_hold = battery.ocv(q)
    period = 1.0 / setup.freq
    tau = slowest_decay_time(model)
    settle = min(max(5.0 * tau, 2.0 if x_start is not None else 4.0, 20.0 * period), 300.0)
    settle = math.ceil(settle / period) * period
    average = max(2.0, 10.0 * period)
    average = math.ceil(average / period) * period
    params = np.tile(model.p_nominal, (q.size, 1))
    k0 = model.param_index("bat_ocv_00")
    params[:, k0:k0 + N_OCV_NODES] = v_hold[:, None]
    x0 = np.tile(model.x0_nominal if x_start is None else np.asarray(x_start, dtype=float), (q.size, 1))
    so = model.state_names.index("bat_qd")
    x0[:, so] = 0.5 * battery.capacity  # mid-table: away from the full taper and the cut-off
    t0 = float(t_start)
    t_out = t0 + np.array([0.0, settle, settle + average])
    res = model.simulate(setup.inputs(t0, t0 + settle + average), t_out=t_out, x0=x0, params=params,
                         record_states=True, rtol=rtol, h_max=step_cap(setup.freq))
    res.raise_on_failure("charging-rate batch failed: ")
    xs = res.states
    assert xs is not None
    i_e = {n: model.state_names.index(n) for n in ("E_base_in", "E_battery")}
    i_mean = -(xs[:, 2, so] - xs[:, 1, so]) / average
    p_in = (xs[:, 2, i_e["E_base_in"]] - xs[:, 1, i_e["E_base_in"]]) / average
    p_cell = (xs[:, 2, i_e["E_battery"]] - xs[:, 1, i_e["E_battery"]]) / average
    return ChargeRateCurve(q, v_hold, i_mean, p_in, p_cell, settle, average)


@dataclass
class Projection:
    """Time to full projected from a quasi-steady charging-rate curve (``t_full_s`` = inf when it stalls)."""

    t_full_s: float  # from the start of the run
    remaining_s: float  # from the end of the simulated horizon
    stall_voltage_V: float | None
    method: str
    curve: ChargeRateCurve
    t_path: np.ndarray = field(default_factory=lambda: np.zeros(0))  # s, projected charge curve (from t_now)
    v_path: np.ndarray = field(default_factory=lambda: np.zeros(0))  # V, open-circuit voltage along it

    def as_dict(self) -> dict[str, Any]:  # JSON at the edge (harvest_summary.json)
        k = max(1, self.t_path.size // 200)
        return {"t_full_s": self.t_full_s, "remaining_s": self.remaining_s, "stall_voltage_V": self.stall_voltage_V,
                "method": self.method, "is_projection": True, "curve": self.curve.as_dict(),
                "path_t_s": self.t_path[::k], "path_v_oc_V": self.v_path[::k]}


def project_time_to_full(setup: HarvestSetup, q_d_now: float, t_now: float, model: PlantModel | None = None,
                         battery: TheveninBattery | None = None, n_points: int = 11,
                         x_now: np.ndarray | None = None) -> Projection:
    """Quasi-steady projection of the time to full from discharged capacity ``q_d_now`` (C) at time ``t_now`` (s);
    ``x_now`` is the state there (the rate measurement starts from it; default: rest)."""
    if model is None or battery is None:
        model, battery, _ = setup.build()
    q_full = battery.taper
    q_now = max(float(q_d_now), q_full)
    method = (f"quasi-steady projection: cycle-averaged charging current measured with the cell held at "
              f"{n_points} states between the run's end state and full (one batch run), t = integral dq / i(q)")
    if q_now <= q_full:
        curve = ChargeRateCurve(np.array([q_now]), battery.ocv(np.array([q_now])), np.array([np.inf]),
                                np.array([np.nan]), np.array([np.nan]), 0.0, 0.0)
        return Projection(t_now, 0.0, None, method, curve)
    # denser towards full, where the charging current falls fastest
    q_pts = q_full + (q_now - q_full) * np.linspace(1.0, 0.0, n_points) ** 2
    curve = charge_rate_curve(setup, q_pts, model=model, battery=battery, x_start=x_now,
                              t_start=t_now if x_now is not None else 0.0)
    i = curve.i_mean
    if np.any(i <= 0):
        k = int(np.argmax(i <= 0))
        if k == 0:
            v_stall = float(curve.v_oc[0])
        else:  # linear interpolation of the zero crossing in q
            f = i[k - 1] / (i[k - 1] - i[k])
            v_stall = float(battery.ocv(q_pts[k - 1] + f * (q_pts[k] - q_pts[k - 1])))
        return Projection(math.inf, math.inf, v_stall, method, curve)
    # integrate dq / i(q), i(q) a monotone cubic through the measured points
    from scipy.integrate import cumulative_trapezoid
    from scipy.interpolate import PchipInterpolator

    q_fine = np.linspace(q_now, q_full, 4001)
    i_fine = PchipInterpolator(-q_pts, i)(-q_fine)
    t_path = t_now + cumulative_trapezoid(1.0 / i_fine, -q_fine, initial=0.0)
    remaining = float(t_path[-1] - t_now)
    return Projection(t_now + remaining, remaining, None, method, curve, t_path, battery.ocv(q_fine))


