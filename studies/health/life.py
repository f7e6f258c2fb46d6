"""A life in one run: a scenario's visit played at every maintenance visit of an operating life, in parallel.

``[life]`` (:class:`board_config.scenario.LifeSpec`) says when the visits are (operating hours) and how the truth
plant degrades (:mod:`.laws`). Each visit is a full board run of the scenario's phases — the 100 Hz firmware, the
simulated rig with that visit's deviations, the link, the MBITs and the condition monitor — on a fresh board and rig
(the flights between visits are summarised: their count and hours are logged, not ticked — unless ``[life]
tick_flights`` asks for some: then the board first ticks that many flights, :func:`with_ticked_flights`). Visits
are independent, so they run on a local process pool (or in this process with ``workers=1``); visit ``i`` draws
its rig seed from ``SeedSequence([seed, i])``, so a life is reproducible whatever the number of workers.

The parent process writes one usage log (``usage.db``: one run, board time = operating hours × 3600 s + the time
inside the visit), the visit records (:mod:`.visit_records`), ``life.json`` and ``timeline.txt``.
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from board_config.scenario import Scenario, load_scenario
from firmware_sim.events import BoardEvent
from studies.health.laws import deviations_at

if TYPE_CHECKING:
    from plant import PlantModel

SECONDS_PER_HOUR = 3600.0


def visit_seed(seed: int, visit: int) -> int:
    """The rig seed of visit ``visit`` (independent of workers and of the other visits)."""
    return int(np.random.SeedSequence([int(seed), int(visit)]).generate_state(1)[0])


@dataclass(frozen=True, slots=True)
class VisitMbit:
    """One MBIT's result at a visit, as the board's ``mbit_result`` event gives it: its verdict, the monitor's
    largest counter and residual (1) and the board time of its FAULT (s; None without one)."""

    mbit: str
    label: str
    verdict: str
    max_count: int
    max_eps: float
    fault_time_s: float | None

    @classmethod
    def from_event(cls, data: Mapping[str, Any]) -> VisitMbit:
        return cls(data["mbit"], data["label"], data["verdict"], data["max_count"], data["max_eps"],
                   data.get("fault_time_s"))

    def to_json(self) -> dict[str, Any]:  # a row of life.json's visits[].mbits
        return {"label": self.label, "verdict": self.verdict, "max_count": self.max_count, "max_eps": self.max_eps,
                "fault_time_s": self.fault_time_s}


@dataclass(frozen=True, slots=True)
class TickedFlights:
    """The flights the board ticked before a visit: how many, their board time (s), the events they logged by
    kind, and of those the incidents and usage summaries."""

    ticked: int
    board_time_s: float
    events: dict[str, int]

    @property
    def incidents(self) -> int:
        return self.events.get("incident", 0)

    @property
    def usage_summaries(self) -> int:
        return self.events.get("usage_summary", 0)

    def to_json(self) -> dict[str, Any]:  # life.json's visits[].ticked_flights
        return {"ticked": self.ticked, "board_time_s": self.board_time_s, "events": self.events,
                "incidents": self.incidents, "usage_summaries": self.usage_summaries}


@dataclass
class VisitRun:
    visit: int
    operating_hours: float
    deviations: dict[str, float]
    seed: int
    events: list[BoardEvent]
    wall_s: float
    verdict: str = "NONE"
    mbits: list[VisitMbit] = field(default_factory=list)
    flights: TickedFlights | None = None  # the ticked flights before this visit (tick_flights > 0)


#: the nominal plant model of each parameter set, built once per worker process
_PROCESS_CACHE: dict[str, PlantModel] = {}


def run_visit(source: str, visit: int, hours: float, deviations: dict[str, float], seed: int, params: str,
              board_config: str | None = None) -> VisitRun:
    """One visit: the scenario's phases on a fresh board and rig with these truth deviations (picklable)."""
    from board_config.board import load_board_config
    from drivers.sim_link import InProcessLink
    from firmware_sim.board import Board
    from firmware_sim.runner import BoardRunner
    from hil_stub.rig import SimulatedRig
    from plant import PlantModel

    t0 = time.perf_counter()
    sc = load_scenario(source)
    sc = sc.with_rig(deviations=dict(deviations))
    flight_end = 0.0
    if sc.life is not None and sc.life.tick_flights > 0 and visit > 1:
        sc, flight_end = with_ticked_flights(sc, sc.life.tick_flights)
    cfg = load_board_config(board_config, overrides=sc.board_overrides, overrides_source=sc.source)
    key = f"nominal:{params}"
    if key not in _PROCESS_CACHE:
        _PROCESS_CACHE[key] = PlantModel(params, terminal="amplifier")
    rig = SimulatedRig(sc, seed=seed, params=params, tick=cfg.tick_period)
    link = InProcessLink(rig, tick=cfg.tick_period)
    board = Board(cfg, nominal=params, nominal_model=_PROCESS_CACHE[key])
    runner = BoardRunner(board, link, rearm_times=[e.at for e in sc.events_of("rearm")], trace_every=None)
    link.open()
    try:
        res = runner.run(sc.duration)
    finally:
        link.close()
    verdicts = [e.data["verdict"] for e in res.events if e.kind == "maintenance_verdict"]
    mbits = [VisitMbit.from_event(e.data) for e in res.events if e.kind == "mbit_result"]
    flights = None
    if flight_end > 0:
        during = [e for e in res.events if e.time < flight_end]
        kinds: dict[str, int] = {}
        for e in during:
            kinds[e.kind] = kinds.get(e.kind, 0) + 1
        flights = TickedFlights(sc.life.tick_flights if sc.life else 0, flight_end, kinds)
    return VisitRun(visit, hours, dict(deviations), seed, list(res.events), time.perf_counter() - t0,
                    verdicts[-1] if verdicts else "NONE", mbits, flights)


