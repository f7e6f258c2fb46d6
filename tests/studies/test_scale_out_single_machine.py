"""Issue 31's "nothing in the single-machine commands gets slower" (bench/bench_single_machine.py): the command as
a user runs it against its single-machine body called directly, interleaved, the ratio of the medians; the direct
body is the same analysis (same diagnosis.json apart from timings)."""

from __future__ import annotations

import json

import pytest

import bench.bench_single_machine as bsm


def test_compare_interleaves_the_command_and_the_direct_body_and_takes_the_median_ratio(monkeypatch):
    calls = []
    walls = {"command": iter([9.0, 2.0, 2.2, 2.4, 50.0]), "direct": iter([1.0, 1.1, 1.2, 0.1])}

    def fake_timed(kind, argv):
        calls.append(kind)
        return next(walls[kind])

    monkeypatch.setattr(bsm, "_timed", fake_timed)
    got = bsm.compare(["diagnose", "x.csv"], 4)
    # the first command run fills the caches and is not counted; then A B, B A, A B, B A
    assert calls == ["command", "command", "direct", "direct", "command", "command", "direct", "direct", "command"]
    assert got["command_s"] == pytest.approx((2.2 + 2.4) / 2)
    assert got["direct_s"] == pytest.approx((1.0 + 1.1) / 2)
    assert got["ratio"] == pytest.approx(2.3 / 1.05)


TIMINGS = {"wall_s", "load_s", "integrator_s", "timings_s"}


def _timeless(x, out):
    """The document without its timings and with --out's path cut from the figure paths."""
    if isinstance(x, dict):
        return {k: _timeless(v, out) for k, v in x.items() if k not in TIMINGS}
    if isinstance(x, list):
        return [_timeless(v, out) for v in x]
    return x.replace(str(out), "OUT") if isinstance(x, str) else x


def _doc(out):
    return _timeless(json.loads((out / "diagnosis.json").read_text()), out)


@pytest.mark.slow
def test_the_direct_diagnose_is_the_command_without_the_batch_layer(tmp_path):
    bsm._records(tmp_path / "recs", 1)
    rec = str(tmp_path / "recs" / "rec000.csv")
    assert bsm._timed("command", ["diagnose", rec, *bsm.CANDIDATES, "--out", str(tmp_path / "a")]) > 0
    assert bsm._timed("direct", ["diagnose", rec, *bsm.CANDIDATES, "--out", str(tmp_path / "b")]) > 0
    assert _doc(tmp_path / "a") == _doc(tmp_path / "b")
