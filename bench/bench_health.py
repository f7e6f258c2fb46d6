"""Health over time (issue 17): a 24-visit life in one run (target: < 60 s wall on 2 cores), ``shm health`` on it,
and the prognosis challenge with ProgPy's metrics against the feature-only baseline.

Reported: the life's wall time on the process pool (2 workers) and, as the same-run baseline, the wall time of the
first four visits in one process (extrapolated to 24); the health assessment's wall time as of a few visits before the
board's first FAULT and whether its 90 % interval holds that visit; the challenge's summary (coverage, α-λ,
prognostic horizon, stable lives, sudden damage, baseline side by side, by group: core, effect, few-visits,
out-of-family) and its wall time (the lives as tasks on ``--scheduler``, two local workers by default). ``--quick``
runs the smoke size of the challenge; the environment variable ``MFC_SHM_HEALTH_CHALLENGE_PER_GROUP=N`` keeps the
first N lives of each group (a reduced run).
"""

from __future__ import annotations

import os
import time
from dataclasses import replace
from pathlib import Path


def run(out_dir: Path, quick: bool, scheduler: str | None = None) -> dict:
    from board_config.scenario import load_scenario
    from studies.health.assess import assess_health
    from studies.health.challenge import challenge_lives, run_challenge
    from studies.health.life import run_life, write_life_log

    sc = load_scenario("aging")
    t0 = time.perf_counter()
    life = run_life(sc, seed=sc.seed, params="table2", workers=2)
    life_wall = time.perf_counter() - t0
    run_dir = out_dir / "health_aging_run"
    run_dir.mkdir(parents=True, exist_ok=True)
    write_life_log(life, sc, run_dir, seed=sc.seed, params="table2")
    one = [v.wall_s for v in life.visits]
    t0 = time.perf_counter()
    if sc.life is None:
        raise RuntimeError(f"{sc.source}: the aging scenario has no [life] table")
    small = replace(sc, life=replace(sc.life, visits=4))
    run_life(small, seed=sc.seed, params="table2", workers=1)
    serial4 = time.perf_counter() - t0

    first = life.first_fault_visit
    hours = {v.visit: v.operating_hours for v in life.visits}
    health = {}
    if first is not None and first > 4:
        as_of = hours[first - 3]
        t0 = time.perf_counter()
        a = assess_health([str(run_dir)], params="table2", as_of=as_of, workers=2)
        f = a.doc["forecast"]
        vis = f.get("trip_visits_90") or [None, None]
        health = {"as_of_hours": as_of, "wall_s": time.perf_counter() - t0, "trip_operating_hours":
                  f["trip_operating_hours"], "trip_interval_90": f["trip_interval_90"], "trip_visits_90": vis,
                  "board_first_fault_visit": first,
                  "interval_holds_first_fault": vis[0] is not None and vis[0] <= first <= (vis[1] or 10 ** 9),
                  "levels": a.doc["levels"]}

    t0 = time.perf_counter()
    per_group = os.environ.get("MFC_SHM_HEALTH_CHALLENGE_PER_GROUP")  # a reduced run: that many lives per group
    lives = challenge_lives("smoke" if quick else "full", per_group=int(per_group) if per_group else None)
    ch = run_challenge(lives, workers=2, progress=lambda s: print(s, flush=True), scheduler=scheduler or "local")
    challenge_wall = time.perf_counter() - t0
    import json

    (out_dir / "health_challenge.json").write_text(json.dumps(ch.to_json(), indent=1,
                                                               default=lambda o: o.tolist() if hasattr(o, "tolist")
                                                               else str(o)))
    return {
        "life_visits": len(life.visits), "life_wall_s_2_workers": life_wall, "life_target_met_60s": life_wall < 60,
        "life_visit_wall_s_mean": sum(one) / len(one), "serial_4_visits_wall_s": serial4,
        "serial_24_visits_extrapolated_s": serial4 * 6, "first_fault_visit": first,
        "health": health, "challenge_lives": len(ch.lives), "challenge_wall_s": challenge_wall,
        "challenge": ch.summary.to_json(), "f1_alarm_threshold_rel": ch.f1_threshold,
        "load_average_1min": os.getloadavg()[0],
    }
