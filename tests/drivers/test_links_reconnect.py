"""The reconnecting link base (drivers.reconnecting_link) on a fake transport: back-off in exchange calls, statistics,
timeouts in a row, rate-limited incident log — what SerialLink and ModbusLink share."""

from __future__ import annotations

import itertools
import logging

import pytest

from drivers.link import LinkError
from drivers.reconnecting_link import MAX_BACKOFF_CALLS, ReconnectingLink


class FakeTransportLink(ReconnectingLink):
    """A link whose transport opens while ``available`` and whose exchange answers while ``answering``."""

    verb = "reconnect"
    reconnected_note = "reconnected"

    def __init__(self) -> None:
        super().__init__("fake://x", logging.getLogger("tests.fake_link"), timeout=0.01, reopen_after=3)
        self.up = False
        self.available = True
        self.answering = True
        self.opens = 0
        self.checks_due = 0

    @property
    def is_open(self) -> bool:
        return self.up

    def _open_transport(self) -> None:
        self.opens += 1
        if not self.available:
            raise LinkError(f"{self.url}: cannot connect")
        self.up = True

    def _drop_transport(self) -> None:
        self.up = False

    def _after_reconnect(self) -> None:
        self.checks_due += 1

    def open(self) -> None:
        self._bring_up()

    def close(self) -> None:
        self.up = False

    def exchange(self) -> bool:
        self._ensure_up()
        if not self.answering:
            raise self._timed_out("no reply")
        self._timeouts_in_row = 0
        return True


def test_backoff_doubles_up_to_the_cap_and_resets_on_reconnect():
    link = FakeTransportLink()
    with link:
        raise_lost = link._link_down("read failed: EIO")
        assert "read failed" in str(raise_lost) and not link.is_open
        link.available = False
        attempts = [link.opens]  # open attempts so far, after each exchange call
        for _ in range(400):
            with pytest.raises(LinkError):
                link.exchange()
            attempts.append(link.opens)
        opened_at = [k for k in range(1, len(attempts)) if attempts[k] > attempts[k - 1]]
        gaps = [b - a for a, b in itertools.pairwise(opened_at)]
        assert gaps[:7] == [2, 4, 8, 16, 32, 64, 64]  # 1, 2, 4 ... exchange calls between attempts, capped
        assert max(gaps) == MAX_BACKOFF_CALLS
        assert link.stats["reconnect_failed"] == len(opened_at) and link.stats["down_exchanges"] > 300
        link.available = True
        while not link.is_open:
            try:
                link.exchange()
            except LinkError:
                pass
        assert link.stats["reconnected"] == 1 and link.checks_due == 1 and link._backoff == 1


def test_timeouts_in_a_row_count_as_a_lost_transport(caplog):
    link = FakeTransportLink()
    link.open()
    link.answering = False
    with caplog.at_level(logging.WARNING, logger="tests.fake_link"):
        for _ in range(2):
            with pytest.raises(LinkError, match="fake://x: no reply"):
                link.exchange()
        assert link.is_open
        with pytest.raises(LinkError, match="3 timeouts in a row"):
            link.exchange()
    assert not link.is_open and link.stats["timeouts"] == 3 and link.stats["link_down"] == 1
    assert "link down (3 timeouts in a row); reconnecting with back-off" in caplog.text
    with pytest.raises(LinkError, match="fake://x: no reply"):
        link.exchange()  # the first call after a loss reconnects at once (back-off 1), then times out again
    assert link.stats["reconnected"] == 1 and link.checks_due == 1


def test_start_up_checks_are_silent(caplog):
    link = FakeTransportLink()
    link.open()
    link.answering = False
    with caplog.at_level(logging.WARNING, logger="tests.fake_link"), link._silenced():
        with pytest.raises(LinkError):
            link.exchange()
    assert caplog.text == "" and link.stats["timeouts"] == 1



def test_realtime_service_hands_the_gil_over_often_and_restores_it():
    """A real-time HIL service shares the interpreter with its servers and (in tests) the board: while it
    runs, the GIL switch interval is at most SWITCH_INTERVAL_S; afterwards it is what it was."""
    import sys

    from links_support import FakeRig

    from hil_stub.service import SWITCH_INTERVAL_S, HilService

    before = sys.getswitchinterval()
    sys.setswitchinterval(0.005)
    try:
        with HilService(FakeRig(), mode="realtime"):
            assert sys.getswitchinterval() <= SWITCH_INTERVAL_S + 1e-9
        assert sys.getswitchinterval() == pytest.approx(0.005)
        with HilService(FakeRig(), mode="lockstep"):
            assert sys.getswitchinterval() == pytest.approx(0.005)
    finally:
        sys.setswitchinterval(before)
