"""A short CPU time slice for the threads that answer the rig link, at normal priority (issue 29.2,
``drivers.latency_slice``): applied with sched_setattr where the kernel takes it (Linux >= 6.12, EEVDF), the policy
stays SCHED_OTHER and the nice value is kept; everywhere else a no-op that says why. `shm hil serve` applies it to
every serving thread (checked in /proc and with chrt), `shm run` to the board's link thread; 0 turns it off."""

from __future__ import annotations

import os
import platform
import re
import subprocess
import sys
import threading
from pathlib import Path

import pytest
from links_support import FakeRig

from board_config.errors import InputError
from drivers.latency_slice import SCHED_OTHER, check_slice_ms, request_slice, thread_slice_s
from hil_stub.service import HilService

ROOT = Path(__file__).resolve().parents[2]


def _kernel_takes_slices() -> bool:
    if platform.system() != "Linux":
        return False
    major, minor = (int(x) for x in re.findall(r"\d+", platform.release())[:2])
    return (major, minor) >= (6, 12)


needs_eevdf = pytest.mark.skipif(not _kernel_takes_slices(), reason="needs Linux >= 6.12 (EEVDF custom slices)")


def test_the_option_range() -> None:
    assert check_slice_ms(0) == 0 and check_slice_ms(0.2) == pytest.approx(2e-4) and check_slice_ms(100) == 0.1
    for bad in (-1, 0.05, 101, float("nan"), float("inf")):
        with pytest.raises(InputError, match="--sched-slice-ms"):
            check_slice_ms(bad)


def test_where_it_cannot_apply_it_changes_nothing_and_says_why() -> None:
    before = thread_slice_s("self", threading.get_native_id())
    for result, why in ((request_slice(2e-4, system="Darwin"), "Darwin"),
                        (request_slice(2e-4, machine="sparc64"), "sparc64")):
        assert not result.applied and why in result.note
    assert thread_slice_s("self", threading.get_native_id()) == before


@needs_eevdf
def test_off_gives_an_inherited_slice_back_to_the_kernel() -> None:
    """0 means the kernel's default even on a thread that got a slice earlier in the process (pytest runs many
    commands in one worker; a thread inherits its creator's slice)."""
    me = threading.get_native_id()
    default = thread_slice_s("self", me)
    try:
        assert request_slice(2e-4).applied and thread_slice_s("self", me) == pytest.approx(2e-4)
        off = request_slice(0)
        assert not off.applied and "off" in off.note
        assert thread_slice_s("self", me) != pytest.approx(2e-4)
    finally:
        request_slice(0)
    assert default is None or thread_slice_s("self", me) == default or default == pytest.approx(2e-4)


def _in_thread(fn):
    out: list = []
    t = threading.Thread(target=lambda: out.append(fn()))
    t.start()
    t.join()
    return out[0]


@needs_eevdf
def test_a_thread_gets_its_slice_and_stays_sched_other_at_its_nice() -> None:
    def work():
        os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), 3)  # this thread only (Linux: per thread)
        result = request_slice(3e-4)
        return (result, thread_slice_s("self", threading.get_native_id()), os.sched_getscheduler(0),
                os.getpriority(os.PRIO_PROCESS, threading.get_native_id()))

    main_before = thread_slice_s("self", threading.get_native_id())
    result, slice_s, policy, nice = _in_thread(work)
    assert result.applied and result.policy == "SCHED_OTHER", result
    assert slice_s == pytest.approx(3e-4) and policy == SCHED_OTHER and nice == 3
    assert thread_slice_s("self", threading.get_native_id()) == main_before  # the calling thread only


@needs_eevdf
def test_a_thread_started_afterwards_inherits_it() -> None:
    def work():
        request_slice(2e-4)
        return _in_thread(lambda: thread_slice_s("self", threading.get_native_id()))

    assert _in_thread(work) == pytest.approx(2e-4)


@pytest.mark.slow
@needs_eevdf
def test_shm_run_gives_the_link_thread_its_slice_and_0_turns_it_off() -> None:
    from shm_cli.main import main

    me = threading.get_native_id()

    def run(tmp: Path, *extra: str) -> float | None:
        with HilService(FakeRig(), mode="realtime") as hil:
            srv = hil.add_modbus_tcp("127.0.0.1:0")
            code = main(["run", "--link", srv.board_url + "&handshake=0", "--duration-s", "0.2", "--quiet",
                         "--out", str(tmp), *extra])
        assert code in (0, 1)  # the fake rig's samples may fail a visit; the link ran paced
        return _in_thread_slice(me)

    base = run(Path(os.environ.get("TMPDIR", "/tmp")) / f"slice-off-{os.getpid()}", "--sched-slice-ms", "0")
    try:
        assert run(Path(os.environ.get("TMPDIR", "/tmp")) / f"slice-on-{os.getpid()}") == pytest.approx(2e-4)
        assert base != pytest.approx(2e-4)
    finally:
        if base:
            request_slice(max(base, 1e-4))  # the test process' main thread as it was


def _in_thread_slice(tid: int) -> float | None:
    return thread_slice_s("self", tid)


