"""A count in a message agrees with its noun (``studies.batch.runner.counted``): a life page of one worker says
'1 worker', a campaign with one batch that failed says '1 of 1 batch did not finish' (were '1 workers', '1 of 1
batches'). A life that lost one worker: tests/studies/test_life_pool.py ('1 worker lost — its visit runs again',
was '1 worker(s) lost — the visit(s) they were running run again'). shm health --as-of with one visit up to it
says '1 visit up to --as-of' (was '1 visit(s)')."""

from __future__ import annotations

from pathlib import Path

import pytest

from board_config.errors import InputError
from studies.campaign.runner import BatchFailure, CampaignOutcome
from studies.health.estimate import Visit
from studies.health.life_report import life_page


def _life(workers: int) -> dict:
    visit = {"visit": 1, "operating_hours": 0.0, "verdict": "PASS", "truth_deviations": {}, "mbits": [],
             "records": []}
    return {"scenario": "tiny-life", "scenario_file": "tiny.toml", "seed": 3, "params": "table2", "workers": workers,
            "wall_s": 1.0, "visits": [visit], "first_fault_visit": None, "first_fault_operating_hours": None,
            "flights_between_visits": 40, "visit_interval_h": 400.0}


def test_the_life_page_counts_its_workers_in_words():
    assert "<p>1 worker; every visit" in life_page(_life(1), None)
    assert "<p>2 workers; every visit" in life_page(_life(2), None)


def test_a_campaign_of_one_batch_that_failed_says_batch():
    def outcome(n_batches: int) -> CampaignOutcome:
        return CampaignOutcome(spec=None, out_dir=Path("c"), result=None, n_batches=n_batches, n_reused=0,
                               n_computed=n_batches - 1, failures=[BatchFailure("b0", "boom")])

    assert outcome(1).failure_message().startswith("1 of 1 batch did not finish (0 finished and stored in c/batches)")
    assert outcome(3).failure_message().startswith("1 of 3 batches did not finish (2 finished")


@pytest.mark.parametrize(("hours", "said"), [
    ([0.0, 100.0], "1 visit up to --as-of 50 h: a trend needs at least two visits (the sources hold 2 visits at 0, "
                   "100 h)"),
    ([0.0], "1 visit up to --as-of 50 h: a trend needs at least two visits (the sources hold 1 visit at 0 h)"),
    ([100.0, 200.0], "0 visits up to --as-of 50 h"),
], ids=["one-of-two", "one-of-one", "none"])
def test_health_as_of_counts_its_visits_in_words(hours, said, monkeypatch):
    import studies.health.assess as assess_mod

    monkeypatch.setattr(assess_mod, "load_visits", lambda sources: [Visit(h, [], i + 1) for i, h in enumerate(hours)])
    with pytest.raises(InputError) as e:
        assess_mod.assess_health(["life_run"], as_of=50.0)
    assert str(e.value).startswith(said), str(e.value)
