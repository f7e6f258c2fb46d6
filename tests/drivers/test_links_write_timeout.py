"""A write timeout reported after the frame went out must not take the serial link down (issue 14, point 4).

pyserial's POSIX ``write`` checks its write timeout *after* ``os.write`` has taken the frame: under CPU load the
process can be descheduled for longer than the timeout between the two, and the write then raises
``SerialTimeoutException`` although the rig has the frame. The link used to treat that as a lost port (closed it, the
next exchanges failed while it reopened with back-off). Reproduced here by making pyserial's timeout expire at once.
"""

from __future__ import annotations

import pytest
import serial.serialutil
from links_support import FakeRig, cmd

from drivers import open_link
from hil_stub.service import HilService


@pytest.fixture
def lockstep_pty():
    rig = FakeRig()
    with HilService(rig, mode="lockstep") as hil:
        srv = hil.add_serial("pty")
        yield srv, rig


def test_write_timeout_after_the_frame_went_out_keeps_the_link(lockstep_pty, monkeypatch):
    srv, rig = lockstep_pty
    with open_link(srv.board_url + "?timeout=0.5") as link:
        first = [link.exchange(cmd(k)) for k in range(1, 4)]
        port = link._port
        assert port is not None
        real_write = port.write

        def preempted_write(data):
            # what pyserial does when the process was descheduled past write_timeout right after os.write
            with monkeypatch.context() as m:
                m.setattr(serial.serialutil.Timeout, "expired", lambda self: True)
                return real_write(data)

        port.write = preempted_write  # type: ignore[method-assign]
        during = [link.exchange(cmd(k)) for k in range(4, 9)]
        port.write = real_write  # type: ignore[method-assign]
        after = [link.exchange(cmd(k)) for k in range(9, 12)]
        assert link._port is port  # never closed
        assert link.stats["write_timeouts"] == 5
        assert link.stats["link_down"] == 0
    assert [s.seq for s in first + during + after] == list(range(1, 12))
    assert [c.seq for c in rig.applied] == list(range(1, 12))
