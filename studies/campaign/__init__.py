"""Monte-Carlo MBIT campaign (seed paper Sec. 4.2, Fig. 11): degraded units, batched simulation, the condition
monitor, detection statistics with Wilson intervals, a resumable result store, local or Dask execution, ROC view.

Typical use::

    from studies.campaign import build_spec, run_campaign
    spec = build_spec("table2", mbits="both", ranges="0:50:10", n_runs=100, seed=1)
    outcome = run_campaign(spec, "out/campaign", workers=2)
    for row in outcome.result.summary():
        print(row.label, row.range_label, row.n_detected, row.probability, row.interval)

Modules: :mod:`.spec` (ranges, draws, seeds), :mod:`.build` (validated spec from names), :mod:`.worker` (one
batch), :mod:`.store` (partial results, resume), :mod:`.runner` (executors, crash handling), :mod:`.results`
(assembled runs, tables, files), :mod:`.statistics` (Wilson), :mod:`.roc` (threshold sweep), :mod:`.paper`,
:mod:`.figures` (Fig. 11, error traces, ROC; imported on demand: matplotlib).
"""

from studies.campaign.build import build_spec, select_mbits
from studies.campaign.results import CampaignResult, MbitRuns, StoredTraces, load_traces
from studies.campaign.roc import RocTable, roc_sweep, verdicts_at
from studies.campaign.runner import (
    BatchFailure,
    CampaignError,
    CampaignOutcome,
    connect_dask,
    run_campaign,
)
from studies.campaign.spec import (
    SIGN_CONVENTIONS,
    BatchSpec,
    CampaignSpec,
    DeviationRange,
    draw_deviations,
    parse_ranges,
)
from studies.campaign.statistics import DetectionStat, wilson_interval
from studies.campaign.store import CampaignStoreError, ResultStore
from studies.campaign.worker import BatchResult, run_batch

__all__ = [
    "SIGN_CONVENTIONS",
    "BatchFailure",
    "BatchResult",
    "BatchSpec",
    "CampaignError",
    "CampaignOutcome",
    "CampaignResult",
    "CampaignSpec",
    "CampaignStoreError",
    "DetectionStat",
    "DeviationRange",
    "MbitRuns",
    "ResultStore",
    "RocTable",
    "StoredTraces",
    "build_spec",
    "connect_dask",
    "draw_deviations",
    "load_traces",
    "parse_ranges",
    "roc_sweep",
    "run_batch",
    "run_campaign",
    "select_mbits",
    "verdicts_at",
    "wilson_interval",
]
