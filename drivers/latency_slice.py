"""A short CPU time slice for the threads that answer a rig link — at normal priority (issue 29, point 2).

On a desk where every core runs a CPU-bound job at the same priority, a woken stub or board thread waits until the
running job's time slice ends or the next scheduler tick (4 ms at HZ = 250) before it runs: the stub's own answer
takes 0.3-0.6 ms, the client sees up to 5 ms at p99. Linux >= 6.12 schedules normal tasks with EEVDF, where a task
may ask for a shorter slice with ``sched_setattr(2)``: policy ``SCHED_OTHER``, its nice value kept, ``sched_runtime``
= the slice in ns (the kernel clamps it to 0.1-100 ms). With the scheduler feature ``PREEMPT_SHORT`` (on by default) a
waking task whose slice is shorter than the running one's preempts it at once instead of waiting for the tick. No
real-time policy, no privilege, no change of nice: the thread's share of the CPU stays that of a nice-0 task, only its
slices are shorter (it runs sooner and more often, for less each time).

:func:`request_slice` applies it to the calling thread (``tid`` 0) or another thread of this process; threads
started afterwards inherit it. Where it cannot apply — not Linux, an architecture whose syscall number is not known
here, a kernel that refuses (EINVAL) or ignores it (older than 6.12: the slice reads back as 0), a thread under a
real-time policy (``chrt``: left as it is) — it changes nothing and says why (:class:`SliceResult` ``.note``, logged
at INFO). ``shm hil serve`` and ``shm run --link`` (hardware links) request 0.2 ms unless ``--sched-slice-ms 0``.
"""

from __future__ import annotations

import ctypes
import logging
import math
import os
import platform
import threading
from collections.abc import Callable
from dataclasses import dataclass

from board_config.errors import InputError

log = logging.getLogger("drivers.latency_slice")

DEFAULT_SLICE_S = 2e-4  #: 0.2 ms: well below the 3 ms default slice of a CPU-bound neighbour
SLICE_MIN_S, SLICE_MAX_S = 1e-4, 0.1  #: what the kernel accepts (it clamps to this range)
SCHED_OTHER = 0
#: (sched_setattr, sched_getattr) per machine (``platform.machine()``)
SYSCALLS: dict[str, tuple[int, int]] = {"x86_64": (314, 315), "aarch64": (274, 275), "riscv64": (274, 275),
                                         "armv7l": (380, 381), "i686": (351, 352)}
_POLICY_NAMES = {0: "SCHED_OTHER", 1: "SCHED_FIFO", 2: "SCHED_RR", 3: "SCHED_BATCH", 5: "SCHED_IDLE",
                 6: "SCHED_DEADLINE"}


class _SchedAttr(ctypes.Structure):
    """``struct sched_attr`` (include/uapi/linux/sched/types.h, SCHED_ATTR_SIZE_VER1: 56 bytes)."""

    _fields_ = [("size", ctypes.c_uint32), ("sched_policy", ctypes.c_uint32), ("sched_flags", ctypes.c_uint64),
                ("sched_nice", ctypes.c_int32), ("sched_priority", ctypes.c_uint32),
                ("sched_runtime", ctypes.c_uint64), ("sched_deadline", ctypes.c_uint64),
                ("sched_period", ctypes.c_uint64), ("sched_util_min", ctypes.c_uint32),
                ("sched_util_max", ctypes.c_uint32)]


@dataclass(frozen=True)
class SliceResult:
    """What :func:`request_slice` did: ``applied`` with the slice the kernel reports (s), else why not."""

    applied: bool
    slice_s: float
    note: str
    policy: str = ""


def check_slice_ms(value: float) -> float:
    """The ``--sched-slice-ms`` value in seconds (0: off); :class:`InputError` outside 0.1-100 ms. Pure."""
    if not math.isfinite(value) or value < 0 or (value and not SLICE_MIN_S <= value / 1e3 <= SLICE_MAX_S):
        raise InputError(f"--sched-slice-ms {value:g}: allowed 0 (off) or {1e3 * SLICE_MIN_S:g} .. "
                         f"{1e3 * SLICE_MAX_S:g} ms")
    return value / 1e3


#: ``syscall(2)`` from the C library: (number, *arguments) -> result (-1 with errno on failure)
_Syscall = Callable[..., int]


def _libc_syscall() -> _Syscall:
    libc = ctypes.CDLL(None, use_errno=True)
    fn = libc.syscall
    fn.restype = ctypes.c_long
    syscall: _Syscall = fn
    return syscall


def _getattr(syscall: _Syscall, nr: int, tid: int) -> _SchedAttr | None:
    attr = _SchedAttr()
    if syscall(nr, tid, ctypes.byref(attr), ctypes.c_uint(ctypes.sizeof(_SchedAttr)), ctypes.c_uint(0)) != 0:
        return None
    return attr


