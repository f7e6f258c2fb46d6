"""Viewers of the live page for ``bench_live_page``, as their own process at the lowest priority (nice 19): in the
odd blocks of a schedule, ``n`` viewers each load the page as a browser would (``/``, ``/live.js``,
``/plotly.min.js`` gzipped) and hold its websocket, reading every message; in the even blocks none is connected.
Prints one JSON line: per block and viewer, the messages received and the seconds its websocket was open.

    python -m bench.live_viewers URL START_MONOTONIC BLOCK_S BLOCKS N
"""

from __future__ import annotations

import asyncio
import json
import os
import sys
import time

from tornado.httpclient import AsyncHTTPClient
from tornado.websocket import websocket_connect


async def _viewer(url: str, until: float, counts: list[float]) -> None:
    """Load the page, hold its websocket until ``until``; ``counts``: [messages, seconds connected]."""
    http = AsyncHTTPClient()
    for path in ("", "live.js", "plotly.min.js"):
        await http.fetch(url + path, headers={"Accept-Encoding": "gzip"}, decompress_response=False)
    ws = await websocket_connect(url.replace("http", "ws") + "ws", max_message_size=64 << 20)
    connected = time.monotonic()
    try:
        while time.monotonic() < until:
            try:
                msg = await asyncio.wait_for(ws.read_message(), max(0.01, until - time.monotonic()))
            except TimeoutError:
                break
            if msg is None:
                break
            counts[0] += 1
    finally:
        counts[1] = time.monotonic() - connected
        ws.close()


async def _main(url: str, start: float, block_s: float, blocks: int, n: int) -> list[list[list[float]]]:
    received: list[list[list[float]]] = []
    for b in range(blocks):
        begin = start + b * block_s
        await asyncio.sleep(max(0.0, begin - time.monotonic()))
        if b % 2 == 0:
            received.append([])
            continue
        counts = [[0.0, 0.0] for _ in range(n)]
        await asyncio.gather(*(_viewer(url, begin + block_s - 0.05, c) for c in counts))
        received.append(counts)
    return received


if __name__ == "__main__":
    # the lowest priority: what is measured is the page's cost to the board's process, not the viewers' own CPU
    # (a browser on another machine, through ssh -L, costs the board's machine nothing)
    os.nice(19)
    url, start, block_s, blocks, n = sys.argv[1], float(sys.argv[2]), float(sys.argv[3]), int(sys.argv[4]), \
        int(sys.argv[5])
    print(json.dumps(asyncio.run(_main(url, start, block_s, blocks, n))), flush=True)
