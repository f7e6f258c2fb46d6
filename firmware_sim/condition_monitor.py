"""Model-based condition monitor of the seed paper (Sec. 4.1, Fig. 10, Eq. 11, Table 3) — pure logic.

No clock and no I/O: every sample comes in with its time as an argument, so the same code runs in the board's
100 Hz loop, in offline Monte-Carlo campaigns and under hypothesis.

Normalised model error (Eq. 11, from Eq. 5 with the error model of Eq. 4)::

    eps = |z3_md - z3_hw| / (|z3_hw| + e0z / kerr_z)

with ``e0z`` and ``kerr_z`` from ``board_config.load_monitor_settings()`` (0.75 mm and 0.075, so the
denominator never falls below 10 mm); the formula lives in ``board_config.error_law`` (the workbench uses the same
one, model first, measurement second).

Fault counter, once per monitor sample (``f_mon``, 100 Hz)::

    if eps > eps_th:   count += counter_up                    (+2)
    else:              count = max(count - counter_down, 0)   (-1, held at 0)
    if count > count_max:  fault latches                      (count_max = 200)

Decisions (documented in docs/monitor.md and tested in tests/firmware_sim/test_monitor_counter.py):

* **Both comparisons are strict** (the paper says the error "exceeds" the threshold and the counter "exceeds"
  count_max): ``eps == eps_th`` is *not* an exceedance and ``count == count_max`` is *not* a fault.
* **Consecutive exceedances to latch a fault** from a counter at ``c`` (``c <= count_max``):
  ``K(c) = (count_max - c) // counter_up + 1``. From zero with Table 3: ``K = 200 // 2 + 1 = 101`` samples, i.e.
  the fault latches on the 101st exceeding sample, **1.00 s after the first** at 100 Hz. Fewer than ``K(0)``
  exceedances in total can never latch a fault (the counter never exceeds ``counter_up`` × exceedances).
* **Latching:** once set, the fault stays set until :meth:`ConditionMonitor.reset` (the counter keeps running
  and is reported, it no longer matters for the verdict).
* **Invalid samples:** a non-finite error (a NaN/Inf model output or measurement: sensor fault) is not
  counted either way — the counter is held and ``n_invalid`` increments. Flagging the sensor is the board's job.
* A stream whose exceedance fraction is above ``counter_down / (counter_up + counter_down)`` (1/3) drifts up.

Two evaluations, identical verdicts (tested sample by sample):

* streaming — :class:`ConditionMonitor` ``update(t, z3_model, z3_meas)``, one sample at a time (the board);
* vectorised — :func:`evaluate` / :func:`evaluate_z3` over whole traces and batches (campaigns, ROC), using the
  closed form of the floored counter (a Lindley recursion):
  ``c_k = S_k - min(-c_0, min_{j<=k} S_j)`` with ``S_k`` the cumulative sum of the steps.
  :meth:`ConditionMonitor.update_many` uses it to process a chunk and continue the stream.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from board_config import MonitorSettings, load_monitor_settings
from board_config.error_law import normalised_error as normalised_error  # Eq. 11 (workbench Eq. 5); re-exported


def consecutive_exceedances_to_fault(count_max: int, counter_up: int, count: int = 0) -> int:
    """Consecutive exceedances that latch a fault starting from counter value ``count`` (strict ``>``)."""
    return max((count_max - count) // counter_up + 1, 1)  # already above count_max: the next exceedance latches


def counter_step(count: int, exceeded: bool, counter_up: int, counter_down: int) -> int:
    """One step of the fault counter: ``+counter_up`` on an exceedance, else ``-counter_down`` held at 0."""
    if exceeded:
        return count + counter_up
    return max(count - counter_down, 0)


@dataclass(frozen=True)
class MonitorState:
    """Everything the monitor remembers between samples."""

    count: int = 0  # fault counter (count)
    fault: bool = False  # latched fault flag (Fault_mon)
    fault_time: float | None = None  # s, time of the sample that latched the fault
    n_samples: int = 0  # samples seen (valid or not)
    n_exceed: int = 0  # samples with eps > eps_th
    n_invalid: int = 0  # samples with a non-finite error (not counted)
    max_count: int = 0  # highest counter value so far
    max_eps: float = 0.0  # highest finite normalised error so far (1)
    t_last: float | None = None  # s, time of the last sample


@dataclass(frozen=True, slots=True)
class MonitorSample:
    """The monitor's answer to one sample."""

    t: float  # s
    eps: float  # normalised error (1)
    exceeded: bool  # eps > eps_th
    valid: bool  # eps finite
    count: int  # counter after this sample
    fault: bool  # latched fault after this sample


