"""The stub answers a Modbus request on its event loop's thread alone (issue 29, point 2): the realtime rig clock
ticks on that loop (no second thread to wake, no GIL hand-over between a request and its reply) and a lockstep plant
step runs inline (no worker thread per transaction); ``rig_clock="thread"`` keeps the clock in a thread of its own."""

from __future__ import annotations

import threading
import time

import pytest
from pymodbus.client import ModbusTcpClient

from drivers.link import ActuatorCommand
from drivers.modbus_registers import COMMAND_START, INPUT_COUNT, INPUT_START, encode_command_block
from hil_stub.service import HilService
from tests.links_support import FakeRig, wait_for


def _serve(mode: str, rig_clock: str = "loop") -> tuple[set[int], int, int | None, int]:
    """(threads the rig ticked on, the event loop's thread, the clock thread or None, ticks) after 5 commands."""
    ticked_on: set[int] = set()
    with HilService(FakeRig(), mode=mode, rig_clock=rig_clock) as hil:
        srv = hil.add_modbus_tcp("127.0.0.1:0")
        hil.host.on_tick = lambda _snap: ticked_on.add(threading.get_ident())
        client = ModbusTcpClient("127.0.0.1", port=srv.port, timeout=2.0)
        assert client.connect()
        try:
            for k in range(1, 6):
                words = encode_command_block(ActuatorCommand(seq=k, v_ch1=10.0 * k, v_ch2=0.0, board_current=0.001))
                assert not client.write_registers(COMMAND_START, words, device_id=1).isError()
                assert not client.read_input_registers(INPUT_START, count=INPUT_COUNT, device_id=1).isError()
            if mode == "realtime":
                assert wait_for(lambda: hil.host.pacing.ticks >= 5, timeout=5.0)
        finally:
            client.close()
        loop_thread = hil.loop._thread.ident
        clock = hil.host._thread
        assert loop_thread is not None
        return ticked_on, loop_thread, None if clock is None else clock.ident, hil.host.snapshot.tick


def test_the_realtime_clock_ticks_on_the_modbus_event_loop() -> None:
    ticked_on, loop_thread, clock_thread, ticks = _serve("realtime")
    assert clock_thread is None and ticked_on == {loop_thread} and ticks >= 5


def test_the_realtime_clock_can_keep_a_thread_of_its_own() -> None:
    ticked_on, loop_thread, clock_thread, _ticks = _serve("realtime", rig_clock="thread")
    assert clock_thread is not None and ticked_on == {clock_thread} != {loop_thread}


def test_a_lockstep_step_runs_on_the_event_loop_not_a_worker_thread() -> None:
    ticked_on, loop_thread, _clock, ticks = _serve("lockstep")
    assert ticked_on == {loop_thread} and ticks == 5  # one tick per command, as before


def test_an_unknown_rig_clock_is_refused_by_name() -> None:
    from board_config.errors import InputError

    with pytest.raises(InputError, match="rig clock 'fast'"):
        HilService(FakeRig(), rig_clock="fast")


def test_the_clock_on_a_loop_waits_for_the_first_command_then_paces_at_100_hz() -> None:
    from hil_stub.loop_thread import LoopThread
    from hil_stub.rig_host import RigHost

    loop = LoopThread()
    host = RigHost(FakeRig(), mode="realtime", keep_lateness=True)
    try:
        host.start(loop.loop)
        assert not wait_for(lambda: host.pacing.ticks > 0, timeout=0.1)  # stands still until a command
        host.submit(ActuatorCommand(1, 10.0, 0.0))
        t0 = time.perf_counter()
        assert wait_for(lambda: host.pacing.ticks >= 30, timeout=5)
        took = time.perf_counter() - t0
    finally:
        host.stop()
        loop.close()
    ticks = host.pacing.ticks
    assert took >= 0.29 - 0.005 * 30  # paced, not run flat out (a tick may run up to 1 ms early)
    assert host.snapshot.sample.t == pytest.approx(0.01 * host.snapshot.tick) and len(host.pacing.lateness_samples) \
        == ticks
    time.sleep(0.05)
    assert host.pacing.ticks == ticks  # stopped: no tick after stop()
