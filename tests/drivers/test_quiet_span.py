"""Quiet spans (drivers.quiet_span): uneventful ticks exchanged and processed in one call must be bit-identical to
tick by tick — events, trace, ledger, board and rig state — over every shipped scenario and over perturbed boards
and seeds; the seams (which runs and links get spans, a peek advances nothing). The closed forms against the
per-tick functions: tests/firmware_sim/test_quiet_closed_forms.py."""

from __future__ import annotations

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from board_config.board import load_board_config
from board_config.scenario import load_scenario
from drivers.link import ActuatorCommand
from drivers.quiet_span import QuietSpanSource
from drivers.sim_link import InProcessLink
from firmware_sim.board import Board
from firmware_sim.runner import BoardRunner
from firmware_sim.scheduler import Scheduler, VirtualClock, WallClock
from hil_stub.rig import SimulatedRig

SCENARIOS = ("default", "maintenance", "degraded", "patch_leakage", "faults", "aging")


def _run(name: str, spans: bool, *, duration: float | None = None, seed: int | None = None,
         overrides: dict | None = None, trace_every: int = 1):
    sc = load_scenario(name)
    over = {section: dict(table) for section, table in sc.board_overrides.items()}
    for key, value in (overrides or {}).items():
        section, field = key.split(".")
        over.setdefault(section, {})[field] = value
    cfg = load_board_config(overrides=over, overrides_source=sc.source)
    rig = SimulatedRig(sc, tick=cfg.tick_period, seed=seed)
    link = InProcessLink(rig, tick=cfg.tick_period)
    board = Board(cfg, nominal=sc.rig.params)
    runner = BoardRunner(board, link, rearm_times=[e.at for e in sc.events_of("rearm")], quiet_spans=spans,
                         trace_every=trace_every)
    link.open()
    res = runner.run(duration if duration is not None else sc.duration)
    return res, board, rig, runner, link


def _assert_identical(a, b) -> None:
    (ra, ba, ga, na, la), (rb, bb, gb, nb, lb) = a, b
    def events(res):
        return [(e.kind, e.tick, e.time, e.data) for e in res.events]

    assert events(ra) == events(rb)
    assert ra.ticks == rb.ticks
    assert ra.trace.data.shape == rb.trace.data.shape
    assert ra.trace.data.tobytes() == rb.trace.data.tobytes()  # bit for bit, NaN included
    assert (ba.state, ba.power, ba._prev_seq, ba.last_sample, ba.incidents, ba.ticks, ba.visit_verdict,
            ba._clock_ref, ba.demand) == (bb.state, bb.power, bb._prev_seq, bb.last_sample, bb.incidents, bb.ticks,
                                          bb.visit_verdict, bb._clock_ref, bb.demand)
    assert (ba.ledger.ticks, ba.ledger.energy_used, ba.ledger.v_first, ba.ledger.v_last, ba.ledger.v_min) == (
        bb.ledger.ticks, bb.ledger.energy_used, bb.ledger.v_first, bb.ledger.v_last, bb.ledger.v_min)
    ta, tb = ga.truth(), gb.truth()
    ta.pop("plant_seconds")
    tb.pop("plant_seconds")
    assert ta == tb
    assert (ga.seq, ga.ticks, ga.sample(), ga.cell.qd) == (gb.seq, gb.ticks, gb.sample(), gb.cell.qd)
    assert vars(ga.amplifier) == vars(gb.amplifier)
    assert na.command == nb.command
    assert la.exchanges == lb.exchanges


@pytest.mark.parametrize("name", SCENARIOS)
def test_every_shipped_scenario_is_bit_identical_with_and_without_spans(name: str) -> None:
    _assert_identical(_run(name, False), _run(name, True))


