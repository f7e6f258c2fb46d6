"""Fake refits for the steps that put a kept term in another's place (``workbench.discover._term_swap``): each refit
records its free parameters (name → bounds) and start values in ``seen`` and returns ``out``; an instant taken is
placed on the whole record at ``placed_s`` (``workbench.discover._since_onset.place_instant``)."""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any


def fake_refits(monkeypatch: Any, seen: dict, held: float, values: dict[str, float],
                placed_s: float = 6.001) -> SimpleNamespace:
    import workbench.discover._since_onset as since_onset
    import workbench.discover._term_swap as term_swap

    class Obj:
        def __init__(self, targets, models, free, base_values, threads):
            seen.setdefault("free", []).append({fp.name: (fp.lower, fp.upper) for fp in free})
            seen.setdefault("start", []).append(dict(base_values))
            self.n_sims = 4

    out = SimpleNamespace(ok=True, held_rms_sigma=held, train_rms_sigma=held, estimates=[], values=values)
    monkeypatch.setattr(term_swap, "Objective", Obj)
    monkeypatch.setattr(term_swap, "refine", lambda obj, start, nfev: out)
    monkeypatch.setattr(since_onset, "placed_on_whole", lambda tg, m, vals, name, score, th: (placed_s, score, 5))
    monkeypatch.setattr(since_onset, "whole_rms", lambda targets, o: o.held_rms_sigma)
    return out
