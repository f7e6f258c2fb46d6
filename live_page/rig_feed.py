"""The rig's side of the live page (``shm hil serve --live``): a thread that reads the rig host 20 times a second.

The rig does not know the board's regime, fault counter or model: its page shows what the rig knows — rig time,
the battery of its cell (voltage, and the state of charge read on the cell's open-circuit curve as the board would),
HV presence and the amplifier, the measured tip deflection while HV is present, the commands received, refused and
left unanswered, the rig's answer time p50/p99 (Modbus servers), its pacing misses and its incident log. The
thread reads only values the rig host publishes for its servers (its immutable snapshot, counters); it takes no
lock of the rig's.
"""

from __future__ import annotations

import math
import threading
from dataclasses import replace
from typing import Any

from live_page.snapshot import MAX_CHUNKS, MAX_EVENTS, Chunk, LinkHealth, Snapshot, SnapshotSlot, bounded
from live_page.soc import SocEstimate

#: publications per second
PUBLISH_HZ = 20.0


class RigFeed:
    """Publishes the state of ``service`` (a :class:`hil_stub.service.HilService`) into ``slot`` from a thread."""

    def __init__(self, slot: SnapshotSlot, service: Any, *, title: str, soc: SocEstimate | None = None,
                 publish_hz: float = PUBLISH_HZ) -> None:
        self.slot = slot
        self.service = service
        self.soc = soc if soc is not None else SocEstimate()
        self._period = 1.0 / publish_hz
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._chunk = 0
        self._seen_incidents = 0
        self._event_index = 0
        self._hv = False
        self._hv_id = 0
        self._answer: tuple[float | None, float | None] = (None, None)
        slot.publish(Snapshot(source="rig", title=title, paced=True,
                              soc_note=self.soc.note))

    def start(self) -> None:
        self._thread = threading.Thread(target=self._run, name="live-rig-feed", daemon=True)
        self._thread.start()

    def finish(self, status: str, report: str | None = None) -> Snapshot:
        """The rig stopped serving: stop the thread, publish the last state (kept by the page)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(2.0)
        return self.publish(finished=True, status=status, report=report)

    def _run(self) -> None:
        try:
            while not self._stop.wait(self._period):
                self.publish()
        except Exception as exc:  # the page stops and says why; the rig serves on
            prev = self.slot.latest()
            self.slot.publish(replace(prev, version=prev.version + 1, status="page stopped", extra=(
                *prev.extra, ("live page stopped (the rig serves on)", f"{type(exc).__name__}: {exc}"))))

    def _answer_time(self) -> tuple[float | None, float | None]:
        """The rig's answer time (s) p50/p99 over its Modbus servers' last answers (refreshed once a second)."""
        if self._chunk % int(1.0 / self._period) == 0:
            for srv in self.service.servers:
                summary = getattr(srv, "service_time_summary", None)
                s = summary() if summary is not None else {}
                if s.get("n"):
                    self._answer = (s["p50_ms"] / 1e3, s["p99_ms"] / 1e3)
        return self._answer

    def publish(self, **final: Any) -> Snapshot:
        prev = self.slot.latest()
        host = self.service.host
        snap_rig = host.snapshot
        sample = snap_rig.sample
        v = float(sample.v_battery)
        soc = self.soc.soc(v)
        if sample.hv_present and not self._hv:
            self._hv_id += 1
        self._hv = bool(sample.hv_present)
        p50, p99 = self._answer_time()
        rows = ((sample.t,), (float(sample.z3),), (math.nan,), (math.nan,)) if self._hv else ((), (), (), ())
        chunk = Chunk(self._chunk, float(sample.t), v, soc, None, p99, self._hv_id, *rows)
        self._chunk += 1
        new = host.incident_count - self._seen_incidents
        lines = list(host.incidents[-new:]) if new > 0 else []
        self._seen_incidents = host.incident_count
        events = tuple((self._event_index + i, str(line)) for i, line in enumerate(lines))
        self._event_index += len(events)
        counters: dict[str, int] = {"refused": int(host.refused_count), "unanswered": int(host.undelivered)}
        for srv in self.service.servers:
            for key, n in {**dict(srv.stats), **srv.faulter.counts()}.items():
                if isinstance(n, int):
                    counters[str(key)] = counters.get(str(key), 0) + n
        link = LinkHealth(exchanges=int(host.commands), misses=int(host.undelivered), rtt_p50_s=p50, rtt_p99_s=p99,
                          incidents=int(host.incident_count), deadline_misses=int(host.pacing.deadline_misses),
                          counters=tuple(sorted(counters.items())))
        extra = (("HV equipment", "present" if sample.hv_present else "absent"),
                 ("amplifier", "active" if snap_rig.amplifier_active else "at 0 V"),
                 ("board runs seen", str(host.board_runs)), ("rig ticks", str(snap_rig.tick)))
        snap = replace(prev, version=prev.version + 1, board_time_s=float(sample.t), v_battery_V=v, soc=soc,
                       mbit_id=self._hv_id, mbit_label="HV present: measured tip (the model is the board's)"
                       if self._hv_id else None, link=link, extra=extra,
                       chunks=bounded(prev.chunks, (chunk,), MAX_CHUNKS),
                       events=bounded(prev.events, events, MAX_EVENTS), **final)
        self.slot.publish(snap)
        return snap
