"""The websocket messages of the live page: what changed between a page's last message and a snapshot (pure).

A message is one JSON object (SI units, names as in :class:`~live_page.snapshot.Snapshot`; non-finite numbers are
``null``). ``full`` is true for a page's first message (the page starts afresh); ``chunks`` and ``events`` hold only
the items whose running index is past what the page already has (``since_chunk``, ``since_event``), the scalars and
the short lists (regime changes, verdicts, link health) are always whole. The same message serves every page at the
same position, so the server encodes it once per position, not once per page.
"""

from __future__ import annotations

import json
from typing import Any

from board_config.json_values import to_jsonable
from live_page.snapshot import MAX_CHUNKS, Chunk, Snapshot


def _chunk(c: Chunk, rows: bool = True) -> dict[str, Any]:
    d: dict[str, Any] = {"i": c.index, "t_s": c.t_s, "v_battery_V": c.v_battery_V, "soc": c.soc,
                         "monitor_count": c.monitor_count, "rtt_p99_s": c.rtt_p99_s, "mbit_id": c.mbit_id}
    if c.mbit_t_s and rows:
        d.update(mbit_t_s=c.mbit_t_s, z3_meas_m=c.z3_meas_m, z3_model_m=c.z3_model_m, eps=c.eps)
    return d


def _chunk_index(c: Chunk) -> int:
    return c.index


def _event_index(e: tuple[int, str]) -> int:
    return e[0]


def _after(items: tuple, since: int, index: Any) -> tuple:
    """The items whose running index is past ``since``: indices run without gaps, so the tail (no scan of the
    whole history for every message)."""
    if not items or index(items[-1]) <= since:
        return ()
    first = index(items[0])
    return items if since < first else items[since - first + 1:]


def message(snap: Snapshot, since_chunk: int = -1, since_event: int = -1, full: bool = False) -> dict[str, Any]:
    """The message that brings a page holding chunks up to ``since_chunk`` and events up to ``since_event`` (-1:
    none) to ``snap``; ``full``: the page's first message (it starts afresh)."""
    link = snap.link
    return {
        "version": snap.version, "full": full, "source": snap.source,
        "title": snap.title, "board_time_s": snap.board_time_s, "planned_s": snap.planned_s, "paced": snap.paced,
        "regime": snap.regime, "regime_since_s": snap.regime_since_s, "regimes": snap.regimes,
        "v_battery_V": snap.v_battery_V, "soc": snap.soc, "soc_note": snap.soc_note,
        "monitor_count": snap.monitor_count, "count_max": snap.count_max, "fault_latched": snap.fault_latched,
        "eps_th": snap.eps_th, "maintenance": snap.maintenance, "mbit_id": snap.mbit_id,
        "mbit_label": snap.mbit_label, "mbit_max_eps": snap.mbit_max_eps, "mbit_max_count": snap.mbit_max_count,
        "verdicts": snap.verdicts,
        "link": {"exchanges": link.exchanges, "misses": link.misses, "rtt_p50_s": link.rtt_p50_s,
                 "rtt_p99_s": link.rtt_p99_s, "incidents": link.incidents, "deadline_misses": link.deadline_misses,
                 "counters": dict(link.counters)},
        "extra": snap.extra,
        # a page shows the current MBIT only: the rows of earlier ones would be sent for nothing
        "chunks": [_chunk(c, c.mbit_id == snap.mbit_id) for c in _after(snap.chunks, since_chunk, _chunk_index)],
        "events": list(_after(snap.events, since_event, _event_index)),
        "finished": snap.finished, "status": snap.status, "report": snap.report,
    }


def _dumps(obj: Any) -> str:
    return json.dumps(to_jsonable(obj), separators=(",", ":"), allow_nan=False)


class ChunkTexts:
    """Each chunk's JSON text, encoded once (with or without its MBIT rows) and kept while snapshots hold the
    chunk: a page's first message in a long run joins up to 2400 kept texts (about 0.1 ms) instead of encoding them
    again (tens of ms in which the server's thread holds the interpreter lock the board's thread needs)."""

    def __init__(self) -> None:
        self._texts: dict[tuple[int, bool], str] = {}

    def text(self, c: Chunk, rows: bool) -> str:
        key = (c.index, rows and bool(c.mbit_t_s))
        t = self._texts.get(key)
        if t is None:
            t = self._texts[key] = _dumps(_chunk(c, rows))
        return t

    def forget_before(self, first_index: int) -> None:
        """Drop the texts of chunks no snapshot holds any more (index below ``first_index``)."""
        if len(self._texts) > 3 * MAX_CHUNKS:
            self._texts = {k: v for k, v in self._texts.items() if k[0] >= first_index}


def encode(snap: Snapshot, since_chunk: int = -1, since_event: int = -1, full: bool = False,
           texts: ChunkTexts | None = None) -> str:
    """:func:`message` as JSON text (strict JSON: NaN and infinities become null). Each chunk is encoded by
    itself (``texts``: kept from one message to the next), never the whole history in one long call."""
    msg = message(snap, last_indices(snap)[0], since_event, full)  # the chunks come from ``texts``
    del msg["chunks"]
    head = _dumps(msg)
    texts = texts if texts is not None else ChunkTexts()
    chunks = _after(snap.chunks, since_chunk, _chunk_index)
    if snap.chunks:
        texts.forget_before(snap.chunks[0].index)
    return head[:-1] + ',"chunks":[' + ",".join(texts.text(c, c.mbit_id == snap.mbit_id) for c in chunks) + "]}"


def last_indices(snap: Snapshot) -> tuple[int, int]:
    """(last chunk index, last event index) a page holds after a message of ``snap`` (-1: none)."""
    return (snap.chunks[-1].index if snap.chunks else -1, snap.events[-1][0] if snap.events else -1)
