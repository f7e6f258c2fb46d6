"""Shared fixtures. Small, fast cases; compiled kernels are cached on disk between runs."""

from __future__ import annotations

import os

import pytest

os.environ.setdefault("MPLBACKEND", "Agg")
os.environ.setdefault("MFC_SHM_THREADS", "1")


@pytest.fixture(scope="session")
def table2_model():
    from plant import PlantModel

    return PlantModel("table2")


@pytest.fixture(scope="session")
def table2_params():
    from board_config import load_parameter_set

    return load_parameter_set("table2")
