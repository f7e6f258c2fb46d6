"""The live page of a running board (issue 32): ``shm run --live [HOST:]PORT`` and ``shm hil serve --live``.

The board (or the rig) publishes an immutable :class:`~live_page.snapshot.Snapshot` at most 20 times a second into a
:class:`~live_page.snapshot.SnapshotSlot` (one reference replaced, never a lock held by the tick); a server thread
(:mod:`live_page.server`, tornado) reads the slot and streams what changed to every open page over a websocket;
the page draws it with plotly.js, served from the installed ``plotly`` package (nothing from the internet).

Layers: :mod:`live_page.snapshot`, :mod:`live_page.messages` and :mod:`live_page.server` know only snapshots (an
import contract keeps them from the firmware, the links and the rig); :mod:`live_page.board_feed` and
:mod:`live_page.rig_feed` read a board or a rig and publish; :mod:`live_page.session` is what the CLI calls.
docs/live.md describes the page.
"""