def update_state(state: MonitorState, t: float, eps: float, settings: MonitorSettings
                 ) -> tuple[MonitorState, MonitorSample]:
    """Pure transition: the state after one sample of normalised error ``eps`` at time ``t`` (s)."""
    if state.t_last is not None and not t > state.t_last:
        raise ValueError(f"monitor sample times must increase: got t={t!r} s after t={state.t_last!r} s")
    eps = float(eps)
    valid = math.isfinite(eps)
    exceeded = valid and eps > settings.eps_th
    count = counter_step(state.count, exceeded, settings.counter_up, settings.counter_down) if valid else state.count
    latch = not state.fault and count > settings.count_max
    new = MonitorState(
        count=count,
        fault=state.fault or latch,
        fault_time=float(t) if latch else state.fault_time,
        n_samples=state.n_samples + 1,
        n_exceed=state.n_exceed + int(exceeded),
        n_invalid=state.n_invalid + int(not valid),
        max_count=max(state.max_count, count),
        max_eps=max(state.max_eps, eps) if valid else state.max_eps,
        t_last=float(t),
    )
    return new, MonitorSample(float(t), eps, exceeded, valid, count, new.fault)


@dataclass(frozen=True)
class MonitorTrace:
    """Vectorised monitor result over traces of shape ``(..., T)`` (leading axes: batch members)."""

    t: np.ndarray  # (T,) s
    eps: np.ndarray  # (..., T) normalised error (1)
    exceeded: np.ndarray  # (..., T) bool
    valid: np.ndarray  # (..., T) bool
    count: np.ndarray  # (..., T) int64 counter after each sample
    fault: np.ndarray  # (..., T) bool latched fault after each sample
    fault_index: np.ndarray  # (...) int64: sample that latched the fault in this trace, -1 if none
    fault_time: np.ndarray  # (...) s, NaN if not latched in this trace
    max_count: np.ndarray  # (...) int64

    @property
    def detected(self) -> np.ndarray:
        """Fault verdict at the end of the trace, shape (...)."""
        return self.fault[..., -1] if self.fault.shape[-1] else np.zeros(self.fault.shape[:-1], dtype=bool)


def counter_trajectory(exceeded: np.ndarray, valid: np.ndarray | None, counter_up: int, counter_down: int,
                       count0: int = 0) -> np.ndarray:
    """Counter after each sample for exceedance flags ``(..., T)``, starting from ``count0`` (closed form).

    Steps ``s_k`` are ``+up`` (exceeded), ``-down`` (not exceeded) or ``0`` (invalid sample); with
    ``S_k = s_1 + ... + s_k`` the floored counter is ``c_k = S_k - min(-count0, min_{j<=k} S_j)``.
    """
    steps = np.where(exceeded, np.int64(counter_up), np.int64(-counter_down))  # int64, any shape (also T = 0)
    if valid is not None:
        steps = np.where(valid, steps, np.int64(0))
    cum = np.cumsum(steps, axis=-1)
    low = np.minimum.accumulate(cum, axis=-1)
    return cum - np.minimum(low, np.int64(-count0))


def evaluate(eps: np.ndarray, settings: MonitorSettings | None = None, t: np.ndarray | None = None,
             state: MonitorState | None = None) -> MonitorTrace:
    """Offline monitor over normalised-error traces ``eps`` of shape ``(..., T)``.

    ``t`` (s) defaults to ``k / f_mon``. ``state`` continues a stream (1-D ``eps`` only); by default the counter
    starts at 0 with no fault. Verdicts are identical to feeding the samples one by one to
    :class:`ConditionMonitor`.
    """
    settings = settings if settings is not None else load_monitor_settings()
    eps = np.asarray(eps, dtype=float)
    if eps.ndim == 0:
        raise ValueError("eps must have a time axis (shape (..., T))")
    n = eps.shape[-1]
    t = np.arange(n) / settings.f_mon if t is None else np.asarray(t, dtype=float)
    if t.shape != (n,):
        raise ValueError(f"t must have shape ({n},) to match eps {eps.shape}, got {t.shape}")
    if not np.all(np.diff(t) > 0):  # fewer than two samples: no difference, nothing to order
        raise ValueError("monitor sample times must increase strictly")
    count0, fault0 = 0, False
    if state is not None:
        if eps.ndim != 1:
            raise ValueError("a start state can only continue a single trace (1-D eps)")
        if state.t_last is not None and n and not t[0] > state.t_last:
            raise ValueError(f"monitor sample times must increase: got t={t[0]!r} s after t={state.t_last!r} s")
        count0, fault0 = state.count, state.fault
    valid = np.isfinite(eps)
    exceeded = valid & (eps > settings.eps_th)  # NaN compares False (no warning)
    count = counter_trajectory(exceeded, valid, settings.counter_up, settings.counter_down, count0)
    above = count > settings.count_max
    fault = np.logical_or.accumulate(above | fault0, axis=-1)  # latched: from the first sample above on
    latched_here = above.any(axis=-1) & (not fault0)
    # the first sample above count_max is the first of the trailing run of faulted samples; -1: none latched here
    fault_index = np.where(latched_here, n - fault.sum(axis=-1), -1)
    fault_time = np.append(t, np.nan)[fault_index]  # index -1 picks the appended NaN (also for an empty trace)
    max_count = count.max(axis=-1, initial=0)  # the counter is never negative
    return MonitorTrace(t=t, eps=eps, exceeded=exceeded, valid=valid, count=count, fault=fault,
                        fault_index=fault_index, fault_time=np.asarray(fault_time), max_count=np.asarray(max_count))


