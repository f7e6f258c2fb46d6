"""A rig whose clock and sequence counter run backwards is named within the first second (issue 33): a sensor fault
("rig_seq runs backwards") and a clock incident ("the rig's clock runs backwards"). The check is pure
(``firmware_sim.sample_order``, board time passed in) and property-tested: a forward stream (counter wraps included)
or a single restart never raises it, three steps back within a second always do."""

from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st
from links_support import FakeRig

from drivers.link import ActuatorCommand, RigSample
from drivers.sim_link import InProcessLink
from firmware_sim.board import Board
from firmware_sim.sample_order import (
    MAX_STEPS_BACK,
    WINDOW_S,
    StepsBack,
    clock_backwards_reason,
    seq_backwards_reason,
    steps_back,
)

PERIOD = 0.01


def _run(seqs: list[int], times: list[float]) -> tuple[list[str], list[str]]:
    """Feed the pure check one sample per 10 ms tick; the sensor and clock reasons raised."""
    state, sensor, clock = StepsBack(), [], []
    prev_seq, prev_t = -1, float("-inf")
    for k, (seq, t) in enumerate(zip(seqs, times, strict=True)):
        state = steps_back(state, prev_seq, seq, prev_t, t, k * PERIOD)
        sensor.append(seq_backwards_reason(state, prev_seq, seq))
        clock.append(clock_backwards_reason(state, prev_t, t))
        prev_seq, prev_t = seq, t
    return [r for r in sensor if r], [r for r in clock if r]


@given(start=st.integers(0, 2**32 - 1), steps=st.lists(st.integers(0, 3), min_size=1, max_size=300),
       t0=st.floats(0, 1e6))
def test_a_forward_stream_never_raises(start: int, steps: list[int], t0: float) -> None:
    seqs, s = [], start
    for d in steps:  # repeats (d = 0) and jumps forwards, wrapping past 2^32 - 1
        s = (s + d) & 0xFFFFFFFF
        seqs.append(s)
    times = [t0 + 0.01 * i for i in range(len(seqs))]
    assert _run(seqs, times) == ([], [])


@given(before=st.integers(1, 200), after=st.integers(1, 200), back_to=st.integers(0, 50))
def test_one_restart_never_raises(before: int, after: int, back_to: int) -> None:
    seqs = list(range(1000, 1000 + before)) + list(range(back_to, back_to + after))
    times = [10.0 + 0.01 * i for i in range(before)] + [0.01 * i for i in range(after)]
    assert _run(seqs, times) == ([], [])


@given(n_back=st.integers(MAX_STEPS_BACK, 50), gap=st.integers(1, 30), start=st.integers(10_000, 2**31))
def test_steps_back_within_the_window_always_raise(n_back: int, gap: int, start: int) -> None:
    # a step back every `gap` ticks (the counter and clock otherwise forwards), n_back of them inside the window
    gap = min(gap, int(WINDOW_S / PERIOD / n_back))
    seqs, times, s, t = [], [], start, 100.0
    for i in range(n_back * max(gap, 1) + 1):
        back = i > 0 and i % max(gap, 1) == 0
        s, t = (s - 5, t - 0.05) if back else (s + 1, t + 0.01)
        seqs.append(s)
        times.append(t)
    sensor, clock = _run(seqs, times)
    assert sensor and "rig_seq runs backwards" in sensor[0]
    assert clock and "clock runs backwards" in clock[0]


@given(spacing_s=st.floats(WINDOW_S / (MAX_STEPS_BACK - 1) * 1.01, 5.0), n=st.integers(1, 6))
def test_steps_back_further_apart_than_the_window_allows_never_raise(spacing_s: float, n: int) -> None:
    every = int(spacing_s / PERIOD) + 1
    seqs, times, s, t = [], [], 10_000, 100.0
    for i in range(n * every + 1):
        back = i > 0 and i % every == 0
        s, t = (s - 5, t - 0.05) if back else (s + 1, t + 0.01)
        seqs.append(s)
        times.append(t)
    assert _run(seqs, times) == ([], [])


class BackwardsRig(FakeRig):
    """A rig whose sample counter and clock run backwards (a replaying sensor path, a broken clock)."""

    def sample(self) -> RigSample:
        s = super().sample()
        return RigSample(100_000 - s.seq, 1000.0 - s.t, s.z3, s.v_patch, s.z0dd, s.v_battery, s.hv_present, s.flags)


def _incidents(board: Board, link: InProcessLink, ticks: int) -> list[tuple[int, str, str]]:
    found = []
    command = ActuatorCommand(0)
    for k in range(ticks):
        result = board.tick(link.exchange(command), k)
        command = result.command
        found += [(e.tick, e.data["incident"], e.data["detail"]) for e in result.events if e.kind == "incident"]
    return found


def test_a_rig_running_backwards_is_a_sensor_fault_and_a_clock_incident_within_a_second() -> None:
    link = InProcessLink(BackwardsRig())
    link.open()
    found = _incidents(Board(), link, 300)
    sensor = [f for f in found if f[1] == "sensor_fault" and "rig_seq runs backwards" in f[2]]
    clock = [f for f in found if f[1] == "clock_mismatch" and "clock runs backwards" in f[2]]
    assert sensor and sensor[0][0] < 100, found  # within the first second (at its third sample, in fact)
    assert clock and clock[0][0] < 100, found
    assert len(clock) == 1  # said once per run


def test_a_forward_rig_raises_nothing_of_the_kind() -> None:
    link = InProcessLink(FakeRig())
    link.open()
    found = _incidents(Board(), link, 300)
    assert not [f for f in found if "backwards" in f[2]], found
