"""The HIL service: one rig host serving every requested endpoint at once (what ``shm hil serve`` runs).

::

    with HilService(rig, mode="realtime", plan=FaultPlan(...)) as hil:
        tcp = hil.add_modbus_tcp("127.0.0.1:0")
        ser = hil.add_serial("pty")
        print(tcp.board_url, ser.board_url)      # what the board passes to --link
        ...
    print(hil.summary())

With ``restart`` (a factory of fresh endpoints, e.g. ``lambda: build_truth_rig(...)``) a lockstep service starts
the rig again for every new board run (:class:`~hil_stub.rig_host.RigHost`): the next rig is built in the background
while the current one serves, so the swap costs the board's first exchange nothing.

Sensor faults of the plan wrap the endpoint (:class:`~hil_stub.faults.SensorFaultRig`); wire faults go to every
server, each with its own seeded random stream; truth changes (deviations, effects) must already be in the
endpoint (:func:`hil_stub.truth.build_truth_rig`).
"""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any, TypeVar

from board_config.errors import InputError
from drivers.link import RigEndpoint
from drivers.modbus_registers import MAP_VERSION
from hil_stub.faults import FaultPlan, SensorFaultRig
from hil_stub.frame_server import FrameServer
from hil_stub.loop_thread import LoopThread
from hil_stub.modbus_server import ModbusRigServer
from hil_stub.rig_host import RigHost

#: where the realtime rig clock can run (:class:`HilService` ``rig_clock``)
RIG_CLOCKS = ("loop", "thread")

_Server = TypeVar("_Server", FrameServer, ModbusRigServer)

#: GIL hand-over interval while a real-time service runs (s): the rig loop, the Modbus event loop and the serial
#: servers share one interpreter — with a board in the same process too (the fault-matrix tests) — and at Python's
#: default 5 ms a reply could wait a whole tick behind a plant step or the board's model step
SWITCH_INTERVAL_S = 5e-4


