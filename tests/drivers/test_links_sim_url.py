"""``sim`` is opened like any URL (issue 13.5): drivers.open_link with the caller's defaults for what the URL leaves
out — ``shm run`` passes its scenario, --seed, --params and board tick, so a bare ``sim`` is the run's own rig."""

from __future__ import annotations

import hil_stub.rig  # noqa: F401  (registers the sim rig factory)
from board_config.scenario import load_scenario
from drivers import open_link
from drivers.sim_link import InProcessLink


def test_bare_sim_takes_the_callers_defaults():
    scen = load_scenario("degraded")
    link = open_link("sim", scenario=scen, seed=7, params="table2", tick=0.02)
    assert isinstance(link, InProcessLink) and link.url == "sim"  # messages still name the URL as given
    assert link.rig.scenario is scen and link.rig.seed == 7 and link.rig.tick == 0.02 and link.tick == 0.02
    assert link.rig.params.name == "table2"


def test_unset_defaults_fall_back_to_the_scenario():
    scen = load_scenario("degraded")
    link = open_link("sim", scenario=scen, seed=None, params=None, tick=0.01)
    assert link.rig.seed == scen.seed and link.rig.deviations == open_link("sim:degraded").rig.deviations


def test_the_url_wins_over_the_defaults():
    link = open_link("sim:maintenance?seed=2", scenario=load_scenario("degraded"), seed=7)
    assert link.rig.scenario.name == "maintenance" and link.rig.seed == 2
    link = open_link("sim://?seed=3", scenario=load_scenario("degraded"))
    assert link.rig.scenario.name == "degraded" and link.rig.seed == 3


def test_hardware_links_ignore_the_sim_defaults():
    link = open_link("socket://127.0.0.1:9?timeout=0.05", scenario=load_scenario("degraded"), seed=1, tick=0.01)
    assert link.url == "socket://127.0.0.1:9?timeout=0.05" and link.timeout == 0.05
