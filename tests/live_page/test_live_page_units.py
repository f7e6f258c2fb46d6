"""The live page's pieces without a browser (issue 32): the address option, the messages, the server's routes and
stream, the board feed over a virtual-time run, the safety defaults."""

from __future__ import annotations

import argparse
import asyncio
import gzip
import io
import json
import math
import urllib.error
import urllib.request
from pathlib import Path

import pytest
from tornado.httpclient import HTTPClientError, HTTPRequest
from tornado.websocket import websocket_connect

from live_page.messages import encode, last_indices
from live_page.server import LiveServer
from live_page.session import LiveSession, is_loopback, live_address
from live_page.snapshot import Chunk, Snapshot, SnapshotSlot, bounded


def test_the_address_is_port_or_host_and_port_loopback_by_default() -> None:
    assert live_address("8765") == ("127.0.0.1", 8765)
    assert live_address("0.0.0.0:80") == ("0.0.0.0", 80)
    assert live_address("[::1]:9000") == ("::1", 9000)
    assert live_address("0") == ("127.0.0.1", 0)
    for bad in ("abc", "70000", ":80", "host:", "-1"):
        with pytest.raises(argparse.ArgumentTypeError, match=r"PORT|host"):
            live_address(bad)
    assert is_loopback("127.0.0.1") and is_loopback("::1") and is_loopback("localhost")
    assert not is_loopback("0.0.0.0") and not is_loopback("192.0.2.7") and not is_loopback("rig-pc")


def _chunk(i: int, rows: int = 0) -> Chunk:
    t = tuple(i + 0.01 * k for k in range(rows))
    return Chunk(i, float(i), 3.0, 0.9, i, 1e-4, 1 if rows else 0, t, tuple(math.nan for _ in t), t, t)


def test_a_message_holds_only_what_the_page_lacks_and_is_strict_json() -> None:
    snap = Snapshot(version=3, chunks=tuple(_chunk(i, rows=2) for i in range(3)),
                    events=((0, "a"), (1, "b"), (2, "c")), v_battery_V=math.nan, mbit_id=1)
    first = json.loads(encode(snap, full=True))
    assert first["full"] and [c["i"] for c in first["chunks"]] == [0, 1, 2] and len(first["events"]) == 3
    assert first["v_battery_V"] is None and first["chunks"][0]["z3_meas_m"] == [None, None]
    later = json.loads(encode(snap, 1, 1))
    assert not later["full"] and [c["i"] for c in later["chunks"]] == [2] and later["events"] == [[2, "c"]]
    assert last_indices(snap) == (2, 2) and last_indices(Snapshot()) == (-1, -1)
    # the rows of an earlier MBIT are left out (a page shows the current one), its slow points are not
    older = json.loads(encode(Snapshot(chunks=(_chunk(0, rows=2),), mbit_id=2), full=True))["chunks"][0]
    assert "eps" not in older and older["v_battery_V"] == 3.0
    assert bounded((1, 2, 3), (4, 5), 3) == (3, 4, 5) and bounded((1,), (), 3) == (1,)


def _get(url: str, **headers: str) -> tuple[int, bytes, dict]:
    try:
        with urllib.request.urlopen(urllib.request.Request(url, headers=headers), timeout=10) as r:
            return r.status, r.read(), dict(r.headers)
    except urllib.error.HTTPError as exc:
        return exc.code, b"", {}


