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

from board_config.json_values import JsonFields
from plant.battery import TheveninBattery
from plant.model import SimulationResult
from plant.signals import G0
from studies.harvest.audit import PowerAudit, power_audit
from studies.harvest.projection import Projection, project_time_to_full
from studies.harvest.requirements import eq8_required_amplitude, eq8_time_to_full
from studies.harvest.setup import PAPER_CLAIM_S, PAPER_GAIN_V_PER_G, HarvestSetup, step_cap


@dataclass(frozen=True)
class HarvestRequirements(JsonFields):
    """What a full recharge within ``target_s`` would take (:meth:`HarvestRun.requirements`); the summary's
    ``what_it_would_take`` (its fields by name: ``to_dict``)."""

    target_s: float
    """Time allowed for the full recharge (s)."""
    energy_to_full_J: float
    """Chemical energy to put into the cell from the run's start state (J)."""
    required_mean_cell_power_W: float
    """That energy over ``target_s`` (W)."""
    measured_mean_base_power_W: float
    """Mean base input power of the run's last chunk (W): an upper bound for any harvest."""
    required_over_base_power: float
    """Required cell power over the measured base power (1; inf without base power)."""
    harvest_efficiency_cell_over_base: float
    """Cell energy over base energy in this run (1; NaN in paper mode, where the cell's energy is not the base's)."""
    accel_for_required_power_g: float
    """Base acceleration (g) carrying the required power at this run's efficiency, power ∝ acceleration²."""
    accel_if_all_base_power_harvested_g: float
    """Base acceleration (g) if all base power reached the cell (a lower bound)."""
    eq8_required_amplitude_V: float
    """Open-circuit amplitude (V) Eq. 8 needs for ``target_s``."""
    eq8_required_gain_V_per_g: float
    """That amplitude per g of this run's base acceleration (V/g)."""
    eq8_time_at_paper_gain_s: float
    """Eq. 8's time to full (s) with the paper's gain at this acceleration."""
    paper_gain_V_per_g: float
    """The paper's stored-voltage gain (V/g)."""
    measured_gain_V_per_g: float
    """This run's peak terminal voltage per g (V/g)."""


@dataclass
class HarvestRun:
    """Result of :func:`run_harvest` (SI units; see the field comments)."""

    setup: HarvestSetup
    battery: TheveninBattery  # the cell charged (its spec: name, cut-off and full voltage, V)
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
    effects: tuple[str, ...] = ()  # the plant's effects
    parameter_set: str = ""  # the plant's parameter set

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
        """harvest_summary.json (the JSON document at the edge)."""
        return {
            "setup": self.setup.as_dict(), "battery": self.battery.describe(), "t_end_s": self.t_end,
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
            "what_it_would_take": self.requirements().to_dict(), "effects": list(self.effects),
            "parameter_set": self.parameter_set,
        }

    def requirements(self, target_s: float = PAPER_CLAIM_S) -> HarvestRequirements:
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
        return HarvestRequirements(
            target_s=target_s,
            energy_to_full_J=e_need,
            required_mean_cell_power_W=p_need,
            measured_mean_base_power_W=p_base,
            required_over_base_power=p_need / p_base if p_base > 0 else math.inf,
            harvest_efficiency_cell_over_base=efficiency,
            accel_for_required_power_g=(accel_g * math.sqrt(p_need / (efficiency * p_base))
                                        if efficiency > 0 and p_base > 0 else
                                        (math.nan if math.isnan(efficiency) else math.inf)),
            accel_if_all_base_power_harvested_g=accel_g * math.sqrt(p_need / p_base) if p_base > 0 else math.inf,
            eq8_required_amplitude_V=a_eq8,
            eq8_required_gain_V_per_g=a_eq8 / accel_g,
            eq8_time_at_paper_gain_s=eq8_time_to_full(PAPER_GAIN_V_PER_G * accel_g, battery, self.setup.v_start,
                                                      self.setup.v_diode),
            paper_gain_V_per_g=PAPER_GAIN_V_PER_G,
            measured_gain_V_per_g=self.stored_gain_v_per_g,
        )


ProgressFn = Callable[[float, float, float], None]  # (t_done_s, t_total_s, soc)

_RECORDED = ("t", "v_bat", "v_bat_term", "soc_bat", "v_stored")
_CHUNK_COLUMNS = ("t_end_s", "v_bat_V", "soc", "i_mean_A", "p_in_W", "va_peak_V", "z3_peak_m")


def _full_crossing(soc: np.ndarray, t_out: np.ndarray, taper_soc: float, t0: float) -> tuple[float, int] | None:
    """When (s, interpolated) and at which output sample the state of charge first reaches ``taper_soc`` in this
    chunk; ``None`` if it does not."""
    hit = np.flatnonzero(soc >= taper_soc)
    if not hit.size:
        return None
    k = int(hit[0])
    if k == 0:
        return t0, k
    f = (taper_soc - soc[k - 1]) / (soc[k] - soc[k - 1])
    return float(t_out[k - 1] + f * (t_out[k] - t_out[k - 1])), k