def test_spans_do_most_of_the_default_flight() -> None:
    """The point of spans: in the default scenario's flight nearly every tick is taken in a span (a test that would
    pass with spans never used would check nothing)."""
    sc = load_scenario("default")
    cfg = load_board_config(overrides=sc.board_overrides, overrides_source=sc.source)
    rig = SimulatedRig(sc, tick=cfg.tick_period)
    link = InProcessLink(rig, tick=cfg.tick_period)
    board = Board(cfg, nominal=sc.rig.params)
    taken: list[int] = []
    take = board.take_quiet

    def counting(k, span):
        m, cmd = take(k, span)
        taken.append(m)
        return m, cmd

    board.take_quiet = counting  # type: ignore[method-assign]
    link.open()
    BoardRunner(board, link, trace_every=None).run(300.0)
    assert sum(taken) >= 0.95 * 30_000, f"only {sum(taken)} of 30000 ticks in spans"
    assert len(taken) < 400


@settings(max_examples=10, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(name=st.sampled_from(["default", "faults", "degraded"]), seed=st.integers(0, 2**16),
       wake_v=st.sampled_from([0.05, 0.2, 1.0, 5.0]),
       wake_acc=st.sampled_from([1.0, 2.0, 4.0, 30.0]), telemetry=st.sampled_from([0.37, 1.0, 10.0]),
       quiet=st.sampled_from([0.5, 3.0, 10.0]), every=st.sampled_from([1, 3, 7]))
def test_perturbed_boards_and_seeds_stay_bit_identical(name, seed, wake_v, wake_acc, telemetry, quiet,
                                                       every) -> None:
    """Wake thresholds that make the board wake often (or never), odd telemetry and quiet periods, trace decimation
    and other seeds, in flight, with link outages, sensor faults, re-arms and extra loads (``faults``) and a
    degraded laminate: spans on and off agree on everything (the first 400 s)."""
    over = {"wake.patch_voltage": {"value": wake_v, "unit": "V"},
            "wake.base_acceleration": {"value": wake_acc, "unit": "m/s^2"},
            "log.telemetry_period": {"value": telemetry, "unit": "s"},
            "sensing.quiet_period": {"value": quiet, "unit": "s"}}
    a = _run(name, False, duration=400.0, seed=seed, overrides=over, trace_every=every)
    b = _run(name, True, duration=400.0, seed=seed, overrides=over, trace_every=every)
    _assert_identical(a, b)


# --- the seams ----------------------------------------------------------------------------------------------------
def test_run_blocks_visits_every_tick_once_in_order_and_reports_progress() -> None:
    sched = Scheduler(100.0)
    seen: list[int] = []
    prog: list[int] = []
    sizes = iter([1, 300, 5, 1, 250, 1000])

    def block(k: int, left: int) -> tuple[int, bool]:
        d = min(next(sizes, 1), left)
        seen.extend(range(k, k + d))
        return d, False

    stats = sched.run_blocks(900, block, first_tick=7, progress=prog.append)
    assert seen == list(range(7, 907)) and stats.ticks == 900
    assert prog[0] == 0 and len(prog) >= 3
    with pytest.raises(ValueError, match="did 0 ticks"):
        Scheduler(100.0).run_blocks(5, lambda k, left: (0, False))
    with pytest.raises(ValueError, match="virtual clock"):
        Scheduler(100.0, WallClock()).run_blocks(5, lambda k, left: (1, False))
    stopped = Scheduler(100.0).run_blocks(900, lambda k, left: (min(40, left), k >= 100))
    assert stopped.ticks == 160  # the block that asked to stop (ticks 120..159) is done, nothing after it
    assert isinstance(Scheduler(100.0).clock, VirtualClock)


def test_a_stop_request_ends_a_run_with_spans_after_the_current_span() -> None:
    """``shm run`` wraps the scheduler to stop on SIGINT/SIGTERM: with spans the run still ends right after the
    span in which the stop was requested (in the flight, spans are at most 200 ticks)."""
    from shm_cli.stop_signal import StoppableScheduler

    class Stop:
        requested = False

    stop = Stop()
    sc = load_scenario("default")
    cfg = load_board_config(overrides=sc.board_overrides, overrides_source=sc.source)
    rig = SimulatedRig(sc, tick=cfg.tick_period)
    link = InProcessLink(rig, tick=cfg.tick_period)
    runner = BoardRunner(Board(cfg, nominal=sc.rig.params), link,
                         scheduler=StoppableScheduler(Scheduler(cfg.tick_rate), stop))  # type: ignore[arg-type]
    assert runner._quiet_span_source() is link

    def progress(i: int) -> None:
        if i >= 3000:
            stop.requested = True

    link.open()
    res = runner.run(300.0, progress=progress)
    assert 3000 <= res.ticks <= 4000, res.ticks  # of 30 000: stopped within a few spans

    class Forwarding:  # forwards run_blocks through __getattr__: it would bypass its own run's conditions
        def __init__(self, inner: Scheduler) -> None:
            self._inner = inner

        def __getattr__(self, name: str):
            return getattr(self._inner, name)

    fwd = BoardRunner(Board(cfg, nominal=sc.rig.params), link,
                      scheduler=Forwarding(Scheduler(cfg.tick_rate)))  # type: ignore[arg-type]
    assert fwd._quiet_span_source() is None


def test_spans_only_in_virtual_time_against_a_rig_that_offers_them() -> None:
    sc = load_scenario("default")
    cfg = load_board_config(overrides=sc.board_overrides, overrides_source=sc.source)
    rig = SimulatedRig(sc, tick=cfg.tick_period)
    link = InProcessLink(rig, tick=cfg.tick_period)
    board = Board(cfg, nominal=sc.rig.params)
    assert isinstance(link, QuietSpanSource)
    assert BoardRunner(board, link)._quiet_span_source() is link
    assert BoardRunner(board, link, quiet_spans=False)._quiet_span_source() is None
    assert BoardRunner(board, link, scheduler=Scheduler(cfg.tick_rate, WallClock()))._quiet_span_source() is None

    class TickByTick:  # a link without peek_quiet (serial, Modbus...)
        url = "x"

        def open(self) -> None: ...

        def close(self) -> None: ...

        def exchange(self, command):
            return link.exchange(command)

    assert BoardRunner(board, TickByTick())._quiet_span_source() is None

    class Injector(InProcessLink):  # changes exchange: must see every tick, so no spans
        def exchange(self, command):
            return super().exchange(command)

    inj = Injector(rig, tick=cfg.tick_period)
    inj.open()
    assert inj.peek_quiet(ActuatorCommand(0, 0.0, 0.0, 0.0), 10) is None


def test_peek_advances_nothing_and_refuses_what_is_not_quiet() -> None:
    sc = load_scenario("default")
    rig = SimulatedRig(sc)
    link = InProcessLink(rig)
    link.open()
    for k in range(5):
        link.exchange(ActuatorCommand(k, 0.0, 0.0, 1e-6))
    before = (rig.t, rig.seq, rig.sample(), rig.cell.qd, rig.sensors._i, vars(rig.amplifier).copy())
    span = link.peek_quiet(ActuatorCommand(9, 0.0, 0.0, 1e-6), 50)
    assert span is not None and 1 <= span.n <= 50
    assert (rig.t, rig.seq, rig.sample(), rig.cell.qd, rig.sensors._i, vars(rig.amplifier)) == before
    assert link.peek_quiet(ActuatorCommand(9, 10.0, 0.0, 1e-6), 50) is None  # a demand
    assert link.peek_quiet(ActuatorCommand(9, 0.0, 0.0, 2e-3), 50) is None  # another load than in force
    assert rig.peek_quiet(ActuatorCommand(9, 0.0, 0.0, 1e-6), 50, 0.02) is None  # not the rig's tick
    link.fail_next(1)
    assert link.peek_quiet(ActuatorCommand(9, 0.0, 0.0, 1e-6), 50) is None  # an injected failure comes first
    with pytest.raises(ValueError):
        rig.commit_quiet(span, span.n + 1)
    # a span's samples are exactly what single exchanges return
    other = SimulatedRig(sc)
    olink = InProcessLink(other)
    olink.open()
    for k in range(5):
        olink.exchange(ActuatorCommand(k, 0.0, 0.0, 1e-6))
    olink._fail_next = 0
    link._fail_next = 0
    m = min(span.n, 17)
    singles = [olink.exchange(ActuatorCommand(10 + i, 0.0, 0.0, 1e-6)) for i in range(m)]
    assert [span.sample(i) for i in range(m)] == singles
    link.commit_quiet(span, m)
    assert rig.sample() == other.sample() and rig.t == other.t and rig.cell.qd == other.cell.qd
