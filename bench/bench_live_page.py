"""Does the live page disturb the board? (issue 32, point 3)

One real-time board run (100 Hz, wall clock, in-process simulated rig, two maintenance visits) with the live page
attached exactly as ``shm run --live`` attaches it, in alternating blocks of the same run: no viewer, then 3 viewers
(a separate process whose viewers each load the page, its script and plotly.js as a browser does and hold the
websocket, reading every message), then none again, and so on. Each tick's start and end are recorded around the
whole tick (the board's work and the feed's); per condition: ticks, deadline misses (a tick that ended after the
next tick's deadline, as ``firmware_sim.scheduler`` counts them) and the tick jitter (start minus deadline) p50 /
p99 / max; and the messages per second each viewer received (the page's update rate).

Full: 12 blocks of 10 s (60 s with no viewer, 60 s with 3); ``--quick``: 4 blocks of 3 s. On a shared machine
other processes' CPU use shows up in p99, max and the misses of both conditions alike (the blocks alternate for
that reason); the load average before the run is recorded with the result.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path
from typing import Any, cast

import numpy as np

#: the bench's phases: name, kind, duration (s); two maintenance visits (MBIT.a and MBIT.b each), 120 s of board time
PHASES = (("parked", "ground", 3), ("visit 1", "maintenance", 55), ("between", "ground", 4),
          ("visit 2", "maintenance", 55), ("parked again", "ground", 3))
#: the bench's scenario file
SCENARIO = """
[scenario]
name = "bench_live_page"
description = "Two maintenance visits, for the live page's disturbance bench."
seed = 1

[rig]
params = "table2"
battery_initial_voltage = { value = 3.0, unit = "V" }
""" + "".join(f"""
[[phase]]
name = "{name}"
kind = "{kind}"
duration = {{ value = {duration_s}, unit = "s" }}
""" for name, kind, duration_s in PHASES)


class TickRecorder:
    """A scheduler wrapper that records each tick's start and end (``time.monotonic``) around everything the tick
    does, the live page's feed included (it wraps the publishing scheduler)."""

    def __init__(self, inner: Any, n: int) -> None:
        self._inner = inner
        self.rate, self.period, self.paced = inner.rate, inner.period, inner.paced
        self.starts = np.zeros(n)
        self.ends = np.zeros(n)
        self.count = 0

    def __getattr__(self, name: str) -> Any:
        return getattr(self._inner, name)

    def run(self, n_ticks: int, step: Any, first_tick: int = 0, progress: Any = None) -> Any:
        starts, ends = self.starts, self.ends

        def recorded(k: int, overran: bool) -> bool:
            i = self.count
            starts[i] = time.monotonic()
            stop = bool(step(k, overran))
            ends[i] = time.monotonic()
            self.count = i + 1
            return stop

        return self._inner.run(n_ticks, recorded, first_tick=first_tick, progress=progress)


def _condition(starts: np.ndarray, ends: np.ndarray, deadlines: np.ndarray, period: float) -> dict[str, float]:
    """Deadline misses and jitter of the ticks given."""
    jitter = starts - deadlines
    misses = ends > deadlines + period
    return {"ticks": int(starts.size), "deadline_misses": int(misses.sum()),
            "jitter_p50_ms": 1e3 * float(np.percentile(jitter, 50)),
            "jitter_p99_ms": 1e3 * float(np.percentile(jitter, 99)), "jitter_max_ms": 1e3 * float(jitter.max()),
            "busy_p99_ms": 1e3 * float(np.percentile(ends - starts, 99))}


def _board_run(out: Path, blocks: int, block_s: float) -> dict[str, Any]:
    from board_config.board import load_board_config
    from board_config.scenario import load_scenario
    from drivers.link import open_link
    from firmware_sim.board import Board
    from firmware_sim.runner import BoardRunner
    from firmware_sim.scheduler import Scheduler, WallClock
    from hil_stub.rig import SimulatedRig  # noqa: F401 - registers the 'sim' link's rig
    from live_page.session import LiveSession

    path = out / "bench_live_page.toml"
    path.write_text(SCENARIO)
    scenario = load_scenario(str(path))
    cfg = load_board_config(overrides=scenario.board_overrides, overrides_source=scenario.source)
    board = Board(cfg, nominal=scenario.rig.params)
    link = open_link("sim", scenario=scenario, tick=cfg.tick_period)
    session = LiveSession(("127.0.0.1", 0), linger_s=0, stream=sys.stderr)
    session.start()
    duration = blocks * block_s
    link, scheduler = session.attach_board(board, link, Scheduler(cfg.tick_rate, WallClock()), title="bench",
                                           planned_s=duration, paced=True)
    recorder = TickRecorder(scheduler, round(duration * cfg.tick_rate) + 1)
    runner = BoardRunner(board, link, scheduler=cast(Any, recorder), on_event=session.on_event)  # a wrapper
    start = time.monotonic() + 0.5
    viewers = subprocess.Popen([sys.executable, "-m", "bench.live_viewers", session.server.url, repr(start),
                                repr(block_s), str(blocks), "3"], stdout=subprocess.PIPE, text=True)
    time.sleep(max(0.0, start - time.monotonic()))
    link.open()
    try:
        result = runner.run(duration)
    finally:
        link.close()
        session.finish("finished")
        session.server.stop()
    received = json.loads(viewers.communicate(timeout=60)[0])
    n = recorder.count
    return {"starts": recorder.starts[:n], "ends": recorder.ends[:n], "start": start, "received": received,
            "period": cfg.tick_period, "stats": result.stats.as_dict(), "messages_sent": session.server.messages_sent}


def run(out: Path, quick: bool = False) -> dict[str, Any]:
    blocks, block_s = (4, 3.0) if quick else (12, 10.0)
    load = os.getloadavg()
    r = _board_run(out, blocks, block_s)
    starts, ends, period = r["starts"], r["ends"], r["period"]
    block = np.floor((starts - r["start"]) / block_s).astype(int)
    # tick i's deadline is start + i * period; no tick starts before its deadline, so the run's start is the
    # earliest start - i * period (to within the clock's resolution)
    ticks = np.arange(starts.size)
    deadlines = float(np.min(starts - ticks * period)) + ticks * period
    res: dict[str, Any] = {"blocks": blocks, "block_s": block_s, "load_average_before": list(load),
                           "messages_sent": r["messages_sent"], "run_tick_stats": r["stats"]}
    for name, odd in (("no_viewer", 0), ("three_viewers", 1)):
        sel = (block % 2) == odd
        res[name] = _condition(starts[sel], ends[sel], deadlines[sel], period)
    rates = [n / s for counts in r["received"] for n, s in counts if s > 0]
    res["viewer_updates_per_s_min"] = min(rates) if rates else None
    res["viewer_updates_per_s_mean"] = float(np.mean(rates)) if rates else None
    for name in ("no_viewer", "three_viewers"):
        c = res[name]
        print(f"   {name}: {c['ticks']} ticks, {c['deadline_misses']} deadline misses, jitter p50 "
              f"{c['jitter_p50_ms']:.3f} ms, p99 {c['jitter_p99_ms']:.3f} ms, max {c['jitter_max_ms']:.1f} ms")
    return res
