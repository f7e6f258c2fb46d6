"""Everything a life's visits would find wrong, found in the parent before any worker starts (issue 33).

A ``[life]`` scenario is played by worker processes (:mod:`studies.health.life`); a mistake found inside one used to
kill the pool. :func:`check_life` runs the same checks first, here, and says what is wrong as one line naming the
file, key or option and what is allowed (a :class:`~board_config.errors.ConfigError` / ``InputError``, exit 2):

* the phases hold a maintenance phase (a visit *is* the maintenance built-in tests; without one no visit says
  anything);
* ``--params`` names a loadable parameter set; the ``[rig]`` effects and their parameters build a plant;
* ``life.flight_scenario`` is a loadable scenario with flight phases before its first maintenance phase;
* every ``[[life.law]]`` ``parameter`` is a parameter of that plant (a core parameter, or one of a ``[rig]``
  effect);
* at every visit the sum of a parameter's ``[rig]`` deviation and law terms stays in the accepted relative range
  [-0.95, 5] (it is no longer clipped in silence: a law that drives k3 to -240 % is a mistake in the file) and the
  deviated value inside the parameter's bounds (an effect parameter too);
* the last visit is at a plausible operating time (at most :data:`MAX_OPERATING_HOURS`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from board_config.errors import ConfigError, InputError
from board_config.parameter import DEVIATION_RANGE, ParameterError
from board_config.scenario import Scenario

if TYPE_CHECKING:
    from plant import PlantModel

#: the latest operating time a visit may have (h): about 114 years of continuous operation — any airframe's life
MAX_OPERATING_HOURS = 1.0e6


def check_life(scenario: Scenario, params: str, params_option: str | None = None) -> None:
    """Raise one clear input error for the first thing in the life that a visit would trip over (see module)."""
    life = scenario.life
    file = scenario.source
    if life is None:
        raise ConfigError(file, "life", "no [life] section")
    if not any(ph.kind == "maintenance" for ph in scenario.phases):
        raise ConfigError(file, "phase", "a [life] scenario's phases are one maintenance visit, but none is of kind "
                          "'maintenance' (add a [[phase]] with kind = \"maintenance\" long enough for MBIT.a and "
                          "MBIT.b, about 30 s)")
    last = life.visit_hours()[-1]
    if last > MAX_OPERATING_HOURS:
        raise ConfigError(file, "life.visit_interval", f"the last visit would be at {last:g} h of operating time, "
                          f"beyond any structure's life (at most {MAX_OPERATING_HOURS:g} h)")
    if life.tick_flights > 0 or life.flight_scenario != "default":
        _check_flight(scenario)
    model = _plant(scenario, params, params_option)
    known = set(model.nominal.names)
    for i, law in enumerate(life.laws):
        if law.parameter not in known:
            hint = ("; an effect's parameter needs its effect in [rig] effects" if not scenario.rig.effects
                    else "")
            raise ConfigError(file, f"life.law[{i}].parameter", f"no such model parameter '{law.parameter}' "
                              f"(known: {', '.join(model.nominal.names)}){hint}")
    _check_visits(scenario, model)


def _check_flight(scenario: Scenario) -> None:
    from studies.health.life import flight_segment

    assert scenario.life is not None
    try:
        flight_segment(scenario.source, scenario.life.flight_scenario)
    except InputError as exc:
        raise ConfigError(scenario.source, "life.flight_scenario", f"{scenario.life.flight_scenario!r}: "
                          f"{exc}") from None
    except ValueError as exc:
        raise ConfigError(scenario.source, "life.flight_scenario", str(exc)) from None


def _plant(scenario: Scenario, params: str, params_option: str | None) -> PlantModel:
    from plant import PlantModel

    try:
        return PlantModel(params, effects=list(scenario.rig.effects), terminal="amplifier",
                          effect_params=dict(scenario.rig.effect_params))
    except InputError as exc:
        text = str(exc)
        if params_option is not None and params_option not in text:
            text = f"{params_option} {params}: {text}"
        elif params_option is None and scenario.source not in text:
            text = f"{scenario.source}: [rig]: {text}"
        raise InputError(text) from None


def _check_visits(scenario: Scenario, model: PlantModel) -> None:
    """Each visit's deviations: in range before any clipping, and inside the parameters' bounds."""
    from studies.health.laws import law_value

    assert scenario.life is not None
    life = scenario.life
    lo, hi = DEVIATION_RANGE
    for k, hours in enumerate(life.visit_hours()):
        devs = {n: float(v) for n, v in scenario.rig.deviations.items()}
        for law in life.laws:
            devs[law.parameter] = devs.get(law.parameter, 0.0) + law_value(law, hours)
        for name, d in devs.items():
            laws = [f"life.law[{i}]" for i, law in enumerate(life.laws) if law.parameter == name]
            where = ", ".join(laws) or f"rig.deviations.{name}"
            if not lo <= d <= hi:  # NaN too
                raise ConfigError(scenario.source, where, f"at visit {k + 1} ({hours:g} h) the relative deviation "
                                  f"of '{name}' would be {d:g} (truth {name} × {1 + d:g}), outside the allowed "
                                  f"[{lo:g}, {hi:g}]: a smaller rate, or fewer or closer visits")
        try:
            model.nominal.with_deviations(devs, "life")
        except ParameterError as exc:
            laws = [f"life.law[{i}]" for i, law in enumerate(life.laws) if law.parameter == exc.name]
            raise ConfigError(scenario.source, ", ".join(laws) or f"rig.deviations.{exc.name}",
                              f"at visit {k + 1} ({hours:g} h): {exc.reason}") from None
