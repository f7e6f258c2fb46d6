"""Assemble a :class:`~studies.campaign.spec.CampaignSpec` from names (parameter set, MBIT keys, ranges),
validating every input with a message that names it."""

from __future__ import annotations

import math
from pathlib import Path

from board_config import MbitDefinition, MonitorSettings, load_mbit_definitions, load_monitor_settings
from board_config.errors import InputError
from plant import PlantModel
from studies.campaign.spec import (
    DEFAULT_BATCH_SIZE,
    DEFAULT_DEVIATED,
    CampaignSpec,
    DeviationRange,
    check_deviation_bounds,
    core_bounds,
    parse_ranges,
)


def select_mbits(selection: str, definitions: dict[str, MbitDefinition]) -> tuple[MbitDefinition, ...]:
    """``a``, ``b``, ``both`` (a and b), ``all`` or a comma list of MBIT keys."""
    text = selection.strip().lower()
    if text == "both":
        keys = ["a", "b"]
    elif text == "all":
        keys = list(definitions)
    else:
        keys = [k.strip() for k in text.split(",") if k.strip()]
    if not keys:
        raise InputError(f"--mbit {selection!r}: no MBIT named (choose a, b or both)")
    unknown = [k for k in keys if k not in definitions]
    if unknown:
        raise InputError(f"--mbit {selection!r}: unknown MBIT {unknown[0]!r} (defined: {', '.join(definitions)}; "
                         "or both / all)")
    if len(set(keys)) != len(keys):
        raise InputError(f"--mbit {selection!r}: an MBIT is listed twice")
    return tuple(definitions[k] for k in keys)


def build_spec(
    params: str = "table2",
    mbits: str = "both",
    ranges: str | tuple[DeviationRange, ...] = "0:50:10",
    n_runs: int = 100,
    seed: int = 1,
    *,
    deviated: tuple[str, ...] = DEFAULT_DEVIATED,
    sign: str = "both",
    noise_std: float = 0.0,
    batch_size: int = DEFAULT_BATCH_SIZE,
    rtol: float = 1e-6,
    mbit_config: str | Path | None = None,
    monitor: MonitorSettings | str | Path | None = None,
) -> CampaignSpec:
    """A validated campaign specification (see :mod:`studies.campaign.spec` for the meaning of each field)."""
    if isinstance(n_runs, bool) or not isinstance(n_runs, int) or n_runs <= 0:
        raise InputError(f"--n must be a positive integer (runs per range), got {n_runs!r}")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise InputError(f"--seed must be an integer >= 0, got {seed!r}")
    rngs = parse_ranges(ranges) if isinstance(ranges, str) else tuple(ranges)
    defs = load_mbit_definitions(mbit_config)
    chosen = select_mbits(mbits, defs)
    settings = monitor if isinstance(monitor, MonitorSettings) else load_monitor_settings(monitor)
    model = PlantModel(params)
    deviated = tuple(deviated)
    if not deviated:
        raise InputError("--deviate: name at least one parameter")
    for name in deviated:
        if name not in model.param_names:
            raise InputError(f"--deviate: unknown parameter {name!r} (model parameters: "
                             f"{', '.join(model.param_names)})")
    if len(set(deviated)) != len(deviated):
        raise InputError("--deviate: a parameter is listed twice")
    nominal = tuple(model.param_value(n) for n in deviated)
    bounds = core_bounds()
    for par in model.own_parameters:
        bounds[par.name] = (float(par.lower), float(par.upper))
    check_deviation_bounds(deviated, nominal, bounds, rngs, sign)
    if not (math.isfinite(noise_std) and noise_std >= 0):
        raise InputError(f"noise standard deviation must be >= 0, got {noise_std!r}")
    return CampaignSpec(params_toml=model.params.to_toml(), params_name=model.params.name, mbits=chosen,
                        ranges=rngs, n_runs=n_runs, seed=seed, monitor=settings, deviated=deviated,
                        nominal_values=nominal, sign=sign, noise_std=float(noise_std), batch_size=batch_size,
                        rtol=rtol)
