"""The in-process link: the board talks to a rig object in the same process, in virtual time.

Each :meth:`InProcessLink.exchange` applies the board's command, advances the rig by one tick and returns the
rig's sample — so rig time moves exactly one tick per exchange, however fast the host runs (deterministic,
"as fast as the machine allows"), and with a wall-clock scheduler in front it runs in real time.

A rig may schedule link outages (``rig.link_down()`` true): the exchange then still lets rig time pass (the command
is *not* delivered; the rig's own watchdog handles that) and raises :class:`~drivers.link.LinkError`, exactly as a
serial or Modbus link would on a timeout. ``fail_next(n)`` injects ``n`` failures from a test.

URL: ``"sim"`` (or ``"sim:NAME"``, ``"sim://?scenario=NAME&seed=S&params=P"``), opened with :func:`drivers.open_link`
like any other; what the URL leaves out comes from the caller's defaults (``open_link("sim", scenario=...,
seed=..., params=..., tick=...)``: ``shm run`` passes its own) and otherwise from the rig. ``drivers`` cannot build
a rig itself (rigs live in ``hil_stub``, which imports drivers, not the other way round): importing ``hil_stub.rig``
registers the rig factory with :func:`set_sim_rig_factory`; :func:`drivers.open_link` then works for ``sim`` URLs.
"""

from __future__ import annotations

from collections.abc import Callable

from board_config.errors import InputError
from drivers.link import ActuatorCommand, LinkError, RigEndpoint, RigSample, register_link_scheme
from drivers.quiet_span import QuietSpan

#: ``factory(url, **defaults)``: the rig of a ``sim`` URL (``defaults`` as given to :func:`drivers.open_link`)
_RIG_FACTORY: Callable[..., RigEndpoint] | None = None


def set_sim_rig_factory(factory: Callable[..., RigEndpoint] | None) -> None:
    """Register how a ``sim`` URL becomes a rig (``hil_stub.rig`` does this on import)."""
    global _RIG_FACTORY
    _RIG_FACTORY = factory


class InProcessLink:
    """A :class:`drivers.Link` to an in-process :class:`drivers.RigEndpoint`, one rig tick per exchange.

    ``tick`` is the rig time (s) advanced per exchange (the board's 100 Hz tick by default).
    """

    def __init__(self, rig: RigEndpoint, tick: float = 0.01, url: str = "sim") -> None:
        if not tick > 0:
            raise ValueError(f"tick must be positive, got {tick!r}")
        self.rig = rig
        self.tick = float(tick)
        self.url = url
        self._open = False
        self._fail_next = 0
        self.exchanges = 0
        self.failures = 0

    def open(self) -> None:
        self._open = True

    def close(self) -> None:
        self._open = False

    def __enter__(self) -> InProcessLink:
        self.open()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def fail_next(self, n: int = 1) -> None:
        """Make the next ``n`` exchanges fail (rig time still advances), for fault-injection tests."""
        self._fail_next += int(n)

    def exchange(self, command: ActuatorCommand) -> RigSample:
        """Deliver ``command``, advance the rig one tick and return its sample; ``LinkError`` on an outage."""
        if not self._open:
            raise LinkError(f"{self.url}: link is not open")
        self.exchanges += 1
        down = getattr(self.rig, "link_down", None)
        if self._fail_next > 0 or (down is not None and down()):
            if self._fail_next > 0:
                self._fail_next -= 1
            self.rig.advance(self.tick)
            self.failures += 1
            raise LinkError(f"{self.url}: no reply (simulated link outage)")
        self.rig.apply(command)
        self.rig.advance(self.tick)
        return self.rig.sample()

    def peek_quiet(self, command: ActuatorCommand, max_ticks: int) -> QuietSpan | None:
        """The rig's quiet span (:mod:`drivers.quiet_span`) for the next exchanges, if it offers them: never while
        the link is closed, a failure is injected, the rig advances by another step than one tick, or a subclass
        overrides :meth:`exchange` without overriding this too."""
        peek: Callable[[ActuatorCommand, int, float], QuietSpan | None] | None = getattr(self.rig, "peek_quiet", None)
        if peek is None or not self._open or self._fail_next > 0:
            return None
        cls = type(self)
        if cls.exchange is not InProcessLink.exchange and cls.peek_quiet is InProcessLink.peek_quiet:
            return None  # a subclass that changes exchange (a test's fault injector...) sees every tick
        return peek(command, max_ticks, self.tick)

    def commit_quiet(self, span: QuietSpan, m: int) -> None:
        """``m`` exchanges of the span's command, at once."""
        self.rig.commit_quiet(span, m)  # type: ignore[attr-defined]
        self.exchanges += m


def _open_sim(url: str, **defaults: object) -> InProcessLink:
    if _RIG_FACTORY is None:
        raise InputError(f"link URL {url!r}: no simulated rig available (import hil_stub.rig, which registers it)")
    rig = _RIG_FACTORY(url, **defaults) if defaults else _RIG_FACTORY(url)
    tick = defaults.get("tick", 0.01)
    if not isinstance(tick, int | float):
        raise InputError(f"link URL {url!r}: the tick must be a number of seconds, got {tick!r}")
    return InProcessLink(rig, tick=float(tick), url=url)


register_link_scheme("sim", _open_sim)
