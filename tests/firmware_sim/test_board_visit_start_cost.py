"""A maintenance visit's first tick does no model run (issue 29, point 4): the nominal reference of the planned MBIT
sequence is the same for every visit, so it is computed once — before the first tick of a paced run — and kept.
Computed in the tick that starts the visit it took tens of ms on a loaded machine: five missed deadlines in a row,
SAFE for an overrun, and a visit that never completed, with the stub and the board as two ordinary processes."""

from __future__ import annotations

import pytest

from board_config.board import load_board_config
from drivers.sim_link import InProcessLink
from firmware_sim.board import Board
from firmware_sim.runner import BoardRunner
from firmware_sim.scheduler import Scheduler, WallClock
from hil_stub.rig import SimulatedRig


@pytest.fixture(scope="module")
def board():
    return Board(load_board_config(None), nominal="table2")


def test_a_paced_run_prepares_the_reference_before_its_first_tick(board, monkeypatch):
    cfg = board.cfg
    BoardRunner(board, InProcessLink(SimulatedRig()), scheduler=Scheduler(cfg.tick_rate, WallClock()))
    reference = board.maintenance.prepare()

    def no_model_run():
        raise AssertionError("a visit's start ran the nominal model")

    monkeypatch.setattr(board.maintenance, "_reference", no_model_run)
    for visit_tick in (100, 5000):  # every visit: the same reference, nothing computed
        board.maintenance.start(visit_tick)
        assert board.maintenance._ref is reference and len(reference) > 1000
        board.maintenance.finish()
