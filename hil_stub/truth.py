"""Build the truth rig the HIL stub serves: a :class:`hil_stub.rig.SimulatedRig` for a scenario, with the fault
plan's physics changes (parameter deviations, added effects) merged into the scenario's ``[rig]`` table.

The rig built here for ``(scenario, seed)`` without changes is the same rig ``shm run --link sim`` builds for that
scenario and seed, so a board over a hardware link and a board in-process face the same truth.
"""

from __future__ import annotations

from typing import Any

from board_config.scenario import Scenario, load_scenario
from hil_stub.faults import TruthChanges
from hil_stub.rig import SimulatedRig


def build_truth_rig(scenario: str | Scenario | None = None, *, seed: int | None = None, params: str | None = None,
                    truth: TruthChanges | None = None, tick: float = 0.01,
                    hv_present: bool | None = None, lookahead_ticks: int | None = None) -> SimulatedRig:
    """The simulated rig for ``scenario`` (a shipped name, a TOML path, a Scenario or None for a quiet parked rig).

    ``params`` overrides the scenario's parameter set; ``truth.deviations`` are added to (and override, key by key)
    the scenario's relative deviations; ``truth.effects`` are appended to the scenario's effects. ``hv_present``
    forces the HV-equipment presence (default: the scenario's phases; without a scenario the amplifier is connected,
    as on a lab bench, so demands written by an operator move the laminate). ``lookahead_ticks``: how many ticks the
    rig may integrate at once while nothing changes (the rig's default is fast in virtual time; a real-time rig
    wants 1 so that no single tick carries the cost of 50).
    """
    scen = load_scenario(scenario) if isinstance(scenario, str) else scenario
    spec = scen.rig if scen is not None else None
    truth = truth or TruthChanges()
    deviations = {**(dict(spec.deviations) if spec else {}), **truth.deviations}
    effects = list(spec.effects if spec else ())
    effects += [e for e in truth.effects if e not in effects]
    if hv_present is None and scen is None:
        hv_present = True
    extra: dict[str, Any] = {} if lookahead_ticks is None else {"lookahead_ticks": lookahead_ticks}
    rig = SimulatedRig(scen, seed=seed, params=params, deviations=deviations, effects=effects, tick=tick,
                       hv_present=hv_present, **extra)
    # Load the amplifier-terminal composition now: SimulatedRig builds it on first HV contact, and loading the
    # compiled kernels (~0.4 s) there would stall a real-time rig for ~40 ticks in the middle of a maintenance visit
    # (the board would see a frozen sample counter). Loading it early changes no result.
    rig._model("amplifier")
    return rig
