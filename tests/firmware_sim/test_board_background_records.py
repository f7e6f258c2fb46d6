"""A paced run writes its visit records beside its ticks (issue 29, point 4): the tick that ends an MBIT hands the
record to a thread and goes on (writing it took 15-40 ms on a loaded machine: missed deadlines in a row and SAFE
for an overrun); the records are written in order, every one before close() returns; a failing record is named
and the rest are still written."""

from __future__ import annotations

import sys
import time
from types import SimpleNamespace

import pytest

from studies.board_run.background_records import BackgroundRecorder


class SlowWriter:
    def __init__(self) -> None:
        self.seen: list[str] = []
        self.closed = False

    def __call__(self, ev) -> None:
        time.sleep(0.03)
        if ev.data.get("bad"):
            raise ValueError("value nan is not finite")
        self.seen.append(f"{ev.kind}:{ev.data['mbit']}")

    def close(self) -> None:
        self.closed = True


def _ev(kind: str, mbit: str, **data):
    return SimpleNamespace(kind=kind, data={"mbit": mbit, **data})


def test_records_are_written_beside_the_ticks_in_order_and_all_before_close():
    writer = SlowWriter()
    before = sys.getswitchinterval()
    rec = BackgroundRecorder(lambda: writer)
    assert sys.getswitchinterval() <= 5e-4
    t0 = time.perf_counter()
    for ev in (_ev("mbit_start", "a"), _ev("telemetry", "a"), _ev("mbit_record", "a"), _ev("mbit_result", "a"),
               _ev("mbit_record", "b", bad=True), _ev("mbit_result", "b")):
        rec(ev)
    assert time.perf_counter() - t0 < 0.02  # the ticks did not wait for 5 x 30 ms of writing
    rec.close()
    assert writer.seen == ["mbit_start:a", "mbit_record:a", "mbit_result:a", "mbit_result:b"] and writer.closed
    assert rec.failure == "ValueError: value nan is not finite"
    assert sys.getswitchinterval() == before


def test_a_writer_that_cannot_be_built_is_an_error_at_once():
    def broken():
        raise OSError("records/: read-only file system")

    with pytest.raises(OSError, match="read-only"):
        BackgroundRecorder(broken)
