"""The health trip's MBIT batches integrate on the thread count every batch uses (``$MFC_SHM_THREADS``, one per
task on a Dask worker), not a fixed number (issue 31: one core per worker)."""

from __future__ import annotations

import numpy as np

import plant
from plant.stepper import default_threads
from studies.health.trip import fault_batch


def test_a_trip_batch_integrates_on_the_threads_mfc_shm_threads_says(monkeypatch) -> None:
    used: list[int] = []
    simulate = plant.PlantModel.simulate

    def spy(self, *args, **kwargs):
        used.append(kwargs.get("threads") or default_threads())
        return simulate(self, *args, **kwargs)

    monkeypatch.setattr(plant.PlantModel, "simulate", spy)
    monkeypatch.setenv("MFC_SHM_THREADS", "1")
    fault = fault_batch("table2", np.zeros((2, 3)))
    assert fault.shape == (2,) and not fault.any()  # the nominal board does not trip
    assert used and set(used) == {1}, used