def request_slice(slice_s: float = DEFAULT_SLICE_S, tid: int = 0, *, machine: str | None = None,
                  system: str | None = None) -> SliceResult:
    """Ask for a ``slice_s`` (s) time slice for thread ``tid`` (0: the calling one), keeping ``SCHED_OTHER`` and its
    nice value; a no-op with a note where that is not possible (see the module docstring)."""
    result = _request(slice_s, tid, machine or platform.machine(), system or platform.system())
    log.info("scheduler slice: %s", result.note)
    return result


def request_process_slice(slice_s: float = DEFAULT_SLICE_S) -> SliceResult:
    """:func:`request_slice` for every thread of this process (those already running — a library's worker started
    at import — and, by inheritance, those started afterwards); the calling thread's result. With ``slice_s`` 0 every
    thread goes back to the kernel's default, also one that inherited a slice from the process' parent."""
    result = request_slice(slice_s)
    if result.applied or slice_s <= 0:
        me = threading.get_native_id()
        for tid in _thread_ids():
            if tid != me:
                _request(slice_s, tid, platform.machine(), platform.system())
    return result


def _thread_ids() -> list[int]:
    try:
        return [int(t) for t in os.listdir("/proc/self/task")]
    except (OSError, ValueError):
        return []


def _request(slice_s: float, tid: int, machine: str, system: str) -> SliceResult:
    numbers = SYSCALLS.get(machine) if system == "Linux" else None
    if slice_s <= 0:  # off: a slice this thread inherited (an earlier request in this process) goes back too
        if numbers is not None:
            _reset(numbers, tid)
        return SliceResult(False, 0.0, "off (--sched-slice-ms 0): the kernel's default slice")
    if system != "Linux":
        return SliceResult(False, 0.0, f"not applied: {system} has no sched_setattr slice (Linux >= 6.12 only)")
    if numbers is None:
        return SliceResult(False, 0.0, f"not applied: sched_setattr's number on {machine} is not known here")
    set_nr, get_nr = numbers
    syscall = _libc_syscall()
    now = _getattr(syscall, get_nr, tid)
    if now is None:
        err = ctypes.get_errno()
        return SliceResult(False, 0.0, f"not applied: sched_getattr failed ({os.strerror(err)})")
    if now.sched_policy != SCHED_OTHER:
        name = _POLICY_NAMES.get(now.sched_policy, str(now.sched_policy))
        return SliceResult(False, 0.0, f"not applied: the thread runs {name} (a real-time policy set by chrt is "
                                       "left as it is)", name)
    want = _SchedAttr(size=ctypes.sizeof(_SchedAttr), sched_policy=SCHED_OTHER, sched_nice=now.sched_nice,
                      sched_runtime=round(min(max(slice_s, SLICE_MIN_S), SLICE_MAX_S) * 1e9))
    if syscall(set_nr, tid, ctypes.byref(want), ctypes.c_uint(0)) != 0:
        err = ctypes.get_errno()
        return SliceResult(False, 0.0, f"not applied: sched_setattr refused ({os.strerror(err)}; needs Linux >= 6.12 "
                                       "with the EEVDF scheduler)")
    got = _getattr(syscall, get_nr, tid)
    if got is None or got.sched_runtime == 0:
        return SliceResult(False, 0.0, "not applied: the kernel ignores a SCHED_OTHER slice (older than Linux 6.12)")
    policy = _POLICY_NAMES.get(got.sched_policy, str(got.sched_policy))
    return SliceResult(True, got.sched_runtime / 1e9, f"{got.sched_runtime / 1e6:g} ms per slice, {policy}, "
                                                      f"nice {got.sched_nice} (sched_setattr)", policy)


def _reset(numbers: tuple[int, int], tid: int) -> None:
    """Give a SCHED_OTHER thread the kernel's default slice back (``sched_runtime`` 0); anything else is left."""
    set_nr, get_nr = numbers
    syscall = _libc_syscall()
    now = _getattr(syscall, get_nr, tid)
    if now is not None and now.sched_policy == SCHED_OTHER:
        back = _SchedAttr(size=ctypes.sizeof(_SchedAttr), sched_policy=SCHED_OTHER, sched_nice=now.sched_nice)
        syscall(set_nr, tid, ctypes.byref(back), ctypes.c_uint(0))


def thread_slice_s(pid: int | str = "self", tid: int | None = None) -> float | None:
    """The slice (s) the kernel reports for a thread (``/proc/PID/task/TID/sched``, ``se.slice``; the process' main
    thread when ``tid`` is None); None where it is not reported."""
    path = f"/proc/{pid}/sched" if tid is None else f"/proc/{pid}/task/{tid}/sched"
    try:
        with open(path) as fh:
            for line in fh:
                if line.startswith("se.slice"):
                    return int(line.split(":")[1]) / 1e9
    except (OSError, ValueError, IndexError):
        return None
    return None
