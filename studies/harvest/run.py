"""Harvesting runs: charge the cell from base vibration, time to full, and the power audit (seed paper Sec. 3.3).

``run_harvest(HarvestSetup(...))`` integrates the plant with a harvesting terminal (``coupled``: the energy-consistent
circuit, or ``paper``: Eq. 8 as written) under a sinusoidal base acceleration, in chunks (progress, early stop when
the cell is full), and returns a :class:`HarvestRun` with

* the charge curve (Fig. 9): open-circuit and terminal voltage, state of charge against time;
* the time to full charge — measured when the run gets there, else a clearly marked *projection*: the cell is slow
  (hours) and the beam fast (seconds), so the cycle-averaged charging current is measured at several cell voltages
  in one batch run (method of averaging) and ``t = integral dq / i(q)`` is integrated over the rest of the charge;
* the power audit (:class:`PowerAudit`): every energy term integrated by the same integrator as the dynamics
  (extra states of the terminal), stored energies from the state; the books must close (coupled), or show how much
  energy Eq. 8 creates (paper).

All quantities SI inside; the CLI converts (``--accel-g``) at the edge.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from board_config import ParameterSet
from board_config.battery import BatterySpec
from board_config.errors import InputError
from plant.battery import TheveninBattery, initial_state
from plant.effects import NOMINAL_EFFECTS
from plant.effects.harvesting import N_OCV_NODES
from plant.model import PlantModel, SimulationResult
from plant.rectifier import MAX_DIODE_DROP_V, FullBridge
from plant.signals import G0, InputSignals

#: --coupling name -> terminal effect
COUPLINGS: dict[str, str] = {"coupled": "harvest_coupled", "paper": "harvest_paper"}
#: physical ranges accepted for a harvesting set-up (inclusive unless noted)
ACCEL_RANGE_G = (0.0, 50.0)  # amplitude, g; lower bound exclusive
FREQ_RANGE_HZ = (0.0, 500.0)  # Hz; lower bound exclusive
R_INT_RANGE_OHM = (0.0, 1e6)  # ohm; lower bound exclusive
I_BOARD_RANGE_A = (0.0, 1.0)  # A
DURATION_RANGE_S = (0.0, 1e7)  # s; lower bound exclusive
#: audit closure required in coupled mode (relative to the energy sources)
AUDIT_TOLERANCE = 0.01
#: the paper's claim: full recharge from 2 V within 10 minutes; and its stated gain at 5.8 Hz (Sec. 3.2-3.3)
PAPER_CLAIM_S = 600.0
PAPER_GAIN_V_PER_G = 35.0

def step_cap(freq: float) -> float:
    """Largest integrator step (s) for a harvesting run at ``freq`` (Hz): 2 ms, or 1/40 of a period.

    The rectifier switches twice per period and the sampled input has a knot every millisecond; with this cap the
    compiled Dormand-Prince at rtol 1e-6 keeps the charge and the audit terms within ~1e-6 of a tight reference
    (measured: 3e-8 ... 9e-7 on 20 s of the what-if set), at half the steps of a 1-ms cap.
    """
    return min(2e-3, 1.0 / (40.0 * float(freq)))


_ACCUMULATORS = ("E_base_in", "E_damping", "E_hysteresis", "E_other_effects", "E_R_ep", "E_rectifier_in",
                 "E_diodes", "E_controller", "E_R_bint", "E_board", "E_battery")


def _check_range(what: str, value: Any, lo: float, hi: float, unit: str, lo_open: bool = True) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{what} must be a number, got {value!r}") from None
    bad_lo = v <= lo if lo_open else v < lo
    if not math.isfinite(v) or bad_lo or v > hi:
        bracket = "(" if lo_open else "["
        raise InputError(f"{what} = {value!r} {unit} outside the allowed range {bracket}{lo:g}, {hi:g}] {unit}")
    return v


@dataclass(frozen=True)
class HarvestSetup:
    """A harvesting experiment (SI units): base acceleration ``accel`` (m/s^2 amplitude) at ``freq`` (Hz)."""

    params: str | ParameterSet = "table2"
    coupling: str = "coupled"
    accel: float = 0.1 * G0  # m/s^2
    freq: float = 5.8  # Hz
    r_int: float = 1.0  # ohm
    v_start: float = 2.0  # V (open-circuit voltage at the start)
    v_diode: float = 0.0  # V per diode
    i_board: float = 0.0  # A
    battery: str | BatterySpec = "ML2032"
    duration: float = 600.0  # s
    eq8_reverse: bool = False  # paper only: Eq. 8 literally (no blocking bridge)
    hysteresis: bool = True  # False: the nominal model without the Bouc-Wen effect (a passive, linear piezo)

    def validate(self) -> TheveninBattery:
        """Check every field; return the cell. Errors name the value and its allowed range."""
        if self.coupling not in COUPLINGS:
            raise InputError(f"coupling {self.coupling!r} unknown (allowed: {', '.join(COUPLINGS)})")
        _check_range("base acceleration amplitude", self.accel / G0, *ACCEL_RANGE_G, "g")
        _check_range("excitation frequency", self.freq, *FREQ_RANGE_HZ, "Hz")
        _check_range("internal resistance R_bint", self.r_int, *R_INT_RANGE_OHM, "ohm")
        _check_range("diode forward drop", self.v_diode, 0.0, MAX_DIODE_DROP_V, "V", lo_open=False)
        _check_range("board load current", self.i_board, *I_BOARD_RANGE_A, "A", lo_open=False)
        _check_range("duration", self.duration, *DURATION_RANGE_S, "s")
        if self.eq8_reverse and self.coupling != "paper":
            raise InputError("eq8_reverse applies to the paper coupling only")
        battery = TheveninBattery(self.battery, r_int=self.r_int)
        battery.discharged_capacity(self.v_start, "start voltage")
        return battery

    def terminal(self) -> str:
        return COUPLINGS[self.coupling]

    def effect_params(self, battery: TheveninBattery) -> dict[str, float]:
        out = battery.effect_params()
        out.update({"V_diode": float(self.v_diode), "i_board": float(self.i_board)})
        if self.coupling == "paper":
            out["eq8_reverse"] = 1.0 if self.eq8_reverse else 0.0
        return out

    def build(self) -> tuple[PlantModel, TheveninBattery, np.ndarray]:
        """(model, cell, initial state) for this set-up."""
        battery = self.validate()
        core = NOMINAL_EFFECTS if self.hysteresis else tuple(e for e in NOMINAL_EFFECTS if e != "bouc_wen")
        model = PlantModel(self.params, terminal=self.terminal(), core=core,
                           effect_params=self.effect_params(battery))
        return model, battery, initial_state(model, battery, self.v_start)

    def inputs(self, t0: float, t1: float) -> InputSignals:
        """Base acceleration samples on [t0, t1] (phase-continuous across chunks)."""
        dt = min(1e-3, 1.0 / (self.freq * 200.0))
        n = math.ceil((t1 - t0) / dt - 1e-9) + 1
        t = t0 + dt * np.arange(n)
        vals = np.zeros((1, n, 3))
        vals[0, :, 2] = self.accel * np.sin(2.0 * np.pi * self.freq * t)
        return InputSignals(t0, dt, vals)

    def as_dict(self) -> dict[str, Any]:
        return {
            "params": self.params if isinstance(self.params, str) else self.params.name,
            "coupling": self.coupling, "terminal": self.terminal(), "accel_m_s2": self.accel,
            "accel_g": self.accel / G0, "freq_Hz": self.freq, "R_bint_ohm": self.r_int, "v_start_V": self.v_start,
            "V_diode_V": self.v_diode, "i_board_A": self.i_board,
            "battery": self.battery if isinstance(self.battery, str) else self.battery.name,
            "duration_s": self.duration, "eq8_reverse": self.eq8_reverse, "hysteresis": self.hysteresis,
        }


# ------------------------------------------------------------------------------------------------------------------
# Power audit
# ------------------------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class AuditRow:
    """One line of the audit: ``side`` is "source", "use" (losses, delivered, stored) or "memo" (not summed)."""

    name: str
    energy_J: float
    side: str
    note: str = ""


@dataclass
class PowerAudit:
    """Energy books of a run: sources = uses + residual. See :func:`power_audit`."""

    duration_s: float
    coupling: str
    rows: list[AuditRow]
    residual_J: float
    relative_residual: float
    battery_crosscheck_J: float  # E_battery accumulator minus the OCV-curve state function
    energy_from_nowhere_J: float  # paper: energy the cell took from patches that never delivered it

    @property
    def sources_J(self) -> float:
        return float(sum(r.energy_J for r in self.rows if r.side == "source"))

    @property
    def uses_J(self) -> float:
        return float(sum(r.energy_J for r in self.rows if r.side == "use"))

    def closes(self, tolerance: float = AUDIT_TOLERANCE) -> bool:
        return bool(abs(self.relative_residual) <= tolerance)

    def row(self, name: str) -> AuditRow:
        for r in self.rows:
            if r.name == name:
                return r
        raise KeyError(f"no audit row '{name}' (rows: {', '.join(r.name for r in self.rows)})")

    def as_dict(self) -> dict[str, Any]:
        return {
            "duration_s": self.duration_s, "coupling": self.coupling,
            "rows": [{"name": r.name, "energy_J": r.energy_J, "mean_power_W": r.energy_J / self.duration_s,
                      "side": r.side, "note": r.note} for r in self.rows],
            "sources_J": self.sources_J, "uses_J": self.uses_J, "residual_J": self.residual_J,
            "relative_residual": self.relative_residual, "closes_within_1pct": self.closes(),
            "battery_crosscheck_J": self.battery_crosscheck_J, "energy_from_nowhere_J": self.energy_from_nowhere_J,
        }

    def table(self) -> str:
        """Plain-text audit table (energies in J and mean powers in W)."""
        lines = [f"{'term':<52} {'energy J':>12} {'mean power W':>13}  side"]
        for r in self.rows:
            lines.append(f"{r.name:<52} {r.energy_J:>12.4e} {r.energy_J / self.duration_s:>13.4e}  {r.side}")
        lines.append(f"{'sources - uses (residual)':<52} {self.residual_J:>12.4e} "
                     f"{self.residual_J / self.duration_s:>13.4e}  {self.relative_residual:+.3%} of sources")
        return "\n".join(lines)


def power_audit(model: PlantModel, battery: TheveninBattery, x_start: np.ndarray, x_end: np.ndarray,
                e_stored_start: tuple[float, float], e_stored_end: tuple[float, float], duration: float,
                coupling: str) -> PowerAudit:
    """Close the books between two states of a harvesting model.

    Sources: base power in (relative frame, ``-z0'' sum m_j z_j'``), the Bouc-Wen part of the piezo work (the model's
    hysteresis is not guaranteed passive, so it is booked with its sign), net work of any other added effects.
    Uses: structural damping, ``R_ep``, bridge diodes, charge controller, ``R_bint``, board load, chemical energy into
    the cell, change of mechanical (kinetic + elastic) and electrical (``C_ep``) energy.
    ``e_stored_*`` = (E_mech, E_elec) in J.
    """
    idx = {n: model.state_names.index(n) for n in _ACCUMULATORS}
    e = {n: float(x_end[i] - x_start[i]) for n, i in idx.items()}
    so = model.state_names.index("bat_qd")
    d_mech = float(e_stored_end[0] - e_stored_start[0])
    d_elec = float(e_stored_end[1] - e_stored_start[1])
    rows = [
        AuditRow("base excitation power in (relative frame)", e["E_base_in"], "source", "-z0'' * sum m_j z_j'"),
        AuditRow("Bouc-Wen hysteresis work on the laminate", e["E_hysteresis"], "source",
                 "theta (q_h - q) delta' / C_ep; either sign"),
        AuditRow("other added effects (net work)", e["E_other_effects"], "source", "0 for the nominal model"),
        AuditRow("structural damping c_i", e["E_damping"], "use"),
        AuditRow("patch resistance R_ep", e["E_R_ep"], "use"),
        AuditRow("bridge diodes", e["E_diodes"], "use"),
        AuditRow("charge controller (no charging past full)", e["E_controller"], "use"),
        AuditRow("cell internal resistance R_bint", e["E_R_bint"], "use"),
        AuditRow("board load", e["E_board"], "use"),
        AuditRow("chemical energy into the cell", e["E_battery"], "use", "integral of v_oc * i_bat"),
        AuditRow("change of mechanical energy (kinetic + elastic)", d_mech, "use"),
        AuditRow("change of electrical energy in C_ep", d_elec, "use"),
        AuditRow("memo: drawn by the bridge from the patch terminals", e["E_rectifier_in"], "memo",
                 "paper mode: the patches never deliver it"),
    ]
    sources = sum(r.energy_J for r in rows if r.side == "source")
    uses = sum(r.energy_J for r in rows if r.side == "use")
    residual = sources - uses
    positive_sources = sum(max(r.energy_J, 0.0) for r in rows if r.side == "source")
    gross = sum(abs(r.energy_J) for r in rows if r.side != "memo")
    scale = positive_sources if positive_sources > 0 else gross
    rel = residual / scale if scale > 0 else 0.0
    state_fn = battery.chemical_energy(float(x_start[so]), float(x_end[so]))
    return PowerAudit(
        duration_s=float(duration), coupling=coupling, rows=rows, residual_J=float(residual),
        relative_residual=float(rel), battery_crosscheck_J=float(e["E_battery"] - state_fn),
        energy_from_nowhere_J=float(e["E_rectifier_in"]) if coupling == "paper" else 0.0,
    )


# ------------------------------------------------------------------------------------------------------------------
# Quasi-steady charging-rate curve and projection
# ------------------------------------------------------------------------------------------------------------------
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

    def as_dict(self) -> dict[str, Any]:
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
    if not res.ok:
        raise FloatingPointError("charging-rate batch failed: " + "; ".join(res.failures()))
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

    def as_dict(self) -> dict[str, Any]:
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


# ------------------------------------------------------------------------------------------------------------------
# The run
# ------------------------------------------------------------------------------------------------------------------
@dataclass
class HarvestRun:
    """Result of :func:`run_harvest` (SI units; see the field comments)."""

    setup: HarvestSetup
    battery: dict[str, Any]
    t: np.ndarray  # s, recorded samples
    v_bat: np.ndarray  # V, open-circuit voltage
    v_bat_term: np.ndarray  # V
    soc: np.ndarray  # 1
    v_stored: np.ndarray  # V, patch terminal voltage
    chunks: dict[str, np.ndarray]  # per-chunk summaries (t_end_s, v_bat_V, soc, i_mean_A, p_in_W, va_peak_V, ...)
    tail: dict[str, np.ndarray]  # the last seconds at full output resolution: t_s, v_stored_V, z3_m, i_bat_A
    reached_full: bool
    t_full_s: float | None  # measured time to full (None when not reached)
    projection: Projection | None
    audit: PowerAudit
    t_end: float  # s simulated
    q_d_start: float  # C
    q_d_end: float  # C
    q_below_cutoff: float  # C drawn below the cut-off
    n_steps: int
    wall_s: float
    meta: dict[str, Any] = field(default_factory=dict)

    @property
    def stored_gain_v_per_g(self) -> float:
        """Peak terminal voltage over the last chunk per g of base acceleration (V/g)."""
        return float(self.chunks["va_peak_V"][-1] / (self.setup.accel / G0))

    @property
    def time_to_full_s(self) -> float:
        """Measured time to full if reached, else the projection (inf when charging stalls)."""
        if self.t_full_s is not None:
            return self.t_full_s
        return self.projection.t_full_s if self.projection is not None else math.nan

    def summary(self) -> dict[str, Any]:
        return {
            "setup": self.setup.as_dict(), "battery": self.battery, "t_end_s": self.t_end,
            "v_bat_start_V": float(self.v_bat[0]), "v_bat_end_V": float(self.v_bat[-1]),
            "soc_start": float(self.soc[0]), "soc_end": float(self.soc[-1]),
            "charge_gained_C": self.q_d_start - self.q_d_end,
            "reached_full": self.reached_full, "t_full_s": self.t_full_s,
            "time_to_full_s": self.time_to_full_s, "time_to_full_is_projection": self.t_full_s is None,
            "projection": self.projection.as_dict() if self.projection is not None else None,
            "stored_voltage_peak_V": float(self.chunks["va_peak_V"][-1]),
            "stored_gain_V_per_g": self.stored_gain_v_per_g,
            "tip_peak_m": float(self.chunks["z3_peak_m"][-1]),
            "mean_base_power_W": float(self.chunks["p_in_W"][-1]),
            "mean_charging_current_A": float(self.chunks["i_mean_A"][-1]),
            "charge_below_cutoff_C": self.q_below_cutoff,
            "audit": self.audit.as_dict(), "n_steps": self.n_steps, "wall_s": self.wall_s,
            "what_it_would_take": self.requirements(), **self.meta,
        }

    def requirements(self, target_s: float = PAPER_CLAIM_S) -> dict[str, Any]:
        """What a full recharge from the run's start state within ``target_s`` would take (SI units).

        * the chemical energy to put in, and its mean power over ``target_s``, against the base power this run
          measured (the whole base input, an upper bound for what any circuit could harvest);
        * the base acceleration that would carry that power if it grew as the square of the acceleration at the
          harvesting efficiency of this run (a lower bound: the harvest cannot exceed the base input);
        * for Eq. 8 (unloaded source, ideal bridge): the open-circuit amplitude and gain it would need, and the time it
          gives with the paper's 35 V/g.
        """
        battery = self.setup.validate()
        e_need = battery.energy_to_full(self.q_d_start)
        p_need = e_need / target_s
        p_base = float(self.chunks["p_in_W"][-1])
        e_cell = self.audit.row("chemical energy into the cell").energy_J
        e_in = self.audit.row("base excitation power in (relative frame)").energy_J
        # in paper mode the cell's energy does not come from the base: no efficiency to speak of
        efficiency = (e_cell / e_in if e_in > 0 else 0.0) if self.setup.coupling == "coupled" else math.nan
        accel_g = self.setup.accel / G0
        a_eq8 = eq8_required_amplitude(battery, self.setup.v_start, target_s, self.setup.v_diode)
        return {
            "target_s": target_s,
            "energy_to_full_J": e_need,
            "required_mean_cell_power_W": p_need,
            "measured_mean_base_power_W": p_base,
            "required_over_base_power": p_need / p_base if p_base > 0 else math.inf,
            "harvest_efficiency_cell_over_base": efficiency,
            "accel_for_required_power_g": (accel_g * math.sqrt(p_need / (efficiency * p_base))
                                           if efficiency > 0 and p_base > 0 else
                                           (math.nan if math.isnan(efficiency) else math.inf)),
            "accel_if_all_base_power_harvested_g": accel_g * math.sqrt(p_need / p_base) if p_base > 0 else math.inf,
            "eq8_required_amplitude_V": a_eq8,
            "eq8_required_gain_V_per_g": a_eq8 / accel_g,
            "eq8_time_at_paper_gain_s": eq8_time_to_full(PAPER_GAIN_V_PER_G * accel_g, battery, self.setup.v_start,
                                                         self.setup.v_diode),
            "paper_gain_V_per_g": PAPER_GAIN_V_PER_G,
            "measured_gain_V_per_g": self.stored_gain_v_per_g,
        }


ProgressFn = Callable[[float, float, float], None]  # (t_done_s, t_total_s, soc)


def run_harvest(setup: HarvestSetup, progress: ProgressFn | None = None, chunk_s: float | None = None,
                dt_out: float = 0.01, max_points: int = 20000, stop_when_full: bool = True, project: bool = True,
                rtol: float = 1e-6) -> HarvestRun:
    """Simulate ``setup.duration`` seconds (or until full) and audit the energy; project when not full."""
    wall0 = time.perf_counter()
    model, battery, x0 = setup.build()
    names = model.state_names
    so = names.index("bat_qd")
    s_below = names.index("bat_q_below_cutoff")
    i_ein = names.index("E_base_in")
    duration = float(setup.duration)
    period = 1.0 / setup.freq
    dt_out = min(dt_out, period / 40.0)
    if chunk_s is None:
        chunk_s = min(max(duration / 60.0, 2.0), 30.0)
    n_chunks = max(1, math.ceil(duration / chunk_s - 1e-9))
    edges = np.linspace(0.0, duration, n_chunks + 1)
    keep_every = max(1, round(duration / dt_out / max_points))
    h_max = step_cap(setup.freq)

    rec: dict[str, list[np.ndarray]] = {k: [] for k in ("t", "v_bat", "v_bat_term", "soc_bat", "v_stored")}
    chunk_cols: dict[str, list[float]] = {k: [] for k in (
        "t_end_s", "v_bat_V", "soc", "i_mean_A", "p_in_W", "va_peak_V", "z3_peak_m")}
    x = x0.copy()
    e_start: tuple[float, float] | None = None
    e_end = (0.0, 0.0)
    t_full: float | None = None
    steps = 0
    t_end = 0.0
    tail: dict[str, np.ndarray] = {}
    taper_soc = 1.0 - battery.taper / battery.capacity
    for c in range(n_chunks):
        t0, t1 = float(edges[c]), float(edges[c + 1])
        n_out = max(2, round((t1 - t0) / dt_out) + 1)
        t_out = np.linspace(t0, t1, n_out)
        res: SimulationResult = model.simulate(setup.inputs(t0, t1), t_out=t_out, x0=x, record_states=True,
                                               rtol=rtol, h_max=h_max)
        if not res.ok:
            raise FloatingPointError(f"harvesting run failed in [{t0:g}, {t1:g}] s: {'; '.join(res.failures())}")
        xs = res.states
        assert xs is not None
        steps += int(res.n_steps.sum())
        if e_start is None:
            e_start = (float(res["E_mech"][0, 0]), float(res["E_elec"][0, 0]))
        soc = res["soc_bat"][0]
        stop_k = n_out - 1
        if t_full is None:
            hit = np.flatnonzero(soc >= taper_soc)
            if hit.size:
                k = int(hit[0])
                if k == 0:
                    t_full = t0
                else:
                    f = (taper_soc - soc[k - 1]) / (soc[k] - soc[k - 1])
                    t_full = float(t_out[k - 1] + f * (t_out[k] - t_out[k - 1]))
                if stop_when_full:
                    stop_k = k
        sl = slice(0 if c == 0 else 1, stop_k + 1)
        for key in rec:
            arr = t_out if key == "t" else res[key][0]
            rec[key].append(arr[sl][::keep_every] if c == 0 else arr[sl][keep_every - 1::keep_every])
        x_last = xs[0, stop_k]
        tail_sel = (t_out <= t_out[stop_k]) & (t_out >= t_out[stop_k] - 4.0)
        tail = {"t_s": t_out[tail_sel], "v_stored_V": res["v_stored"][0][tail_sel],
                "z3_m": res["z3"][0][tail_sel], "i_bat_A": res["i_bat"][0][tail_sel]}
        dt_chunk = float(t_out[stop_k] - t0)
        # a sliding window of whole periods at the chunk's end for peaks, the whole chunk for means
        win = t_out >= t_out[stop_k] - max(period * math.floor(min(dt_chunk, 2.0) / period), period)
        win &= t_out <= t_out[stop_k]
        chunk_cols["t_end_s"].append(float(t_out[stop_k]))
        chunk_cols["v_bat_V"].append(float(res["v_bat"][0, stop_k]))
        chunk_cols["soc"].append(float(soc[stop_k]))
        chunk_cols["i_mean_A"].append(float(-(x_last[so] - x[so]) / dt_chunk) if dt_chunk > 0 else 0.0)
        chunk_cols["p_in_W"].append(float((x_last[i_ein] - x[i_ein]) / dt_chunk) if dt_chunk > 0 else 0.0)
        chunk_cols["va_peak_V"].append(float(np.max(np.abs(res["v_stored"][0][win]))))
        chunk_cols["z3_peak_m"].append(float(np.max(np.abs(res["z3"][0][win]))))
        e_end = (float(res["E_mech"][0, stop_k]), float(res["E_elec"][0, stop_k]))
        x = np.array(x_last)
        t_end = float(t_out[stop_k])
        if progress is not None:
            progress(t_end, duration, float(soc[stop_k]))
        if t_full is not None and stop_when_full:
            break
    assert e_start is not None
    audit = power_audit(model, battery, x0, x, e_start, e_end, t_end, setup.coupling)
    projection = None
    if t_full is None and project:
        projection = project_time_to_full(setup, float(x[so]), t_end, model=model, battery=battery, x_now=x)
    cat = {k: np.concatenate(v) for k, v in rec.items()}
    return HarvestRun(
        setup=setup, battery=battery.describe(), t=cat["t"], v_bat=cat["v_bat"], v_bat_term=cat["v_bat_term"],
        soc=cat["soc_bat"], v_stored=cat["v_stored"], chunks={k: np.array(v) for k, v in chunk_cols.items()},
        tail=tail,
        reached_full=t_full is not None, t_full_s=t_full, projection=projection, audit=audit, t_end=t_end,
        q_d_start=float(x0[so]), q_d_end=float(x[so]), q_below_cutoff=float(x[s_below] - x0[s_below]),
        n_steps=steps, wall_s=time.perf_counter() - wall0,
        meta={"effects": list(model.effect_names), "parameter_set": model.params.name},
    )


# ------------------------------------------------------------------------------------------------------------------
# What it would take
# ------------------------------------------------------------------------------------------------------------------
def eq8_time_to_full(amplitude_v: float, battery: TheveninBattery, v_start: float, v_diode: float = 0.0,
                     n: int = 4001) -> float:
    """Eq. 8 (unloaded source) with ``|v_a|`` a rectified sine of ``amplitude_v`` (V): time (s) from ``v_start`` to
    full, cycle-averaged (closed-form mean current). inf when the amplitude never beats the cell voltage."""
    bridge = FullBridge(v_diode)
    q0 = battery.discharged_capacity(v_start, "start voltage")
    q = np.linspace(q0, battery.taper, n)
    v = battery.ocv(q)
    i = np.array([bridge.mean_charging_current(amplitude_v, 0.0, float(vv), battery.r_int) for vv in v])
    if np.any(i <= 0):
        return math.inf
    return float(np.trapezoid(1.0 / i, -q))


def eq8_required_amplitude(battery: TheveninBattery, v_start: float, target_s: float, v_diode: float = 0.0) -> float:
    """Smallest open-circuit amplitude (V) with which Eq. 8 fills the cell from ``v_start`` within ``target_s``."""
    from scipy.optimize import brentq

    lo = float(battery.v_nodes[0]) + 2.0 * v_diode + 1e-9
    if eq8_time_to_full(lo, battery, v_start, v_diode) <= target_s:
        return lo  # any amplitude that can reach the full voltage at all is fast enough (tiny R_bint)
    hi = lo + 1.0
    while eq8_time_to_full(hi, battery, v_start, v_diode) > target_s:
        hi = lo + 2.0 * (hi - lo)
        if hi > 1e6:
            return math.inf
    return float(brentq(lambda a: eq8_time_to_full(a, battery, v_start, v_diode) - target_s, lo, hi,
                        xtol=1e-6, rtol=1e-9))


def required_mean_power(battery: TheveninBattery, v_start: float, target_s: float) -> float:
    """Chemical power (W) the cell must take in, on average, to fill from ``v_start`` within ``target_s``."""
    return battery.energy_to_full(battery.discharged_capacity(v_start, "start voltage")) / float(target_s)


def open_circuit_base_power(params: str | ParameterSet, accel: float, freqs: np.ndarray,
                            settle_s: float = 6.0, average_s: float = 3.0) -> tuple[np.ndarray, np.ndarray]:
    """Mean base power in (W) and peak open-circuit voltage (V) of the laminate at each frequency (batch run).

    For a linear resonator with mechanical damping c, the power an ideally matched electrical load can take at
    resonance is a quarter of the base power the open-circuit structure absorbs there — an upper bound for any
    harvesting circuit on this laminate (see docs/harvesting.md).
    """
    freqs = np.atleast_1d(np.asarray(freqs, dtype=float))
    model = PlantModel(params, terminal="harvest_paper", effect_params={"bat_taper": 1e-12})
    x0 = np.tile(model.x0_nominal, (freqs.size, 1))
    x0[:, model.state_names.index("bat_qd")] = 0.0  # full cell: nothing flows, the patches are open-circuit
    t_end = settle_s + average_s
    dt = min(1e-3, 1.0 / (float(freqs.max()) * 200.0))
    t = dt * np.arange(math.ceil(t_end / dt) + 1)
    vals = np.zeros((freqs.size, t.size, 3))
    vals[:, :, 2] = accel * np.sin(2.0 * np.pi * freqs[:, None] * t[None, :])
    t_out = np.concatenate([np.linspace(settle_s, t_end, 400)])
    t_out = np.concatenate([[0.0], t_out])
    res = model.simulate(InputSignals(0.0, dt, vals), t_out=t_out, x0=x0, record_states=True,
                         h_max=step_cap(float(freqs.max())))
    if not res.ok:
        raise FloatingPointError("open-circuit power batch failed: " + "; ".join(res.failures()))
    xs = res.states
    assert xs is not None
    i_e = model.state_names.index("E_base_in")
    p_in = (xs[:, -1, i_e] - xs[:, 1, i_e]) / (t_end - settle_s)
    v_pk = np.max(np.abs(res["v_stored"][:, 1:]), axis=1)
    return p_in, v_pk