def evaluate_z3(z3_model: np.ndarray, z3_meas: np.ndarray, settings: MonitorSettings | None = None,
                t: np.ndarray | None = None) -> MonitorTrace:
    """Offline monitor from tip displacements (m): the model prediction ``(T,)`` or ``(..., T)`` and the
    measurement ``(..., T)`` sampled at the monitor rate."""
    settings = settings if settings is not None else load_monitor_settings()
    return evaluate(normalised_error(z3_model, z3_meas, settings.e0z, settings.kerr_z), settings, t)


class ConditionMonitor:
    """Streaming condition monitor for one test run (the board's 100 Hz loop).

    >>> mon = ConditionMonitor()                        # Table 3 settings from board_config
    >>> s = mon.update(0.00, z3_model=1.0e-3, z3_meas=1.1e-3)
    >>> s.count, s.fault
    (0, False)

    ``update`` takes one sample (time in s, tip displacements in m) and returns a :class:`MonitorSample`;
    ``update_many`` takes a chunk (vectorised, same verdicts); ``state`` is the full :class:`MonitorState`;
    ``reset()`` clears the counter and the latched fault before the next test.
    """

    def __init__(self, settings: MonitorSettings | None = None) -> None:
        self.settings = settings if settings is not None else load_monitor_settings()
        self._state = MonitorState()

    @property
    def state(self) -> MonitorState:
        return self._state

    @property
    def fault(self) -> bool:
        return self._state.fault

    @property
    def count(self) -> int:
        return self._state.count

    @property
    def samples_to_fault(self) -> int:
        """Consecutive exceedances that would latch a fault from the current counter value."""
        return consecutive_exceedances_to_fault(self.settings.count_max, self.settings.counter_up,
                                                self._state.count)

    def reset(self) -> None:
        self._state = MonitorState()

    def error(self, z3_model: float, z3_meas: float) -> float:
        """Eq. 11 for one sample (m in, 1 out)."""
        return normalised_error(z3_model, z3_meas, self.settings.e0z, self.settings.kerr_z)

    def update(self, t: float, z3_model: float, z3_meas: float) -> MonitorSample:
        """One monitor sample at time ``t`` (s): model prediction and measurement of z3 (m)."""
        return self.update_eps(t, self.error(float(z3_model), float(z3_meas)))

    def update_eps(self, t: float, eps: float) -> MonitorSample:
        """One monitor sample given the normalised error directly."""
        self._state, sample = update_state(self._state, t, eps, self.settings)
        return sample

    def update_many(self, t: np.ndarray, z3_model: np.ndarray, z3_meas: np.ndarray) -> MonitorTrace:
        """A chunk of samples (1-D arrays, s and m), vectorised; the stream continues afterwards."""
        return self.update_many_eps(t, normalised_error(z3_model, z3_meas, self.settings.e0z,
                                                        self.settings.kerr_z))

    def update_many_eps(self, t: np.ndarray, eps: np.ndarray) -> MonitorTrace:
        """A chunk of normalised errors (1-D) at times ``t`` (s), vectorised; the stream continues."""
        eps, t = np.atleast_1d(eps), np.atleast_1d(t)  # evaluate() makes them float
        if eps.ndim != 1 or t.shape != eps.shape:
            raise ValueError(f"update_many needs 1-D t and eps of equal length, got {t.shape} and {eps.shape}")
        trace = evaluate(eps, self.settings, t, self._state)
        if t.size == 0:
            return trace
        st = self._state
        latched_here = bool(trace.fault_index >= 0)
        finite = trace.eps[trace.valid]
        self._state = replace(
            st,
            count=int(trace.count[-1]),
            fault=st.fault or latched_here,
            fault_time=float(trace.fault_time) if latched_here else st.fault_time,
            n_samples=st.n_samples + int(t.size),
            n_exceed=st.n_exceed + int(trace.exceeded.sum()),
            n_invalid=st.n_invalid + int((~trace.valid).sum()),
            max_count=max(st.max_count, int(trace.max_count)),
            max_eps=max(st.max_eps, float(finite.max())) if finite.size else st.max_eps,
            t_last=float(trace.t[-1]),
        )
        return trace
