"""An effect file emitted by ``shm discover`` against the same physics written by hand from the plant's seam: both
simulated on a 1.5 s sweep of the Table-2 beam (tip displacement, tight tolerance)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np


def emitted_against_hand(tmp_path: Path, term: Any, values: dict[str, float], hand: type,
                         hand_values: dict[str, float]) -> tuple[float, float]:
    """The dictionary ``term`` emitted at ``values`` (its coefficient and shape) and the ``hand`` effect at
    ``hand_values``: (largest change of z3 the hand effect makes, largest difference between the two), m."""
    from board_config import load_parameter_set
    from plant import PlantModel
    from workbench.discover._effect_writer import emit_effect_source
    from workbench.simulation import synth_record, synth_test

    base = load_parameter_set("table2")
    f = tmp_path / "emitted.py"
    f.write_text(emit_effect_source([term], values))
    rec = synth_record(synth_test("sweep", duration_s=1.5), PlantModel(base), seed=None)
    inputs, t = rec.input_signals(), rec.t
    emitted, by_hand = PlantModel(base, effects=[str(f)]), PlantModel(base, effects=[hand])
    pe, ph = emitted.p_nominal.copy(), by_hand.p_nominal.copy()
    for name, v in values.items():
        pe[emitted.param_index(name)] = v
    for name, v in hand_values.items():
        ph[by_hand.param_index(name)] = v
    ze = emitted.simulate(inputs, t_out=t, params=pe, rtol=1e-9)["z3_meas"][0]
    zh = by_hand.simulate(inputs, t_out=t, params=ph, rtol=1e-9)["z3_meas"][0]
    nominal = PlantModel(base).simulate(inputs, t_out=t, rtol=1e-9)["z3_meas"][0]
    return float(np.max(np.abs(zh - nominal))), float(np.max(np.abs(ze - zh)))
