"""Headless Chromium driven over the DevTools protocol, for the live page's tests (tornado's websocket client, no
extra package): open a page, evaluate JavaScript in it, take a screenshot, close it.

``CHROMIUM`` is Debian's ``chromium`` (``make setup`` installs it as root); without it the tests skip."""

from __future__ import annotations

import asyncio
import base64
import itertools
import json
import shutil
import subprocess
from pathlib import Path
from typing import Any

from tornado.websocket import WebSocketClientConnection, websocket_connect

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")


class Browser:
    """One headless Chromium; pages are CDP sessions (``Target.attachToTarget`` with ``flatten``)."""

    def __init__(self, proc: subprocess.Popen, ws: WebSocketClientConnection) -> None:
        self.proc = proc
        self.ws = ws
        self._ids = itertools.count(1)
        #: JavaScript exceptions and console errors of every page (``Runtime.exceptionThrown``, console.error)
        self.page_errors: list[str] = []

    @classmethod
    async def launch(cls, profile: Path, width: int = 1500, height: int = 1000) -> Browser:
        assert CHROMIUM is not None
        proc = subprocess.Popen(
            [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage", "--no-first-run",
             "--remote-debugging-port=0", f"--user-data-dir={profile}", f"--window-size={width},{height}",
             "about:blank"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        port_file = profile / "DevToolsActivePort"
        for _ in range(300):
            if port_file.exists() and len(port_file.read_text().split()) >= 2:
                break
            await asyncio.sleep(0.05)
        port, path = port_file.read_text().split()[:2]
        ws = await websocket_connect(f"ws://127.0.0.1:{port}{path}", max_message_size=64 << 20)
        return cls(proc, ws)

    async def send(self, method: str, params: dict[str, Any] | None = None, session: str | None = None) -> Any:
        msg_id = next(self._ids)
        msg: dict[str, Any] = {"id": msg_id, "method": method, "params": params or {}}
        if session is not None:
            msg["sessionId"] = session
        await self.ws.write_message(json.dumps(msg))
        while True:
            text = await asyncio.wait_for(self.ws.read_message(), 30.0)
            if text is None:
                raise ConnectionError("chromium closed the DevTools connection")
            reply = json.loads(text)
            method_seen = reply.get("method")
            if method_seen == "Runtime.exceptionThrown":
                details = reply["params"]["exceptionDetails"]
                self.page_errors.append(str(details.get("exception", {}).get("description") or details))
            elif method_seen == "Runtime.consoleAPICalled" and reply["params"].get("type") == "error":
                self.page_errors.append(" ".join(str(a.get("value", a.get("description")))
                                                 for a in reply["params"].get("args", [])))
            if reply.get("id") == msg_id:
                if "error" in reply:
                    raise RuntimeError(f"{method}: {reply['error']}")
                return reply.get("result", {})

    async def open(self, url: str) -> tuple[str, str]:
        """(target id, session id) of a new page at ``url``."""
        target = (await self.send("Target.createTarget", {"url": url}))["targetId"]
        session = (await self.send("Target.attachToTarget", {"targetId": target, "flatten": True}))["sessionId"]
        await self.send("Runtime.enable", session=session)
        return target, session

    async def evaluate(self, session: str, expression: str) -> Any:
        r = await self.send("Runtime.evaluate", {"expression": expression, "returnByValue": True}, session)
        if "exceptionDetails" in r:
            raise RuntimeError(f"{expression}: {r['exceptionDetails']}")
        return r["result"].get("value")

    async def wait_for(self, session: str, expression: str, timeout_s: float = 20.0) -> Any:
        """The value of ``expression`` once it is truthy (polled every 0.1 s); TimeoutError after ``timeout_s``."""
        for _ in range(int(timeout_s / 0.1)):
            value = await self.evaluate(session, expression)
            if value:
                return value
            await asyncio.sleep(0.1)
        raise TimeoutError(f"{expression!r} still false after {timeout_s:g} s")

    async def screenshot(self, session: str, path: Path) -> None:
        r = await self.send("Page.captureScreenshot", {"format": "png", "captureBeyondViewport": True}, session)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(base64.b64decode(r["data"]))

    async def close_page(self, target: str) -> None:
        await self.send("Target.closeTarget", {"targetId": target})

    async def close(self) -> None:
        try:
            await asyncio.wait_for(self.send("Browser.close"), 5.0)
        except Exception:
            pass
        self.ws.close()
        try:
            self.proc.wait(5.0)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait(5.0)


#: what the page displays: element id -> (text, data-value)
READ_PAGE = """(() => { const out = {}; for (const el of document.querySelectorAll('[id]')) {
  if (el.children.length === 0 || el.id === 'events') out[el.id] = [el.textContent, el.dataset.value ?? null]; }
  out.events = Array.from(document.querySelectorAll('#events li')).map((li) => li.textContent);
  out.traces = Object.fromEntries(['chart-eps', 'chart-z3', 'chart-battery', 'chart-regime', 'chart-count']
    .map((id) => [id, ((document.getElementById(id) || {}).data || []).map((t) => t.x.length)]));
  return out; })()"""