def test_the_server_streams_changes_serves_offline_assets_and_changes_nothing(tmp_path: Path) -> None:
    slot = SnapshotSlot(Snapshot(version=1, chunks=(_chunk(0),)))
    report = tmp_path / "report.html"
    server = LiveServer(slot, port=0, report=lambda: report if report.exists() else None)
    server.start()
    try:
        status, page, _ = _get(server.url)
        assert status == 200 and b'src="/plotly.min.js"' in page and b"http" not in page.split(b"<body>")[0]
        status, js, headers = _get(server.url + "plotly.min.js", **{"Accept-Encoding": "gzip"})
        assert status == 200 and headers["Content-Encoding"] == "gzip" and b"plotly" in gzip.decompress(js)[:2000]
        assert _get(server.url + "report")[0] == 404
        report.write_text("<html>the report</html>")
        assert _get(server.url + "report")[1] == b"<html>the report</html>"
        req = urllib.request.Request(server.url, data=b"x", method="POST")
        with pytest.raises(urllib.error.HTTPError, match="405"):
            urllib.request.urlopen(req, timeout=10)

        async def stream() -> tuple[dict, dict]:
            ws = await websocket_connect(server.url.replace("http", "ws") + "ws")
            first = json.loads(await ws.read_message())
            await ws.write_message('{"command": "rearm"}')  # ignored: read-only
            slot.publish(Snapshot(version=2, chunks=(_chunk(0), _chunk(1)), events=((0, "x"),)))
            second = json.loads(await asyncio.wait_for(ws.read_message(), 5.0))
            ws.close()
            with pytest.raises(HTTPClientError, match="403"):  # another origin cannot read the stream
                await websocket_connect(HTTPRequest(server.url.replace("http", "ws") + "ws",
                                                    headers={"Origin": "http://elsewhere.example"}))
            return first, second

        first, second = asyncio.run(stream())
        assert first["full"] and first["version"] == 1 and [c["i"] for c in first["chunks"]] == [0]
        assert not second["full"] and second["version"] == 2 and [c["i"] for c in second["chunks"]] == [1]
        assert second["events"] == [[0, "x"]]
        assert json.loads(_get(server.url + "state.json")[1])["version"] == 2
    finally:
        server.stop()


def test_a_non_loopback_address_is_warned_about(monkeypatch: pytest.MonkeyPatch) -> None:
    out = io.StringIO()
    session = LiveSession(("0.0.0.0", 8765), stream=out)
    monkeypatch.setattr(session.server, "start", lambda: None)  # no socket on every interface in a test
    session.start()
    assert "WARNING: serving on 0.0.0.0, not on loopback" in out.getvalue()
    quiet = io.StringIO()
    session = LiveSession(("127.0.0.1", 8765), stream=quiet)
    monkeypatch.setattr(session.server, "start", lambda: None)
    session.start()
    assert "WARNING" not in quiet.getvalue() and "ssh -L 8765:127.0.0.1:8765" in quiet.getvalue()


@pytest.mark.slow
def test_the_board_feed_publishes_what_the_board_did(tmp_path: Path) -> None:
    """A virtual-time maintenance visit through the publishing scheduler: the last snapshot's regime changes,
    verdicts, MBIT rows and ε are the board's (ε by the monitor's own Eq. 11)."""
    from board_config.board import load_board_config
    from board_config.scenario import load_scenario
    from drivers.link import open_link
    from firmware_sim.board import Board
    from firmware_sim.runner import BoardRunner
    from firmware_sim.scheduler import Scheduler
    from hil_stub.rig import SimulatedRig  # registers the simulated rig behind the 'sim' URL
    from live_page.board_feed import BoardFeed, PublishingScheduler, TimedLink

    scenario = load_scenario("degraded")
    cfg = load_board_config(overrides=scenario.board_overrides, overrides_source=scenario.source)
    board = Board(cfg, nominal=scenario.rig.params)
    link = TimedLink(open_link("sim", scenario=scenario, tick=cfg.tick_period))
    assert isinstance(link._inner.rig, SimulatedRig)
    slot = SnapshotSlot()
    wall = iter(range(10**9))  # a clock that advances 10 ms a call: a publication every 5th tick at 20 Hz
    feed = BoardFeed(slot, board, title="t", planned_s=scenario.duration, paced=False, link=link,
                     clock=lambda: 0.01 * next(wall))
    runner = BoardRunner(board, link, scheduler=PublishingScheduler(Scheduler(cfg.tick_rate), feed),
                         on_event=feed.on_event)
    link.open()
    result = runner.run(scenario.duration)
    snap = feed.finish("finished", None)
    changes = [e for e in result.events if e.kind == "regime_change"]
    assert snap.regimes[1:] == tuple((e.time, e.data["to_regime"]) for e in changes)
    assert snap.regime == board.regime.value and snap.finished and snap.link.exchanges == result.ticks
    mbits = [e.data for e in result.events if e.kind == "mbit_result"]
    assert snap.verdicts[:len(mbits)] == tuple(f"{d['label']} {d['verdict']}" for d in mbits)
    assert snap.mbit_max_eps == pytest.approx(mbits[-1]["max_eps"])
    rows = [c for c in snap.chunks if c.mbit_id == snap.mbit_id and c.mbit_t_s]
    eps = [e for c in rows for e in c.eps]
    assert len(eps) >= mbits[-1]["n_samples"] - 2 and max(eps) == pytest.approx(mbits[-1]["max_eps"])
    assert link.timed > 0 and link.rtt_percentiles()[1] is not None


