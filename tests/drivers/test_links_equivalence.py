"""Every hardware link, served lock-step, behaves exactly like the in-process link on the same rig: the same
sequence of samples and failures for the same commands — including out-of-limit commands (refused, flagged, output
kept) and the rig's scheduled link outages (no reply, rig time still advances). The float32 encoding on the wire is
the only difference allowed."""

from __future__ import annotations

import pytest
from links_support import FakeRig

from drivers import ActuatorCommand, LinkError, open_link
from drivers.sim_link import InProcessLink
from hil_stub.service import HilService

pytestmark = pytest.mark.integration

OUTAGES = [(0.105, 0.145)]  # rig time (s): exchanges 11..14 fail


def commands():
    for k in range(1, 41):
        v = 20.0 * k
        if k in (7, 25):
            v = 1600.0  # above Table 1: refused
        yield ActuatorCommand(k, v, -v / 2, 0.001 * (k % 3))


def outcomes(link):
    out = []
    link.open()
    try:
        for c in commands():
            try:
                s = link.exchange(c)
                out.append(("ok", s.seq, round(s.t, 9), s.z3, s.v_patch, s.flags))
            except LinkError:
                out.append(("error",))
    finally:
        link.close()
    return out


@pytest.mark.parametrize("kind", ["serial", "socket", "modbus-tcp", "modbus-rtu"])
def test_same_outcomes_as_in_process(kind):
    ref = outcomes(InProcessLink(FakeRig(OUTAGES)))
    assert [o[0] for o in ref].count("error") == 4
    with HilService(FakeRig(OUTAGES), mode="lockstep") as hil:
        srv = {"serial": lambda: hil.add_serial("pty"), "socket": lambda: hil.add_serial("socket://127.0.0.1:0"),
               "modbus-tcp": lambda: hil.add_modbus_tcp("127.0.0.1:0"),
               "modbus-rtu": lambda: hil.add_modbus_rtu("pty")}[kind]()
        url = srv.board_url + ("&" if "?" in srv.board_url else "?") + "timeout=0.1&reopen=1000"
        got = outcomes(open_link(url))
    assert [o[0] for o in got] == [o[0] for o in ref]
    for a, b in zip(got, ref):
        if a[0] == "ok":
            assert a[1:3] == b[1:3] and a[5] == b[5]  # rig counter, rig time, flags (refusals) identical
            assert a[3] == pytest.approx(b[3], rel=1e-6, abs=1e-12) and a[4] == pytest.approx(b[4], rel=1e-6)
