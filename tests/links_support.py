"""Helpers for the link tests: a small deterministic rig and bounded waiting."""

from __future__ import annotations

import logging
import shutil
import struct
import subprocess
import time
from collections.abc import Callable, Iterator
from typing import Any

from drivers import open_link
from drivers.link import FLAG_LIMIT_REFUSED, ActuatorCommand, RigSample
from hil_stub.faults import FaultPlan, LinkFaults
from hil_stub.service import HilService

logging.getLogger("pymodbus").setLevel(logging.CRITICAL)


class FakeRig:
    """A first-order lag from the differential demand to z3 (1e-5 m/V), in rig time; optional link outages;
    refuses demands outside Table 1 like the simulated rig."""

    def __init__(self, outages: list[tuple[float, float]] | None = None) -> None:
        self.t = 0.0
        self.seq = 0
        self.v = (0.0, 0.0)
        self.z3 = 0.0
        self.applied: list[ActuatorCommand] = []
        self.outages = outages or []
        self.refused = False

    def apply(self, command: ActuatorCommand) -> None:
        """Refuses a demand outside Table 1 (keeps the last output, flags the samples), as the real rig does."""
        if not (-500.0 <= command.v_ch1 <= 1500.0 and -500.0 <= command.v_ch2 <= 1500.0):
            self.refused = True
            return
        self.refused = False
        self.applied.append(command)
        self.v = (command.v_ch1, command.v_ch2)

    def advance(self, dt: float) -> None:
        self.t += dt
        self.seq += 1
        target = 1e-5 * (self.v[0] - self.v[1]) / 2
        self.z3 += (target - self.z3) * min(1.0, dt / 0.05)

    def sample(self) -> RigSample:
        return RigSample(self.seq, self.t, self.z3, (self.v[0] - self.v[1]) / 2, 0.0, 3.0, True,
                         FLAG_LIMIT_REFUSED if self.refused else 0)

    def link_down(self) -> bool:
        return any(a <= self.t < b for a, b in self.outages)


class LinkWrapper:
    """A Link around ``link`` for a test: passes everything through, counting exchanges in ``n`` (1-based); a test
    overrides :meth:`before_exchange` to record, fail or disturb exchange ``n`` before it reaches ``link``."""

    def __init__(self, link) -> None:
        self.link = link
        self.url = link.url
        self.n = 0

    def open(self) -> None:
        self.link.open()

    def close(self) -> None:
        self.link.close()

    def before_exchange(self, command: ActuatorCommand) -> None:
        """Called with ``self.n`` already counting this exchange."""

    def exchange(self, command: ActuatorCommand) -> RigSample:
        self.n += 1
        self.before_exchange(command)
        return self.link.exchange(command)


def cmd(k: int, v1: float = 100.0, v2: float = -100.0) -> ActuatorCommand:
    """A board command for tick ``k`` (±100 V differential, 2 mA board current)."""
    return ActuatorCommand(seq=k, v_ch1=v1, v_ch2=v2, board_current=0.002)


def first_reply(link, seqs: range) -> RigSample | None:
    """Exchange ``cmd(k)`` for k in ``seqs`` until one is answered (``LinkError`` skipped): that sample, or ``None``.
    Bounded by ``seqs`` (a reopen back-off is at most 64 exchange calls)."""
    from drivers.link import LinkError

    for k in seqs:
        try:
            return link.exchange(cmd(k))
        except LinkError:
            pass
    return None


def exchange_errors(link, seqs: range) -> list[str]:
    """Exchange ``cmd(k)`` for every k in ``seqs``; the messages of the exchanges that raised ``LinkError``."""
    from drivers.link import LinkError

    errors = []
    for k in seqs:
        try:
            link.exchange(cmd(k))
        except LinkError as exc:
            errors.append(str(exc))
    return errors