@dataclass
class _ChunkRecorder:
    """The charge curve (thinned to ``keep_every``), the per-chunk summaries and the last seconds of the run."""

    keep_every: int
    period: float  # s, one period of the base drive
    i_qd: int  # state index of the cell's discharge charge
    i_ein: int  # state index of the base energy in
    rec: dict[str, list[np.ndarray]] = field(default_factory=lambda: {k: [] for k in _RECORDED})
    cols: dict[str, list[float]] = field(default_factory=lambda: {k: [] for k in _CHUNK_COLUMNS})
    tail: dict[str, np.ndarray] = field(default_factory=dict)

    def add(self, first: bool, t_out: np.ndarray, res: SimulationResult, stop_k: int, x: np.ndarray,
            x_last: np.ndarray) -> None:
        """One chunk's outputs up to ``stop_k`` (``x``/``x_last``: the state at the chunk's start and stop)."""
        sl = slice(0 if first else 1, stop_k + 1)
        for key in self.rec:
            arr = t_out if key == "t" else res[key][0]
            self.rec[key].append(arr[sl][::self.keep_every] if first else arr[sl][self.keep_every - 1::self.keep_every])
        tail_sel = (t_out <= t_out[stop_k]) & (t_out >= t_out[stop_k] - 4.0)
        self.tail = {"t_s": t_out[tail_sel], "v_stored_V": res["v_stored"][0][tail_sel],
                     "z3_m": res["z3"][0][tail_sel], "i_bat_A": res["i_bat"][0][tail_sel]}
        dt_chunk = float(t_out[stop_k] - t_out[0])
        period = self.period
        # a sliding window of whole periods at the chunk's end for peaks, the whole chunk for means
        win = t_out >= t_out[stop_k] - max(period * math.floor(min(dt_chunk, 2.0) / period), period)
        win &= t_out <= t_out[stop_k]
        so, i_ein = self.i_qd, self.i_ein
        self.cols["t_end_s"].append(float(t_out[stop_k]))
        self.cols["v_bat_V"].append(float(res["v_bat"][0, stop_k]))
        self.cols["soc"].append(float(res["soc_bat"][0][stop_k]))
        self.cols["i_mean_A"].append(float(-(x_last[so] - x[so]) / dt_chunk) if dt_chunk > 0 else 0.0)
        self.cols["p_in_W"].append(float((x_last[i_ein] - x[i_ein]) / dt_chunk) if dt_chunk > 0 else 0.0)
        self.cols["va_peak_V"].append(float(np.max(np.abs(res["v_stored"][0][win]))))
        self.cols["z3_peak_m"].append(float(np.max(np.abs(res["z3"][0][win]))))


def run_harvest(setup: HarvestSetup, progress: ProgressFn | None = None, chunk_s: float | None = None,
                dt_out: float = 0.01, max_points: int = 20000, stop_when_full: bool = True, project: bool = True,
                rtol: float = 1e-6) -> HarvestRun:
    """Simulate ``setup.duration`` seconds (or until full) and audit the energy; project when not full."""
    wall0 = time.perf_counter()
    model, battery, x0 = setup.build()
    names = model.state_names
    so = names.index("bat_qd")
    s_below = names.index("bat_q_below_cutoff")
    duration = float(setup.duration)
    period = 1.0 / setup.freq
    dt_out = min(dt_out, period / 40.0)
    if chunk_s is None:
        chunk_s = min(max(duration / 60.0, 2.0), 30.0)
    n_chunks = max(1, math.ceil(duration / chunk_s - 1e-9))
    edges = np.linspace(0.0, duration, n_chunks + 1)
    h_max = step_cap(setup.freq)
    recorder = _ChunkRecorder(max(1, round(duration / dt_out / max_points)), period, so, names.index("E_base_in"))
    x = x0.copy()
    e_start: tuple[float, float] | None = None
    e_end = (0.0, 0.0)
    t_full: float | None = None
    steps = 0
    t_end = 0.0
    taper_soc = 1.0 - battery.taper / battery.capacity
    for c in range(n_chunks):
        t0, t1 = float(edges[c]), float(edges[c + 1])
        t_out = np.linspace(t0, t1, max(2, round((t1 - t0) / dt_out) + 1))
        res: SimulationResult = model.simulate(setup.inputs(t0, t1), t_out=t_out, x0=x, record_states=True,
                                               rtol=rtol, h_max=h_max)
        res.raise_on_failure(f"harvesting run failed in [{t0:g}, {t1:g}] s: ")
        xs = res.states
        assert xs is not None
        steps += int(res.n_steps.sum())
        if e_start is None:
            e_start = (float(res["E_mech"][0, 0]), float(res["E_elec"][0, 0]))
        stop_k = len(t_out) - 1
        crossing = _full_crossing(res["soc_bat"][0], t_out, taper_soc, t0) if t_full is None else None
        if crossing is not None:
            t_full = crossing[0]
            if stop_when_full:
                stop_k = crossing[1]
        x_last = xs[0, stop_k]
        recorder.add(c == 0, t_out, res, stop_k, x, x_last)
        e_end = (float(res["E_mech"][0, stop_k]), float(res["E_elec"][0, stop_k]))
        x = np.array(x_last)
        t_end = float(t_out[stop_k])
        if progress is not None:
            progress(t_end, duration, recorder.cols["soc"][-1])
        if t_full is not None and stop_when_full:
            break
    assert e_start is not None
    audit = power_audit(model, battery, x0, x, e_start, e_end, t_end, setup.coupling)
    projection = None
    if t_full is None and project:
        projection = project_time_to_full(setup, float(x[so]), t_end, model=model, battery=battery, x_now=x)
    cat = {k: np.concatenate(v) for k, v in recorder.rec.items()}
    return HarvestRun(
        setup=setup, battery=battery, t=cat["t"], v_bat=cat["v_bat"], v_bat_term=cat["v_bat_term"],
        soc=cat["soc_bat"], v_stored=cat["v_stored"], chunks={k: np.array(v) for k, v in recorder.cols.items()},
        tail=recorder.tail,
        reached_full=t_full is not None, t_full_s=t_full, projection=projection, audit=audit, t_end=t_end,
        q_d_start=float(x0[so]), q_d_end=float(x[so]), q_below_cutoff=float(x[s_below] - x0[s_below]),
        n_steps=steps, wall_s=time.perf_counter() - wall0,
        effects=tuple(model.effect_names), parameter_set=model.params.name,
    )
