"""The 100 Hz scheduler with an injected clock: virtual time, deadline misses and jitter statistics."""

from __future__ import annotations

import pytest

from firmware_sim.scheduler import Scheduler, VirtualClock, WallClock


class ScriptedClock:
    """A wall-clock stand-in: sleeping jumps to the deadline plus a scripted lateness; work takes scripted time."""

    def __init__(self, lateness, work):
        self.t = 0.0
        self.lateness = list(lateness)
        self.work = list(work)
        self.k = 0

    def now(self) -> float:
        return self.t

    def sleep_until(self, t: float) -> None:
        late = self.lateness[self.k] if self.k < len(self.lateness) else 0.0
        self.t = max(self.t, t + late)

    def spend(self) -> None:
        self.t += self.work[self.k] if self.k < len(self.work) else 0.0
        self.k += 1


def test_virtual_time_runs_every_tick_in_order():
    seen = []
    sched = Scheduler(100.0, VirtualClock())
    stats = sched.run(250, lambda k, over: seen.append((k, over)), first_tick=10)
    assert [k for k, _ in seen] == list(range(10, 260))
    assert not any(o for _, o in seen)
    assert stats.ticks == 250 and not stats.paced and stats.deadline_misses == 0
    assert stats.elapsed == pytest.approx(2.49)  # the clock stood at each deadline


def test_stop_request_ends_the_run():
    stats = Scheduler(100.0).run(100, lambda k, o: k == 9)
    assert stats.ticks == 10


def test_deadline_misses_jitter_and_overrun_flag():
    period = 0.01
    # tick 3 takes 2.5 periods: it misses, and tick 4, starting 15 ms late, ends after its own period too;
    # ticks 6, 7 and 8 each take 1.2 periods (three misses in a row); tick 1 starts 1 ms late
    work = [0.001] * 20
    work[3] = 0.025
    work[6] = work[7] = work[8] = 0.012
    lateness = [0.0] * 20
    lateness[1] = 0.001
    clock = ScriptedClock(lateness, work)
    flags = []

    def step(k, overran):
        flags.append(overran)
        clock.spend()

    sched = Scheduler(100.0, clock)
    stats = sched.run(20, step)
    assert stats.paced
    assert stats.deadline_misses == 5  # ticks 3, 4, 6, 7, 8
    assert stats.max_consecutive_misses == 3
    # the step learns about an overrun at the next tick
    assert [i for i, f in enumerate(flags) if f] == [4, 5, 7, 8, 9]
    # jitter: tick 1 started 1 ms late; tick 4 started 15 ms late (tick 3 ran until 55 ms)
    assert stats.jitter_max == pytest.approx(0.015, abs=1e-12)
    assert stats.jitter_p50 == pytest.approx(0.0, abs=1e-12)
    assert stats.busy_max == pytest.approx(0.025)
    d = stats.as_dict()
    assert d["deadline_misses"] == 5 and d["rate_Hz"] == 100.0 and d["jitter_max_s"] == stats.jitter_max
    assert period == sched.period


def test_wall_clock_paces_real_time():
    sched = Scheduler(200.0, WallClock())
    stats = sched.run(40, lambda k, o: None)
    assert stats.paced
    assert stats.elapsed == pytest.approx(40 / 200.0, abs=0.05)  # 0.2 s of real time, not instantly
    assert stats.jitter_p50 >= 0.0


def test_wall_clock_does_not_spin_under_a_real_time_policy(monkeypatch):
    """A SCHED_FIFO board that spins starves the normal-priority threads of its core (the pty's kernel worker, the
    rig's threads): under a real-time policy the default spin is 0 and the sleep alone keeps the pace."""
    import os

    import firmware_sim.scheduler as sch

    monkeypatch.setattr(os, "sched_getscheduler", lambda pid: os.SCHED_FIFO)
    assert sch.running_real_time() and WallClock().spin_s == 0.0
    assert WallClock(spin_s=0.002).spin_s == 0.002  # an explicit spin is kept
    stats = Scheduler(200.0, WallClock()).run(20, lambda k, o: None)
    assert stats.elapsed == pytest.approx(20 / 200.0, abs=0.05)
    monkeypatch.setattr(os, "sched_getscheduler", lambda pid: os.SCHED_OTHER)
    assert not sch.running_real_time() and WallClock().spin_s == sch.DEFAULT_SPIN_S

    def refuse(pid):
        raise PermissionError("not allowed")

    monkeypatch.setattr(os, "sched_getscheduler", refuse)
    assert not sch.running_real_time()


def test_rate_must_be_positive():
    with pytest.raises(ValueError, match="positive"):
        Scheduler(0.0)