class HilService:
    """A rig host plus its servers (see the module docstring)."""

    def __init__(self, endpoint: RigEndpoint, *, mode: str = "realtime", dt: float = 0.01,
                 plan: FaultPlan | None = None, start: str = "first-command", keep_lateness: bool = False,
                 restart: Callable[[], RigEndpoint] | None = None, clock_slice_s: float | None = None,
                 rig_clock: str = "loop", hot_path: bool = True) -> None:
        if rig_clock not in RIG_CLOCKS:
            raise InputError(f"rig clock {rig_clock!r}: allowed {', '.join(RIG_CLOCKS)}")
        #: where the realtime rig clock runs with a Modbus server: on its event loop's thread ("loop") or in a thread
        #: of its own ("thread"; always so without a Modbus server)
        self.rig_clock = rig_clock
        self.hot_path = hot_path  #: Modbus FC 03/04/16/23 answered by :mod:`hil_stub.modbus_hot_path`
        self.plan = plan or FaultPlan()
        self.endpoint = self._with_faults(endpoint)
        self._build = restart if mode == "lockstep" else None
        self._builder: ThreadPoolExecutor | None = None
        self._spare: Future | None = None
        self.host = RigHost(self.endpoint, dt=dt, mode=mode, start=start, keep_lateness=keep_lateness,
                            restart=self._next_rig if self._build is not None else None,
                            clock_slice_s=clock_slice_s)
        self.servers: list[FrameServer | ModbusRigServer] = []
        self._loop: LoopThread | None = None
        self._started = False
        self._switch_interval: float | None = None

    def _with_faults(self, endpoint: RigEndpoint) -> RigEndpoint:
        if self.plan.sensors.active:  # a fresh wrapper: its noise stream starts again from the plan's seed
            return SensorFaultRig(endpoint, self.plan.sensors, self.plan.seed)
        return endpoint

    def _build_spare(self) -> None:
        """Start building the rig the next board run will get (in the background)."""
        if self._build is None:
            return
        if self._builder is None:
            self._builder = ThreadPoolExecutor(max_workers=1, thread_name_prefix="rig-spare")
        self._spare = self._builder.submit(self._build)

    def _next_rig(self) -> RigEndpoint:
        """A rig as built at the start, for a new board run (the spare, then the next spare is started)."""
        spare, self._spare = self._spare, None
        if spare is None:
            assert self._build is not None
            fresh = self._build()
        else:
            fresh = spare.result()
        self._build_spare()
        self.endpoint = self._with_faults(fresh)
        return self.endpoint

    @property
    def loop(self) -> LoopThread:
        if self._loop is None:
            self._loop = LoopThread()
        return self._loop

    def _add(self, server: _Server) -> _Server:
        self.servers.append(server)
        if self._started:
            server.start()
            if isinstance(server, ModbusRigServer) and self.rig_clock == "loop":
                self.host.run_clock_on(self.loop.loop)
        return server

    def add_serial(self, where: str = "pty", *, link_path: str | None = None,
                   baudrate: int = 115200) -> FrameServer:
        """The framed serial protocol on ``where`` (``pty``, ``socket://HOST:PORT`` to listen, or a device)."""
        srv = FrameServer(self.host, where, faults=self.plan.link, seed=self.plan.seed, stream=len(self.servers) + 1,
                          link_path=link_path, baudrate=baudrate)
        return self._add(srv)

    def add_modbus_tcp(self, address: str = "127.0.0.1:0", *, unit: int = 1,
                       map_version: int = MAP_VERSION) -> ModbusRigServer:
        """Serve the rig over Modbus TCP; ``map_version=1`` serves the map without the sample mirror and FC 23."""
        srv = ModbusRigServer(self.host, "tcp", address, loop=self.loop, unit=unit, faults=self.plan.link,
                              seed=self.plan.seed, stream=len(self.servers) + 1, map_version=map_version,
                              hot_path=self.hot_path)
        return self._add(srv)

    def add_modbus_rtu(self, path: str = "pty", *, unit: int = 1, baudrate: int = 115200,
                       parity: str = "N", map_version: int = MAP_VERSION) -> ModbusRigServer:
        srv = ModbusRigServer(self.host, "rtu", path, loop=self.loop, unit=unit, faults=self.plan.link,
                              seed=self.plan.seed, stream=len(self.servers) + 1, baudrate=baudrate, parity=parity,
                              map_version=map_version, hot_path=self.hot_path)
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
            on_loop = self.rig_clock == "loop" and any(isinstance(s, ModbusRigServer) for s in self.servers)
            self.host.start(self.loop.loop if on_loop else None)
            self._build_spare()
        except Exception:
            self.stop()
            raise

    def stop(self) -> None:
        self.host.stop()
        if self._builder is not None:
            self._builder.shutdown(wait=False, cancel_futures=True)
            self._builder = None
            self._spare = None
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
            "board_runs": h.board_runs, "rig_restarts": h.restarts,
            "incidents": h.incident_count, "pacing": h.pacing.summary() if h.mode == "realtime" else None,
            "servers": {srv.describe(): {**dict(srv.stats), **srv.faulter.counts(), **_answer_times(srv)}
                        for srv in self.servers},
            "faults": self.plan.describe(),
        }


def _answer_times(server: FrameServer | ModbusRigServer) -> dict[str, Any]:
    """A Modbus server's answer times for the summary: from reading the request (``answer_time``) and, on TCP where
    the kernel stamps what it receives, from the kernel's receive timestamp (``answer_time_from_kernel_rx``)."""
    if not isinstance(server, ModbusRigServer):
        return {}
    out: dict[str, Any] = {"answer_time": server.service_time_summary()}
    if server.kind == "tcp":
        out["answer_time_from_kernel_rx"] = (server.service_time_summary(from_kernel=True) if server.kernel_stamps
                                             else {"n": 0, "note": "no kernel receive timestamps on this system"})
    return out