def flight_segment(life_source: str, flight_scenario: str) -> tuple[tuple[Any, ...], tuple[Any, ...], float]:
    """(phases, events, length in s) of one flight: ``flight_scenario``'s phases before its first maintenance
    phase, with the events inside them. A relative ``.toml`` path is taken from the life scenario's folder."""
    p = Path(flight_scenario)
    if flight_scenario.endswith(".toml") and not p.is_absolute() and not p.exists():
        p = Path(life_source).parent / p
    fs = load_scenario(p if flight_scenario.endswith(".toml") else flight_scenario)
    phases = []
    for ph in fs.phases:
        if ph.kind == "maintenance":
            break
        phases.append(ph)
    if not phases:
        raise ValueError(f"{fs.source}: no flight phases before its first maintenance phase (life.flight_scenario)")
    end = phases[-1].end
    events = tuple(e for e in fs.events if e.at < end and e.kind != "rearm")
    return tuple(phases), events, end


def with_ticked_flights(sc: Scenario, n: int) -> tuple[Scenario, float]:
    """The visit scenario preceded by ``n`` ticked flights; returns it and the board time (s) the flights take."""
    from dataclasses import replace

    assert sc.life is not None
    phases, events, length = flight_segment(sc.source, sc.life.flight_scenario)
    new_ph: list[Any] = []
    new_ev: list[Any] = []
    for i in range(n):
        off = i * length
        new_ph += [replace(ph, start=ph.start + off, name=f"flight{i + 1}:{ph.name}") for ph in phases]
        new_ev += [replace(e, at=e.at + off) for e in events]
    total = n * length
    new_ph += [replace(ph, start=ph.start + total) for ph in sc.phases]
    new_ev += [replace(e, at=e.at + total) for e in sc.events]
    return replace(sc, phases=tuple(new_ph), events=tuple(new_ev)), total


