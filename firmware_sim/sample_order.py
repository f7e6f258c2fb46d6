"""Does the rig's sample stream run forwards? Its sequence counter (``rig_seq``) and clock (``t``) as the board sees
them, tick by tick (issue 33). Pure: no I/O, no clock of its own — the board passes its own time in.

One step back is normal now and then: a rig that restarts (its counter and clock start again), a late reply taken for
the next one. A rig whose counter or clock keeps stepping back is broken (a sample path replaying old data, a
clock running backwards): ``MAX_STEPS_BACK`` steps back within ``WINDOW_S`` of board time are a fault —
:func:`seq_backwards_reason` a sensor fault (the samples cannot be trusted, as with a frozen counter), and
:func:`clock_backwards_reason` a clock incident. With the board's 100 Hz tick a rig running backwards is named at its
third sample.
"""

from __future__ import annotations

from dataclasses import dataclass

WINDOW_S = 1.0  #: board time (s) over which steps back are counted
MAX_STEPS_BACK = 3  #: this many steps back within WINDOW_S are a fault (one is a restart or a late reply)
_WRAP_HIGH, _WRAP_LOW = 0xFFFF0000, 0x10000  # a uint32 counter wrapping from near 2^32 to near 0 runs forwards


@dataclass(frozen=True, slots=True)
class StepsBack:
    """Board times (s) of the recent steps back of the rig's counter (``seq``) and clock (``t``), oldest first."""

    seq: tuple[float, ...] = ()
    t: tuple[float, ...] = ()

    @property
    def any(self) -> bool:
        return bool(self.seq or self.t)


def seq_stepped_back(prev: int, seq: int) -> bool:
    """Whether the uint32 counter went from ``prev`` to ``seq`` backwards (a wrap past 2^32 - 1 is forwards;
    ``prev`` < 0: no sample before)."""
    return 0 <= seq < prev and not (prev >= _WRAP_HIGH and seq < _WRAP_LOW)


def _keep(times: tuple[float, ...], now: float, window_s: float, add: bool) -> tuple[float, ...]:
    kept = tuple(x for x in times if now - x < window_s)
    return (*kept, now) if add else kept


def steps_back(state: StepsBack, prev_seq: int, seq: int, prev_t: float, t: float, now: float,
               window_s: float = WINDOW_S) -> StepsBack:
    """``state`` after the sample (``seq``, rig time ``t`` s) that followed (``prev_seq``, ``prev_t``), at board time
    ``now`` (s): steps back added, those older than ``window_s`` dropped. A NaN time never counts as a step."""
    return StepsBack(_keep(state.seq, now, window_s, seq_stepped_back(prev_seq, seq)),
                     _keep(state.t, now, window_s, t < prev_t))


def seq_backwards_reason(state: StepsBack, prev_seq: int, seq: int, window_s: float = WINDOW_S) -> str:
    """Why the samples cannot be trusted ('' if they can): the counter keeps stepping back."""
    if len(state.seq) < MAX_STEPS_BACK:
        return ""
    return (f"rig_seq runs backwards ({len(state.seq)} steps back within {window_s:g} s, the last {prev_seq} -> "
            f"{seq}: old samples replayed?)")


def clock_backwards_reason(state: StepsBack, prev_t: float, t: float, window_s: float = WINDOW_S) -> str:
    """Why the rig's clock cannot be trusted ('' if it can): it keeps stepping back."""
    if len(state.t) < MAX_STEPS_BACK:
        return ""
    return (f"the rig's clock runs backwards ({len(state.t)} steps back within {window_s:g} s of board time, the "
            f"last {prev_t:.3f} -> {t:.3f} s)")
