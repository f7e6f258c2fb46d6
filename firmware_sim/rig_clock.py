"""The board's check of the rig's clock (sample times) against its own (tick count), every :data:`CLOCK_WINDOW` s of
board time: a virtual-time board against a real-time rig (or the reverse) sees the two drift apart. Pure: no I/O, no
clock of its own."""

from __future__ import annotations

import numpy as np

CLOCK_WINDOW = 2.0  # s of board time between two checks of the rig's clock against the board's


def clocks_agree(board_dt: float, rig_dt: float) -> bool:
    """Whether the rig's clock advanced ``rig_dt`` (s) within a factor 2 of the board's ``board_dt`` (s)."""
    return 0.5 * board_dt <= rig_dt <= 2.0 * board_dt


def mismatch_reason(board_dt: float, rig_dt: float) -> str:
    """What a disagreement of the two clocks means, and what to do about it."""
    return (f"the rig's clock advanced {rig_dt:.2f} s while the board ticked {board_dt:.2f} s: "
            + ("the board runs in virtual time against a real-time rig (run the board with --realtime, or the rig "
               "with --clock lockstep)" if rig_dt < board_dt else
               "the rig runs faster than the board (is the board paced slower than its tick?)"))


def quiet_clock_checks(k: int, m: int, ref: tuple[int, float], t: np.ndarray, period: float, reported: bool
                       ) -> tuple[int, list[tuple[int, float]]]:
    """The checks of the rig's clock over quiet ticks ``k .. k + m - 1`` (rig times ``t``, s), from the reference
    ``ref`` = (tick, rig time s): each check falls on the first tick a window after the last reference and is silent
    (a new reference) unless it finds a mismatch not yet ``reported``, where the quiet run must stop. Returns the
    ticks of the run that stay quiet and the (tick, rig time) of the silent checks in them."""
    ref_k, ref_t = ref
    checks: list[tuple[int, float]] = []
    while m > 0:
        d = k - ref_k
        c = max(0, int(CLOCK_WINDOW / period) - d - 2)
        while c < m and (d + c) * period < CLOCK_WINDOW:
            c += 1
        if c >= m:
            break
        t_c = float(t[c])
        if not clocks_agree((d + c) * period, t_c - ref_t) and not reported:
            return c, checks
        ref_k, ref_t = k + c, t_c
        checks.append((ref_k, ref_t))
    return m, checks
