"""Start-up and slow rigs (issue 12, points 1 and 5): a peer that stays silent at open is one error naming what was
tried, with no warning per attempt before it; a Modbus rig slower than its processing budget is reported as such
and its exchanges never run past the link's budget (the board's tick does not collapse)."""

from __future__ import annotations

import logging
import os
import tty

import pytest
from links_support import FakeRig, exchange_errors

from drivers import LinkError, open_link
from hil_stub.faults import FaultPlan, LinkFaults
from hil_stub.service import HilService

pytestmark = pytest.mark.integration


def test_a_silent_serial_peer_at_start_up_is_one_clear_error(caplog):
    master, slave = os.openpty()  # nobody answers on the other side
    tty.setraw(master)
    tty.setraw(slave)
    try:
        link = open_link(f"serial:{os.ttyname(slave)}")
        with caplog.at_level(logging.WARNING), pytest.raises(LinkError) as err:
            link.open()
    finally:
        os.close(master)
        os.close(slave)
    text = str(err.value)
    assert "does not answer PING at start-up" in text and "5 attempts" in text and "115200 baud" in text
    assert not [r for r in caplog.records if r.name.startswith("drivers.")], "warnings printed before the error"


def test_a_modbus_rig_slower_than_its_budget_is_reported_and_bounded():
    plan = FaultPlan(link=LinkFaults(processing_s=0.0045), seed=1)  # 4.5 ms per transaction: 9 ms per exchange
    with HilService(FakeRig(), mode="realtime", plan=plan) as hil:
        srv = hil.add_modbus_tcp("127.0.0.1:0")
        link = open_link(srv.board_url + "&fc23=0")  # two transactions per tick (FC 16 + FC 04)
        link.open()  # the start-up reads have their own budget: a slow rig still connects
        try:
            errors = exchange_errors(link, range(1, 31))
        finally:
            link.close()
    assert len(errors) >= 25, "two 4.5 ms transactions do not fit the 8 ms exchange budget"
    assert link.stats["slow_replies"] >= 1  # slow transactions are reported against the budget (logged)
    assert any("exchange budget" in e for e in errors)
    # the message says what the write took of the budget, not a bare leftover
    assert all("no valid reply within 8.0 ms" in e or "the command write took" in e or "no time left" in e
               or "unexpected reply" in e for e in errors), errors[:3]
