"""The model run on a record's own test: replay of its inputs, synthetic records, frequency responses."""

from __future__ import annotations

from workbench.simulation._frequency_response import stepped_sine
from workbench.simulation._replay import (
    DEFAULT_HORIZON_S,
    DEFAULT_INTERVAL_S,
    FrfReplay,
    Replay,
    SimulationFailed,
    estimate_noise_std,
    linearise,
    model_for,
    model_output_for,
    replay,
    replay_frf,
)
from workbench.simulation._synth import (
    blame_non_finite,
    neutral_effects,
    synth_frf,
    synth_inputs,
    synth_record,
    synth_test,
    truth_model,
    write_frf_record,
)

__all__ = [
    "DEFAULT_HORIZON_S",
    "DEFAULT_INTERVAL_S",
    "FrfReplay",
    "Replay",
    "SimulationFailed",
    "blame_non_finite",
    "estimate_noise_std",
    "linearise",
    "model_for",
    "model_output_for",
    "neutral_effects",
    "replay",
    "replay_frf",
    "stepped_sine",
    "synth_frf",
    "synth_inputs",
    "synth_record",
    "synth_test",
    "truth_model",
    "write_frf_record",
]
