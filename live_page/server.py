"""The live page's server: tornado in one background thread, reading only the published snapshot.

Routes (all GET; there is no route that changes anything — the page has no controls):

====================  ===========================================================================================
``/``                  the page (``assets/index.html``)
``/live.js``, ``/live.css``  its script and style (``assets/``)
``/plotly.min.js``     plotly.js from the installed ``plotly`` package (gzip-compressed once at start)
``/ws``                the websocket: a full message on connect, then what changed, one message per publication
``/state.json``        the full message of now (for scripts and ``curl``)
``/report``            the run's ``report.html`` once it is written (404 before)
====================  ===========================================================================================

Every ``1 / stream_hz`` seconds the server reads the slot; if the snapshot is new it encodes one message per distinct
page position (usually one for all pages) and writes it to every page whose previous message has left; a page whose
previous write is still pending (a slow line) skips this round and catches up with the next. Memory per page is
therefore bounded, and the board's thread is never involved. A websocket from another origin is refused (tornado's
default same-origin check), so a foreign web page cannot read the stream through the browser.
"""

from __future__ import annotations

import asyncio
import gzip
import socket
import threading
from collections.abc import Callable
from importlib import resources
from pathlib import Path
from typing import Any

import tornado.httpserver
import tornado.ioloop
import tornado.netutil
import tornado.web
import tornado.websocket

from live_page.messages import ChunkTexts, encode, last_indices
from live_page.snapshot import SnapshotSlot

#: how often the server looks at the slot (Hz): faster than the board publishes (20 Hz), so that every publication
#: reaches the pages (a page gets at most one message per publication; at least 10 per second is the target)
STREAM_HZ = 40.0


def _asset(name: str) -> bytes:
    return resources.files("live_page").joinpath("assets", name).read_bytes()


def _plotly_js() -> bytes:
    import plotly.offline  # the plotly.js bundle of the installed plotly package (no CDN)

    return plotly.offline.get_plotlyjs().encode()


class _Static(tornado.web.RequestHandler):
    def initialize(self, body: bytes, content_type: str, gzipped: bytes | None = None) -> None:
        self._body = body
        self._type = content_type
        self._gzipped = gzipped

    def get(self) -> None:
        self.set_header("Content-Type", self._type)
        self.set_header("Cache-Control", "no-cache" if self._gzipped is None else "max-age=3600")
        if self._gzipped is not None and "gzip" in self.request.headers.get("Accept-Encoding", ""):
            self.set_header("Content-Encoding", "gzip")
            self.finish(self._gzipped)
        else:
            self.finish(self._body)


class _State(tornado.web.RequestHandler):
    def initialize(self, slot: SnapshotSlot) -> None:
        self._slot = slot

    def get(self) -> None:
        self.set_header("Content-Type", "application/json")
        self.set_header("Cache-Control", "no-store")
        self.finish(encode(self._slot.latest(), full=True))


class _Report(tornado.web.RequestHandler):
    def initialize(self, report: Callable[[], Path | None]) -> None:
        self._report = report

    def get(self) -> None:
        path = self._report()
        if path is None or not path.is_file():
            raise tornado.web.HTTPError(404, reason="the report is written when the run ends")
        self.set_header("Content-Type", "text/html; charset=utf-8")
        self.finish(path.read_bytes())


class _Stream(tornado.websocket.WebSocketHandler):
    def initialize(self, server: LiveServer) -> None:
        self._server = server
        self.position: tuple[int, int] | None = None  # (chunk, event) the page holds; None: nothing yet
        self.version = -1  # of the last snapshot sent
        self.pending: Any = None

    def open(self, *args: str, **kwargs: str) -> None:
        self._server.pages.add(self)
        self._server.push()

    def on_message(self, message: str | bytes) -> None:
        pass  # read-only: whatever a page sends is ignored

    def on_close(self) -> None:
        self._server.pages.discard(self)


class LiveServer:
    """Serves the page for ``slot`` on ``host:port`` (port 0: any free port) from a daemon thread.

    ``report`` returns the report file once written (None before). :meth:`start` binds in the caller's thread (an
    address in use raises ``OSError`` there) and returns when the server is up; :meth:`stop` ends it."""

    def __init__(self, slot: SnapshotSlot, host: str = "127.0.0.1", port: int = 0,
                 report: Callable[[], Path | None] | None = None, stream_hz: float = STREAM_HZ) -> None:
        self.slot = slot
        self.host = host
        self.port = port
        self._report = report or (lambda: None)
        self._stream_hz = stream_hz
        self.pages: set[_Stream] = set()
        self.messages_sent = 0
        self._chunk_texts = ChunkTexts()  # used in the server's thread only
        self._loop: tornado.ioloop.IOLoop | None = None
        self._thread: threading.Thread | None = None

    @property
    def url(self) -> str:
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"http://{host}:{self.port}/"

    def _application(self) -> tornado.web.Application:
        plotly_js = _plotly_js()
        return tornado.web.Application([
            (r"/", _Static, {"body": _asset("index.html"), "content_type": "text/html; charset=utf-8"}),
            (r"/live.js", _Static, {"body": _asset("live.js"), "content_type": "text/javascript; charset=utf-8"}),
            (r"/live.css", _Static, {"body": _asset("live.css"), "content_type": "text/css; charset=utf-8"}),
            (r"/plotly.min.js", _Static, {"body": plotly_js, "content_type": "text/javascript; charset=utf-8",
                                          "gzipped": gzip.compress(plotly_js, 6)}),
            (r"/ws", _Stream, {"server": self}),
            (r"/state.json", _State, {"slot": self.slot}),
            (r"/report", _Report, {"report": self._report}),
        ], websocket_ping_interval=10, log_function=lambda handler: None)  # no access log on the run's stderr

    def start(self) -> None:
        family = socket.AF_INET6 if ":" in self.host else socket.AF_INET
        sockets = tornado.netutil.bind_sockets(self.port, address=self.host, family=family)
        self.port = sockets[0].getsockname()[1]
        app = self._application()
        ready = threading.Event()

        def serve() -> None:
            asyncio.set_event_loop(asyncio.new_event_loop())
            loop = self._loop = tornado.ioloop.IOLoop.current()
            server = tornado.httpserver.HTTPServer(app)
            server.add_sockets(sockets)
            tornado.ioloop.PeriodicCallback(self.push, 1000.0 / self._stream_hz).start()
            ready.set()
            loop.start()
            server.stop()
            loop.close(all_fds=True)

        self._thread = threading.Thread(target=serve, name="live-page", daemon=True)
        self._thread.start()
        ready.wait(10.0)

    def push(self) -> None:
        """Send the published snapshot to every page that has room for it (in the server's thread)."""
        snap = self.slot.latest()
        texts: dict[tuple[int, int] | None, str] = {}
        for page in list(self.pages):
            if page.version == snap.version or (page.pending is not None and not page.pending.done()):
                continue
            pos = page.position
            text = texts.get(pos)
            if text is None:
                text = texts[pos] = encode(snap, *(pos or (-1, -1)), full=pos is None, texts=self._chunk_texts)
            try:
                page.pending = page.write_message(text)
            except tornado.websocket.WebSocketClosedError:
                self.pages.discard(page)
                continue
            page.position = last_indices(snap)
            page.version = snap.version
            self.messages_sent += 1

    def stop(self) -> None:
        loop, thread = self._loop, self._thread
        if loop is not None and thread is not None:
            loop.add_callback(loop.stop)
            thread.join(5.0)
        self._loop = self._thread = None
