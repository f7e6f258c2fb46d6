"""The same campaign on a Dask cluster (a distributed LocalCluster with worker processes) gives the same numbers,
bit for bit, as in-process execution; an unreachable scheduler is a clear error."""

from __future__ import annotations

import time

import numpy as np
import pytest

distributed = pytest.importorskip("distributed")

from studies.campaign import CampaignError, build_spec, connect_dask, run_campaign  # noqa: E402


def test_dask_local_cluster_gives_identical_numbers(tmp_path):
    spec = build_spec("table2", mbits="both", ranges="10:30:10", n_runs=3, seed=5, batch_size=2)
    local = run_campaign(spec, tmp_path / "local", workers=1)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                                  silence_logs=40) as cluster:
        remote = run_campaign(spec, tmp_path / "dask", dask_scheduler=cluster.scheduler_address)
    assert remote.complete and remote.executor.startswith("dask tcp://")
    assert remote.n_computed == len(spec.batches())
    for key in spec.mbit_keys:
        a, b = local.result.mbits[key], remote.result.mbits[key]
        assert np.array_equal(a.eps, b.eps) and np.array_equal(a.z3_meas, b.z3_meas)
        assert np.array_equal(a.fault, b.fault) and np.array_equal(a.fault_time, b.fault_time, equal_nan=True)
    assert [s.row() for s in local.result.summary()] == [s.row() for s in remote.result.summary()]
    assert np.array_equal(local.result.values, remote.result.values)


def test_unreachable_scheduler_is_a_clear_error_quickly():
    t0 = time.perf_counter()
    with pytest.raises(CampaignError, match=r"cannot reach the Dask scheduler at 'tcp://127.0.0.1:9' within 1 s"):
        connect_dask("tcp://127.0.0.1:9", timeout_s=1.0)
    assert time.perf_counter() - t0 < 30  # not a hang
    with pytest.raises(CampaignError, match="cannot"):
        connect_dask("not-an-address::", timeout_s=1.0)