@pytest.mark.integration
def test_a_port_in_use_is_refused_before_an_earlier_run_is_touched(tmp_path: Path) -> None:
    import socket
    import subprocess
    import sys

    out = tmp_path / "run"
    out.mkdir()
    (out / "summary.json").write_text('{"scenario": "earlier", "ticks": 1}')
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        r = subprocess.run([sys.executable, "-m", "shm_cli.main", "run", "--scenario", "maintenance", "--quiet",
                            "--force", "--live", f"127.0.0.1:{port}", "--out", str(out)],
                           capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and f"--live 127.0.0.1:{port}: cannot serve the live page there" in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and "Traceback" not in r.stderr
    assert (out / "summary.json").read_text() == '{"scenario": "earlier", "ticks": 1}'


@pytest.mark.integration
def test_the_rig_page_follows_the_rig() -> None:
    """``shm hil serve --live``: the page's state is the rig's (rig time moving, its cell, HV, no board regime)."""
    import re
    import subprocess
    import sys
    import time

    proc = subprocess.Popen([sys.executable, "-m", "shm_cli.main", "hil", "serve", "--scenario", "maintenance",
                             "--modbus-tcp", "127.0.0.1:0", "--start", "now", "--duration", "4", "--status-every",
                             "0", "--live", "0", "--live-linger", "0"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        url = None
        assert proc.stderr is not None
        for line in proc.stderr:
            m = re.search(r"live page: (http://\S+/)", line)
            if m:
                url = m.group(1)
                break
        assert url is not None
        first = json.loads(_get(url + "state.json")[1])
        while first["status"] == "starting":  # the page is up a moment before the rig is attached
            time.sleep(0.05)
            first = json.loads(_get(url + "state.json")[1])
        time.sleep(1.0)
        second = json.loads(_get(url + "state.json")[1])
        assert first["source"] == second["source"] == "rig" and second["regime"] is None
        assert second["board_time_s"] > first["board_time_s"] + 0.5  # rig time, running from --start now
        assert 2.9 < second["v_battery_V"] < 3.1 and 0.0 < second["soc"] <= 1.0
        assert dict(second["extra"])["HV equipment"] in ("present", "absent")
        assert second["link"]["exchanges"] == 0 and not second["finished"]
        assert proc.wait(60) == 0
    finally:
        proc.kill()
        proc.wait(10)


def test_the_state_of_charge_table_is_the_cells_curve() -> None:
    from board_config.battery import load_battery
    from live_page.soc import SocEstimate

    cell = load_battery()
    est = SocEstimate(cell)
    lo, hi = cell.voltage_range
    for v in (lo, 2.5, 2.9, 2.95, 3.0, hi):
        exact = 1.0 - float(cell.discharged_capacity(v)) / cell.capacity
        assert est.soc(v) == pytest.approx(exact, abs=2e-3)
    assert est.soc(hi + 1.0) == pytest.approx(est.soc(hi)) and est.soc(math.nan) is None and est.soc(None) is None


def test_a_slow_page_skips_rounds_instead_of_queueing() -> None:
    """A page whose previous message has not left (a slow tunnel) gets nothing new until it has; then it gets
    everything it lacks in one message."""
    from concurrent.futures import Future

    class Page:
        def __init__(self) -> None:
            self.position, self.version, self.pending, self.sent = None, -1, None, []

        def write_message(self, text: str) -> Future:
            self.sent.append(json.loads(text))
            f: Future = Future()
            return f

    slot = SnapshotSlot(Snapshot(version=1, chunks=(_chunk(0),)))
    server = LiveServer(slot)
    page = Page()
    server.pages.add(page)  # type: ignore[arg-type]
    server.push()
    assert [m["version"] for m in page.sent] == [1] and page.sent[0]["full"]
    for v in (2, 3, 4):  # the first write never completes: nothing more is queued
        slot.publish(Snapshot(version=v, chunks=tuple(_chunk(i) for i in range(v))))
        server.push()
    assert len(page.sent) == 1
    page.pending.set_result(None)
    server.push()
    assert [m["version"] for m in page.sent] == [1, 4] and [c["i"] for c in page.sent[1]["chunks"]] == [1, 2, 3]


def test_the_feed_publishes_at_most_20_times_a_second_and_counts_lost_exchanges() -> None:
    from drivers.link import ActuatorCommand, LinkError
    from live_page.board_feed import BoardFeed, TimedLink

    class Flaky:
        def __init__(self) -> None:
            self.n = 0

        def exchange(self, command: ActuatorCommand) -> object:
            self.n += 1
            if self.n % 4 == 0:
                raise LinkError("no reply")
            return object()

    class Monitor:
        settings = type("S", (), {"count_max": 200, "eps_th": 0.2})()
        state = type("St", (), {"fault": False, "max_eps": 0.0, "max_count": 0})()

    class Maintenance:
        monitor, active, monitor_count, current, z3_model = Monitor(), False, 0, "done", math.nan

    class FakeBoard:
        period, maintenance, last_sample, incidents = 0.01, Maintenance(), None, 0
        regime = type("R", (), {"value": "STANDBY_HARVEST"})()

    link = TimedLink(Flaky())
    now = [0.0]
    slot = SnapshotSlot()
    feed = BoardFeed(slot, FakeBoard(), title="t", planned_s=2.0, paced=True, link=link, clock=lambda: now[0])
    for k in range(200):  # 2 s of 100 Hz ticks
        with pytest.raises(LinkError) if (k + 1) % 4 == 0 else _no_error():
            link.exchange(ActuatorCommand(k))
        feed.after_tick(k)
        now[0] += 0.01
    assert 38 <= slot.latest().version <= 41  # 20 per second (the first snapshot is version 0)
    snap = feed.finish("finished", None)  # the last state, whenever the run ends
    assert snap.finished and snap.link.exchanges == 200 and snap.link.misses == 50
    assert snap.link.rtt_p50_s is not None and snap.link.rtt_p99_s is not None


class _no_error:
    def __enter__(self) -> None:
        return None

    def __exit__(self, *exc: object) -> bool:
        return False


def test_a_failing_feed_stops_the_page_never_the_board() -> None:
    from live_page.board_feed import BoardFeed

    class Monitor:
        settings = type("S", (), {"count_max": 200, "eps_th": 0.2})()

    class Maintenance:
        monitor = Monitor()

        @property
        def active(self) -> bool:
            raise RuntimeError("a board the feed does not understand")

    class FakeBoard:
        period, maintenance, last_sample, incidents = 0.01, Maintenance(), None, 0
        regime = type("R", (), {"value": "STANDBY_HARVEST"})()

    slot = SnapshotSlot()
    feed = BoardFeed(slot, FakeBoard(), title="t", planned_s=1.0, paced=True, clock=lambda: 0.0)
    for k in range(3):
        feed.after_tick(k)  # does not raise
    feed.on_event(type("E", (), {"kind": "regime_change", "time": 1.0, "tick": 100, "data": {}})())
    snap = slot.latest()
    assert snap.status == "page stopped" and "a board the feed does not understand" in dict(snap.extra)[
        "live page stopped (the board runs on)"]
    assert feed.finish("finished", "/report").status == "finished"


def test_kept_chunk_texts_give_the_same_messages() -> None:
    from live_page.messages import ChunkTexts

    texts = ChunkTexts()
    first = Snapshot(version=1, chunks=tuple(_chunk(i, rows=2) for i in range(3)), mbit_id=1)
    assert encode(first, full=True, texts=texts) == encode(first, full=True)
    later = Snapshot(version=2, chunks=(*first.chunks[1:], _chunk(3, rows=2)), mbit_id=2)  # a new MBIT
    assert encode(later, full=True, texts=texts) == encode(later, full=True)  # old rows left out, as without
    assert encode(later, 2, -1, texts=texts) == encode(later, 2, -1)
    assert json.loads(encode(later, full=True, texts=texts))["chunks"][0] == json.loads(encode(later, full=True))[
        "chunks"][0]
