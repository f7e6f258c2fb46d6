"""The HIL service: one rig host serving every requested endpoint at once (what ``shm hil serve`` runs).

::

    with HilService(rig, mode="realtime", plan=FaultPlan(...)) as hil:
        tcp = hil.add_modbus_tcp("127.0.0.1:0")
        ser = hil.add_serial("pty")
        print(tcp.board_url, ser.board_url)      # what the board passes to --link
        ...
    print(hil.summary())

Sensor faults of the plan wrap the endpoint (:class:`~hil_stub.faults.SensorFaultRig`); wire faults go to every
server, each with its own seeded random stream; truth changes (deviations, effects) must already be in the
endpoint (:func:`hil_stub.truth.build_truth_rig`).
"""

from __future__ import annotations

import contextlib
import sys
from typing import Any, TypeVar

from drivers.link import RigEndpoint
from hil_stub.faults import FaultPlan, SensorFaultRig
from hil_stub.frame_server import FrameServer
from hil_stub.modbus_server import LoopThread, ModbusRigServer
from hil_stub.rig_host import RigHost

_Server = TypeVar("_Server", FrameServer, ModbusRigServer)

#: GIL hand-over interval while a real-time service runs (s): the rig loop, the Modbus event loop and the serial
#: servers share one interpreter — with a board in the same process too (the fault-matrix tests) — and at Python's
#: default 5 ms a reply could wait a whole tick behind a plant step or the board's model step
SWITCH_INTERVAL_S = 5e-4


class HilService:
    """A rig host plus its servers (see the module docstring)."""

    def __init__(self, endpoint: RigEndpoint, *, mode: str = "realtime", dt: float = 0.01,
                 plan: FaultPlan | None = None, start: str = "first-command", keep_lateness: bool = False) -> None:
        self.plan = plan or FaultPlan()
        if self.plan.sensors.active:
            endpoint = SensorFaultRig(endpoint, self.plan.sensors, self.plan.seed)
        self.endpoint = endpoint
        self.host = RigHost(endpoint, dt=dt, mode=mode, start=start, keep_lateness=keep_lateness)
        self.servers: list[FrameServer | ModbusRigServer] = []
        self._loop: LoopThread | None = None
        self._started = False
        self._switch_interval: float | None = None

    @property
    def loop(self) -> LoopThread:
        if self._loop is None:
            self._loop = LoopThread()
        return self._loop

    def _add(self, server: _Server) -> _Server:
        self.servers.append(server)
        if self._started:
            server.start()
        return server

    def add_serial(self, where: str = "pty", *, link_path: str | None = None,
                   baudrate: int = 115200) -> FrameServer:
        """The framed serial protocol on ``where`` (``pty``, ``socket://HOST:PORT`` to listen, or a device)."""
        srv = FrameServer(self.host, where, faults=self.plan.link, seed=self.plan.seed, stream=len(self.servers) + 1,
                          link_path=link_path, baudrate=baudrate)
        return self._add(srv)

    def add_modbus_tcp(self, address: str = "127.0.0.1:0", *, unit: int = 1) -> ModbusRigServer:
        srv = ModbusRigServer(self.host, "tcp", address, loop=self.loop, unit=unit, faults=self.plan.link,
                              seed=self.plan.seed, stream=len(self.servers) + 1)
        return self._add(srv)

    def add_modbus_rtu(self, path: str = "pty", *, unit: int = 1, baudrate: int = 115200,
                       parity: str = "N") -> ModbusRigServer:
        srv = ModbusRigServer(self.host, "rtu", path, loop=self.loop, unit=unit, faults=self.plan.link,
                              seed=self.plan.seed, stream=len(self.servers) + 1, baudrate=baudrate, parity=parity)
        return self._add(srv)

    def start(self) -> None:
        if self._started:
            return
        self._started = True
        if self.host.mode == "realtime" and self._switch_interval is None:
            self._switch_interval = sys.getswitchinterval()
            sys.setswitchinterval(min(self._switch_interval, SWITCH_INTERVAL_S))
        try:
            for srv in self.servers:
                srv.start()
            self.host.start()
        except Exception:
            self.stop()
            raise

    def stop(self) -> None:
        self.host.stop()
        for srv in self.servers:
            with contextlib.suppress(Exception):
                srv.stop()
        if self._loop is not None:
            self._loop.close()
            self._loop = None
        if self._switch_interval is not None:
            sys.setswitchinterval(self._switch_interval)
            self._switch_interval = None
        self._started = False

    def __enter__(self) -> HilService:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def summary(self) -> dict[str, Any]:
        """Counts and pacing, JSON-able."""
        h = self.host
        snap = h.snapshot
        return {
            "mode": h.mode, "tick_s": h.dt, "rig_time_s": snap.sample.t, "rig_ticks": snap.tick,
            "commands": h.commands, "refused": h.refused_count, "undelivered": h.undelivered,
            "incidents": h.incident_count, "pacing": h.pacing.summary() if h.mode == "realtime" else None,
            "servers": {srv.describe(): {**dict(srv.stats), **srv.faulter.counts()} for srv in self.servers},
            "faults": self.plan.describe(),
        }