@dataclass
class LifeResult:
    visits: list[VisitRun]
    wall_s: float
    workers: int
    interrupted: bool = False  # stopped on request (SIGTERM/SIGINT): ``visits`` are those finished by then
    planned: int = 0  # visits the life has

    @property
    def first_fault_visit(self) -> int | None:
        return next((v.visit for v in self.visits if v.verdict == "FAULT"), None)

    def first_fault_hours(self) -> float | None:
        return next((v.operating_hours for v in self.visits if v.verdict == "FAULT"), None)


def plan_life(scenario: Scenario) -> list[tuple[int, float, dict[str, float]]]:
    """(visit number from 1, operating hours, truth deviations) of every visit."""
    life = scenario.life
    if life is None:
        raise ValueError(f"{scenario.source}: no [life] section")
    base = dict(scenario.rig.deviations)
    return [(i + 1, h, deviations_at(life.laws, h, base)) for i, h in enumerate(life.visit_hours())]


def _absolute(path: Any) -> Any:
    """An existing file's absolute path (a parameter set's or board file's name, or None, as it is)."""
    return str(Path(path).resolve()) if path and Path(path).is_file() else path


def run_life(scenario: Scenario, *, seed: int, params: str, workers: int | None = None,
             board_config: str | None = None, on_visit: Callable[[VisitRun], None] | None = None,
             should_stop: Callable[[], bool] = lambda: False, scheduler: str | None = None) -> LifeResult:
    """Every visit of the scenario's life on Dask (default a local cluster of min(CPU count, visits) worker
    processes, or the cluster at ``scheduler``: :class:`studies.board_run.life_pool.LifePool`; ``workers=1``
    without a ``scheduler``, or ``scheduler="synchronous"``: in this process). ``on_visit`` sees the visits
    in visit order. When ``should_stop()`` turns true, no new visit starts, the workers are stopped and the result
    holds the visits finished by then (``interrupted``)."""
    from studies.board_run.life_pool import LifePool

    plan = plan_life(scenario)
    n_workers = workers if workers is not None else min(len(plan), os.cpu_count() or 1)
    t0 = time.perf_counter()
    source = scenario.source
    if scheduler not in (None, "", "local", "synchronous"):  # a cluster's worker reads the files by path from its
        source, params, board_config = (_absolute(x) for x in (source, params, board_config))  # own working folder
    args = [(source, v, h, d, visit_seed(seed, v), params, board_config) for v, h, d in plan]
    done: dict[int, VisitRun] = {}
    shown = [0]

    def finished(i: int, r: VisitRun) -> None:
        done[i] = r
        while shown[0] in done:  # in visit order: deterministic output whatever finishes first
            if on_visit:
                on_visit(done[shown[0]])
            shown[0] += 1

    stopped = False
    if scheduler == "synchronous" or (n_workers <= 1 and scheduler in (None, "", "local")):
        for i, a in enumerate(args):
            if should_stop():
                stopped = True
                break
            finished(i, run_visit(*a))
    else:
        with LifePool(run_visit, min(n_workers, len(args)), scheduler) as pool:
            stopped = pool.run(args, finished, should_stop)
    for i in sorted(done):  # finished after a gap (a stop): shown too
        if i >= shown[0] and on_visit:
            on_visit(done[i])
    return LifeResult([done[i] for i in sorted(done)], time.perf_counter() - t0, n_workers, stopped, len(plan))


