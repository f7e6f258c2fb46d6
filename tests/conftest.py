"""Shared fixtures. Small, fast cases; compiled kernels are cached on disk between runs."""

from __future__ import annotations

import os

import pytest
from hypothesis import HealthCheck, settings

# The tests mirror the packages (tests/<package>/test_*.py, no __init__: each file is imported by its own name, its
# folder put on the path by pytest). What tests of several rooms share lives in a support module here in tests/
# (on the path with this conftest); a test module imports from its own room only (the mutation sample, which runs
# other rooms' tests, loads them from their files).

os.environ.setdefault("MPLBACKEND", "Agg")
os.environ.setdefault("MFC_SHM_THREADS", "1")

# Two workers on two cores, often beside a benchmark or the kernels' compilation: how long a strategy takes to draw
# is the machine's load, not a property of the code (a clean-clone run beside the damage challenge failed
# test_work_items_cover_the_batch_in_whole_groups on "2 inputs in 1.17 s" of three integers). The other health
# checks stay.
settings.register_profile("suite", suppress_health_check=[HealthCheck.too_slow])
settings.load_profile("suite")


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Mark the measured-slow tests of ``slow_tests.SLOW_TESTS`` ``slow`` (``make test-fast`` leaves them out), then
    run the slow ones first: ``pytest -n 2`` hands tests out in this order, and a long test left for the end keeps
    one worker busy while the other idles (the longest first is the classic rule for the shortest makespan)."""
    from slow_tests import SLOW_TESTS

    for item in items:
        name = getattr(item, "originalname", None) or item.name
        if f"{item.path.name}::{name}" in SLOW_TESTS:
            item.add_marker(pytest.mark.slow)
    items.sort(key=lambda item: item.get_closest_marker("slow") is None)  # stable: files keep their order


@pytest.fixture(scope="session")
def table2_model():
    from plant import PlantModel

    return PlantModel("table2")


@pytest.fixture(scope="session")
def table2_params():
    from board_config import load_parameter_set

    return load_parameter_set("table2")
