"""The ``Link`` seam between the board firmware and a rig (simulated in-process, a HIL stub across a serial
port or Modbus, or the real CompactRIO + high-voltage amplifier).

One call per firmware tick: the board sends its :class:`ActuatorCommand` and gets back the rig's latest
:class:`RigSample`. A link never reads a clock to decide *what* to do; timeouts are its only use of time.
Every failure to exchange is a :class:`LinkError` (the board goes SAFE on it).

Implementations are chosen by URL through :func:`open_link`; registering a new one is one new module plus
one :func:`register_link_scheme` call.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

from board_config.errors import InputError


class LinkError(IOError):
    """The link could not complete an exchange (timeout, lost port, corrupt reply, refused command)."""


@dataclass(frozen=True)
class ActuatorCommand:
    """What the board asks of the rig for one tick (SI units).

    ``v_ch1``/``v_ch2``: high-voltage amplifier channel demands (V), already inside Table 1 limits.
    ``board_current``: current the board electronics draw from the battery in this tick (A).
    ``seq``: the board's tick counter (wraps at 2**32).
    """

    seq: int
    v_ch1: float = 0.0
    v_ch2: float = 0.0
    board_current: float = 0.0


@dataclass(frozen=True)
class RigSample:
    """What the rig reports for one tick (SI units).

    ``seq``: the rig's sample counter (a frozen value means a stale sensor path).
    ``t``: rig time (s). ``z3``: laser tip displacement (m). ``v_patch``: patch terminal voltage (V).
    ``z0dd``: base acceleration (m/s^2). ``v_battery``: board battery terminal voltage (V).
    ``hv_present``: external high-voltage equipment connected (maintenance).
    ``flags``: bit field of rig-side conditions (bit 0 sensor fault, bit 1 limit refused, bit 2 rig fault).
    """

    seq: int
    t: float
    z3: float
    v_patch: float
    z0dd: float
    v_battery: float
    hv_present: bool = False
    flags: int = 0


FLAG_SENSOR_FAULT = 1
FLAG_LIMIT_REFUSED = 2
FLAG_RIG_FAULT = 4


@runtime_checkable
class Link(Protocol):
    """A connection to a rig. ``exchange`` is called once per tick."""

    url: str

    def open(self) -> None: ...

    def close(self) -> None: ...

    def exchange(self, command: ActuatorCommand) -> RigSample: ...


@runtime_checkable
class RigEndpoint(Protocol):
    """The rig side, as a link server or the in-process link sees it (implemented by ``hil_stub``).

    ``apply`` takes the latest board command (the rig validates it and refuses out-of-limit demands,
    keeping its last safe output); ``advance`` moves rig time forward by ``dt`` seconds (the caller owns the
    clock: virtual time in-process, wall-clock pacing in the HIL server); ``sample`` returns the latest
    snapshot without advancing anything.
    """

    def apply(self, command: ActuatorCommand) -> None: ...

    def advance(self, dt: float) -> None: ...

    def sample(self) -> RigSample: ...


#: ``factory(url, **defaults)``: the link for ``url``; ``defaults`` (see :func:`open_link`) it has no use for it ignores
LinkFactory = Callable[..., Link]
_SCHEMES: dict[str, LinkFactory] = {}


def register_link_scheme(scheme: str, factory: LinkFactory) -> None:
    """Make ``open_link`` build ``factory(url, **defaults)`` for URLs starting with ``scheme`` (e.g.
    ``"modbus-tcp://"``)."""
    _SCHEMES[scheme] = factory


def registered_schemes() -> list[str]:
    return sorted(_SCHEMES)


def open_link(url: str, **defaults: object) -> Link:
    """The link for ``url`` (longest registered scheme prefix wins). Raises ``InputError`` on an unknown URL.

    ``defaults``: what the caller knows for the settings ``url`` leaves out — ``tick`` (s, the board's tick) and, for
    a simulated rig, the caller's ``scenario``, ``seed`` and ``params`` (``shm run`` passes its own, so ``sim`` is
    the run's rig). A link ignores the defaults it has no use for; ``None`` values count as not given.
    """
    given = {key: value for key, value in defaults.items() if value is not None}
    for scheme in sorted(_SCHEMES, key=len, reverse=True):
        # a bare name ('sim') is a scheme only as a whole word: 'sim', 'sim:...', 'sim?...' (not 'simfoo')
        if url.startswith(scheme) and (scheme.endswith(":") or scheme.endswith("/")
                                       or url[len(scheme):len(scheme) + 1] in ("", ":", "?")):
            return _SCHEMES[scheme](url, **given)
    raise InputError(f"unknown link URL '{url}' (known schemes: {', '.join(registered_schemes()) or 'none'})")