def wait_for(predicate: Callable[[], bool], timeout: float = 5.0, interval: float = 0.005) -> bool:
    """Poll until ``predicate()`` or ``timeout`` seconds (bounded)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if predicate():
            return True
        time.sleep(interval)
    return bool(predicate())


def missing_tools(*names: str) -> str | None:
    """The reason to skip when a Debian tool is missing (``make setup`` installs mbpoll and socat)."""
    missing = [n for n in names if shutil.which(n) is None]
    if missing:
        return (f"{', '.join(missing)} not installed (make setup installs them: apt-get install -y mbpoll socat); "
                "this third-party-client test cannot run")
    return None


def exchange_through_outage(link, make_command: Callable[[int], ActuatorCommand], budget_s: float = 10.0,
                            max_exchanges: int = 5000, pause_s: float = 0.002) -> list[bool]:
    """Exchange on ``link`` until a failed exchange has been followed by a good one (or the budget runs out).

    Returns one outcome per exchange (True = reply received). Bounded in count and time.
    """
    from drivers.link import LinkError

    outcomes: list[bool] = []
    end = time.monotonic() + budget_s
    for k in range(1, max_exchanges):
        try:
            link.exchange(make_command(k))
            outcomes.append(True)
        except LinkError:
            outcomes.append(False)
        if (False in outcomes and outcomes[-1]) or time.monotonic() > end:
            break
        time.sleep(pause_s)
    return outcomes


def _add_endpoint(hil: HilService, endpoint: str) -> Any:
    return hil.add_modbus_tcp("127.0.0.1:0") if endpoint == "modbus-tcp" else hil.add_serial("pty")


def lockstep_stub(endpoint: str) -> Iterator[tuple[HilService, Any, FakeRig]]:
    """A lock-step stub around a :class:`FakeRig` with one ``endpoint`` (``"modbus-tcp"`` or ``"serial"`` on a
    pty), for a fixture to ``yield from``: the service, the endpoint, the rig."""
    rig = FakeRig()
    with HilService(rig, mode="lockstep") as hil:
        yield hil, _add_endpoint(hil, endpoint), rig


def outcomes_through_injected_outage(endpoint: str, query: str) -> tuple[list[bool], dict[str, int]]:
    """A lock-step stub whose ``endpoint`` (``"modbus-tcp"`` or ``"serial"``) drops the link from 0.1 s to 0.4 s of
    rig time, and the board's link (the endpoint's URL + ``query``) exchanging through it: the outcomes
    (:func:`exchange_through_outage`) and the endpoint's counters."""
    plan = FaultPlan(link=LinkFaults(disconnect_at_s=0.1, disconnect_for_s=0.3))
    with HilService(FakeRig(), mode="lockstep", plan=plan) as hil:
        srv = _add_endpoint(hil, endpoint)
        link = open_link(srv.board_url + query)
        link.open()
        try:
            outcomes = exchange_through_outage(link, cmd)
        finally:
            link.close()
    return outcomes, srv.stats


def link_url_printed_by(proc: subprocess.Popen, lines: int) -> str:
    """The ``--link`` URL a started ``shm hil serve`` prints on stdout (read up to ``lines`` lines); when there is
    none, the stub is killed and the test fails."""
    assert proc.stdout is not None
    for _ in range(lines):
        line = proc.stdout.readline()
        if "board: --link " in line:
            return line.split("board: --link ", 1)[1].strip()
    proc.kill()
    raise AssertionError("the stub printed no --link URL")


def rtu_crc(frame: bytes) -> bytes:
    """The Modbus RTU CRC-16 of ``frame`` (polynomial 0xA001, little-endian), computed here bit by bit so that the
    tests check the stub's frames against a CRC of their own."""
    crc = 0xFFFF
    for b in frame:
        crc ^= b
        for _ in range(8):
            crc = (crc >> 1) ^ 0xA001 if crc & 1 else crc >> 1
    return struct.pack("<H", crc)


def maintenance_scenario(name: str, description: str, maintenance_s: float, *, verdict: str = "PASS",
                         rig: str = "", board: str = "", parked_after_s: float = 0.5) -> str:
    """A scenario file's text: a parked second, one maintenance visit of ``maintenance_s`` s, the HV removed for
    ``parked_after_s`` s. ``rig`` adds lines to ``[rig]``; ``board`` adds ``[board.*]`` tables (text, ending in a
    blank line)."""
    phases = "\n".join(f'[[phase]]\nname = "{n}"\nkind = "{k}"\nduration = {{ value = {s:g}, unit = "s" }}\n'
                       for n, k, s in (("parked", "ground", 1), ("maintenance", "maintenance", maintenance_s),
                                       ("disconnected", "ground", parked_after_s)))
    return (f'\n[scenario]\nname = "{name}"\ndescription = "{description}"\nseed = 1\nexpect_verdict = "{verdict}"\n'
            f'\n[rig]\nparams = "table2"\nbattery_initial_voltage = {{ value = 3.0, unit = "V" }}\n{rig}\n{board}'
            f"{phases}")


#: a parked second, one maintenance visit (MBIT.a, MBIT.b, verdict) of 28 s and the HV removed: the shortest scenario
#: whose board run ends with a clean PASS verdict (tests that run `shm hil serve` and `shm run --link` as processes)
SHORT_MAINTENANCE_SCENARIO = maintenance_scenario(
    "maintenance-short", "A parked second, a maintenance visit (MBIT.a, MBIT.b, verdict), HV removed.", 28)
