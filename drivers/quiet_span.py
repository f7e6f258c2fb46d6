"""Quiet spans: a stretch of uneventful ticks exchanged in one call, for in-process rigs in virtual time.

While the board sleeps, senses, or waits in maintenance after its MBITs, its command does not change (zero demand,
the regime's current; only the sequence number grows) and the rig's plant is already integrated ahead in lookahead
blocks. A rig that can say, without advancing anything, which samples the next ``n`` exchanges of such a command
would return (:meth:`QuietSpanSource.peek_quiet`) lets the board process those ticks as one array operation; the rig
is then moved on by exactly the ticks the board took (:meth:`QuietSpanSource.commit_quiet`, at most ``n``: the board
stops at the first tick that is not quiet, which is then exchanged and processed one by one as usual). Both sides
guarantee the result is *bit-identical* to ``n`` single exchanges and ticks; ``tests/drivers/test_quiet_span.py``
checks it
over every shipped scenario.

Only a link that owns its rig in the same process can offer this (:class:`drivers.sim_link.InProcessLink`); a
serial or Modbus link exchanges tick by tick, and a paced (real-time) run never asks.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np

from drivers.link import ActuatorCommand, RigSample


@dataclass(frozen=True, eq=False)
class QuietSpan:
    """The samples of the next ``n`` exchanges of an unchanged zero-demand command (SI units, arrays of length n).

    Every sample of a span has the same ``hv_present`` and ``flags`` 0; the ``i``-th has sequence number
    ``(seq0 + i) mod 2**32``. ``rig_state`` is the rig's own bookkeeping for :meth:`QuietSpanSource.commit_quiet`.
    """

    seq0: int
    t: np.ndarray  # s, rig time of each sample
    z3: np.ndarray  # m
    v_patch: np.ndarray  # V
    z0dd: np.ndarray  # m/s^2
    v_battery: np.ndarray  # V
    hv_present: bool = False
    rig_state: Any = None

    @property
    def n(self) -> int:
        return int(self.t.shape[0])

    def sample(self, i: int) -> RigSample:
        """The ``i``-th sample as the link would have returned it."""
        return RigSample((self.seq0 + i) & 0xFFFFFFFF, float(self.t[i]), float(self.z3[i]), float(self.v_patch[i]),
                         float(self.z0dd[i]), float(self.v_battery[i]), self.hv_present, 0)


@runtime_checkable
class QuietSpanSource(Protocol):
    """What offers quiet spans: an in-process rig, or a link to one."""

    def peek_quiet(self, command: ActuatorCommand, max_ticks: int) -> QuietSpan | None:
        """The samples of the next exchanges (1 to ``max_ticks``) if each carried ``command``'s demand and current,
        or None when that is not a quiet stretch (a demand, a pending change, a scheduled incident...)."""
        ...

    def commit_quiet(self, span: QuietSpan, m: int) -> None:
        """Advance exactly as ``m`` exchanges (``1 <= m <= span.n``) of the span's command would have."""
        ...