def write_life_log(result: LifeResult, scenario: Scenario, out: Path, *, seed: int, params: str,
                   link_url: str = "sim", board_config: dict | None = None, status: str = "finished",
                   final_dir: Path | None = None) -> dict[str, Any]:
    """usage.db (one run, its ``status``), the visit records and their links, life.json. Returns the life summary
    (life.json's document, the JSON at the edge the life report is drawn from).
    ``final_dir``: where the files will live once moved there (``out`` is then a staging folder)."""
    from firmware_sim.usage_log import UsageLog
    from studies.health.visit_records import VisitRecordWriter, run_identity

    db_path = out / "usage.db"
    for suffix in ("", "-wal", "-shm"):
        Path(str(db_path) + suffix).unlink(missing_ok=True)
    life = scenario.life
    assert life is not None
    rate = 100.0
    identity = run_identity(board_config or {})
    log = UsageLog(db_path)
    ok = False
    try:
        run_id = log.start_run(scenario=scenario.name, seed=seed, link_url=link_url, params=params,
                               board_config=board_config or {},
                               rig={"life": True, "visits": life.visits, "visit_interval_h": life.visit_interval,
                                    **identity})
        writer = VisitRecordWriter(out, db_path, params=params, z3_noise_m=scenario.rig.z3_noise,
                                   scenario=scenario.name, run_id=run_id, identity=identity)
        try:
            for v in result.visits:
                offset = v.operating_hours * SECONDS_PER_HOUR
                writer.set_visit(v.visit, v.operating_hours, offset)
                off_ticks = round(offset * rate)
                for ev in v.events:
                    shifted = BoardEvent(ev.kind, ev.tick + off_ticks, ev.time + offset, ev.data)
                    log.write(shifted)
                    writer(ev)
                writer.db.execute(
                    "INSERT INTO life_visits(run_id, visit, operating_hours, board_time_s, flights_before, verdict, "
                    "truth_json, seed) VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
                    (run_id, v.visit, v.operating_hours, offset, life.flights_between_visits * (v.visit - 1),
                     v.verdict, json.dumps(v.deviations), v.seed))
        finally:
            writer.close()
        ok = True
    finally:
        log.close(status if ok else "failed")
    first = result.first_fault_visit
    summary = {
        "scenario": scenario.name, "scenario_file": scenario.source, "seed": seed, "params": params,
        "run_id": run_id, "database": str((final_dir or out) / "usage.db"), "life": True, "workers": result.workers,
        "status": status, "visits_planned": result.planned or len(result.visits), **identity,
        "ticks": round(len(result.visits) * scenario.duration * rate),  # board ticks over all visits
        "wall_s": result.wall_s, "visits": [
            {"visit": v.visit, "operating_hours": v.operating_hours, "verdict": v.verdict, "seed": v.seed,
             "truth_deviations": v.deviations, "wall_s": v.wall_s,
             "mbits": [m.to_json() for m in v.mbits],
             "ticked_flights": v.flights.to_json() if v.flights is not None else None,
             "records": [f"records/visit-{v.visit:03d}_mbit-{m.mbit}.csv" for m in v.mbits]}
            for v in result.visits],
        "first_fault_visit": first,
        "first_fault_operating_hours": result.first_fault_hours(),
        "flights_between_visits": life.flights_between_visits,
        "tick_flights": life.tick_flights, "flight_scenario": life.flight_scenario if life.tick_flights else None,
        "visit_interval_h": life.visit_interval,
    }
    (out / "life.json").write_text(json.dumps(summary, indent=2, default=float))
    return summary


def visit_line(v: VisitRun) -> str:
    """One timeline line per visit."""
    mb = ", ".join(f"{m.label} {m.verdict} (max eps {m.max_eps:.3f}, counter {m.max_count})" for m in v.mbits)
    devs = ", ".join(f"{k} {100 * d:+.1f} %" for k, d in sorted(v.deviations.items()))
    fl = ""
    if v.flights is not None:
        f = v.flights
        fl = (f"  after {f.ticked} ticked flight(s) ({f.board_time_s:g} s of board time: "
              f"{f.incidents} incident(s), {f.usage_summaries} usage summary record(s))")
    return (f"visit {v.visit:3d} at {v.operating_hours:8.1f} h  [{devs}]  {mb}  -> {v.verdict}{fl}  "
            f"({v.wall_s:.1f} s)")
