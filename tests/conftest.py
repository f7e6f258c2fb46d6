"""Shared fixtures. Small, fast cases; compiled kernels are cached on disk between runs."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest

# The tests mirror the packages (tests/<package>/test_*.py, no __init__: each file is imported by its own name).
# A few tests reuse another room's test module (the mutation sample, the board scenarios of test_links_board): every
# room is on the path from the start, so such an import does not depend on which room pytest collected first.
sys.path[1:1] = sorted(str(p) for p in Path(__file__).parent.iterdir() if p.is_dir() and p.name.isidentifier())

os.environ.setdefault("MPLBACKEND", "Agg")
os.environ.setdefault("MFC_SHM_THREADS", "1")


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Mark the measured-slow tests of ``slow_tests.SLOW_TESTS`` ``slow`` (``make test-fast`` leaves them out)."""
    from slow_tests import SLOW_TESTS

    for item in items:
        name = getattr(item, "originalname", None) or item.name
        if f"{item.path.name}::{name}" in SLOW_TESTS:
            item.add_marker(pytest.mark.slow)


@pytest.fixture(scope="session")
def table2_model():
    from plant import PlantModel

    return PlantModel("table2")


@pytest.fixture(scope="session")
def table2_params():
    from board_config import load_parameter_set

    return load_parameter_set("table2")
