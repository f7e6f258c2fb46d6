"""What a full recharge would take: Eq. 8's closed forms (unloaded source, ideal bridge), the mean power the cell
must take in, and the open-circuit base power of the laminate (an upper bound for any harvesting circuit)."""

from __future__ import annotations

import math

import numpy as np

from board_config import ParameterSet
from plant.battery import TheveninBattery
from plant.model import PlantModel
from plant.rectifier import FullBridge
from plant.signals import InputSignals
from studies.harvest.setup import step_cap


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
    res.raise_on_failure("open-circuit power batch failed: ")
    xs = res.states
    assert xs is not None
    i_e = model.state_names.index("E_base_in")
    p_in = (xs[:, -1, i_e] - xs[:, 1, i_e]) / (t_end - settle_s)
    v_pk = np.max(np.abs(res["v_stored"][:, 1:]), axis=1)
    return p_in, v_pk