@pytest.mark.slow
@needs_eevdf
@pytest.mark.parametrize("slice_ms", ["0.2", "0"])
def test_hil_serve_serves_from_threads_with_the_slice_at_normal_priority(slice_ms: str, tmp_path: Path) -> None:
    proc = subprocess.Popen([sys.executable, "-m", "shm_cli.main", "hil", "serve", "--modbus-tcp", "127.0.0.1:0",
                             "--duration", "60", "--status-every", "0", "--sched-slice-ms", slice_ms],
                            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, cwd=ROOT,
                            env={**os.environ, "PYTHONPATH": str(ROOT)})
    try:
        assert proc.stdout is not None
        lines = []
        for line in proc.stdout:
            lines.append(line)
            if "scheduler slice:" in line:
                break
        tids = os.listdir(f"/proc/{proc.pid}/task")
        slices = {tid: thread_slice_s(proc.pid, int(tid)) for tid in tids}
        chrt = subprocess.run(["chrt", "-p", str(proc.pid)], capture_output=True, text=True).stdout
        policies = {tid: os.sched_getscheduler(int(tid)) for tid in tids}
    finally:
        proc.terminate()
        proc.wait(30)
    assert "SCHED_OTHER" in chrt and "priority: 0" in chrt, chrt
    assert set(policies.values()) == {SCHED_OTHER}
    assert len(slices) >= 2  # main, the Modbus event loop (the rig clock runs on it)
    if slice_ms == "0.2":
        assert "0.2 ms per slice, SCHED_OTHER" in lines[-1]
        assert all(v == pytest.approx(2e-4) for v in slices.values()), slices
    else:
        assert "off" in lines[-1] and not any(v == pytest.approx(2e-4) for v in slices.values()), slices


@needs_eevdf
def test_the_rig_clock_thread_can_keep_the_kernels_slice_while_the_serving_threads_get_the_short_one() -> None:
    """``--clock-slice-ms 0``: the serving threads (the Modbus event loop) keep the short slice they inherit, the rig
    clock thread — the physics step, a GIL holder — goes back to the kernel's default."""

    def serve() -> tuple[float | None, float | None, str]:
        request_slice(2e-4)  # as `shm hil serve` does for the process before it builds the service
        with HilService(FakeRig(), mode="realtime", clock_slice_s=0.0, rig_clock="thread") as hil:
            hil.add_modbus_tcp("127.0.0.1:0")
            clock_thread, loop_thread = hil.host._thread, hil.loop._thread
            assert clock_thread is not None and clock_thread.native_id and loop_thread.native_id
            return (thread_slice_s("self", clock_thread.native_id), thread_slice_s("self", loop_thread.native_id),
                    hil.host.clock_slice_note)

    clock_slice, loop_slice, note = _in_thread(serve)
    assert loop_slice == pytest.approx(2e-4)
    assert clock_slice is not None and clock_slice != pytest.approx(2e-4) and "off" in note


def test_the_default_slice_is_chosen_per_link() -> None:
    from shm_cli.hil_cmd import serving_slice_ms

    assert serving_slice_ms(None, serial_endpoints=0) == 0.2  # Modbus TCP only: the short slice
    assert serving_slice_ms(None, serial_endpoints=1) == 0.0  # an RTU / serial endpoint: the kernel's default
    assert serving_slice_ms(0.5, serial_endpoints=1) == 0.5 and serving_slice_ms(0.0, serial_endpoints=0) == 0.0


@needs_eevdf
def test_off_for_the_process_gives_every_running_thread_the_kernels_slice_back() -> None:
    """A process started by one with a slice (a test runner, a bench) inherits it in every thread it has; 0 for the
    process (``shm hil serve --sched-slice-ms 0``, or its default with an RTU endpoint) resets them all."""
    from drivers.latency_slice import request_process_slice

    def work() -> float | None:
        request_slice(2e-4)
        go = threading.Event()
        tid: list[int] = []

        def waiting() -> None:
            tid.append(threading.get_native_id())
            go.wait(10)

        worker = threading.Thread(target=waiting)
        worker.start()
        while not tid:
            pass
        try:
            assert thread_slice_s("self", tid[0]) == pytest.approx(2e-4)  # inherited
            request_process_slice(0)
            return thread_slice_s("self", tid[0])
        finally:
            go.set()
            worker.join()

    assert _in_thread(work) != pytest.approx(2e-4)


@pytest.mark.slow
@needs_eevdf
@pytest.mark.parametrize(("endpoint", "announced"), [(("--modbus-tcp", "127.0.0.1:0"), "0.2 ms per slice"),
                                                     (("--modbus-rtu", "pty"), "off")])
def test_hil_serve_chooses_the_slice_per_link_by_default(endpoint: tuple[str, str], announced: str) -> None:
    proc = subprocess.Popen([sys.executable, "-m", "shm_cli.main", "hil", "serve", *endpoint, "--duration", "60",
                             "--status-every", "0"], stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True,
                            cwd=ROOT, env={**os.environ, "PYTHONPATH": str(ROOT)})
    try:
        assert proc.stdout is not None
        line = next((line for line in proc.stdout if "scheduler slice:" in line), "")
    finally:
        proc.terminate()
        proc.wait(30)
    assert announced in line, line
