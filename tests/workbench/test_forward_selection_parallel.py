"""Forward selection's independent fits run two at a time (issue 26 point 7: a forward step's quick tries and the
backward step's drop-one fits of one set were most of forward selection's time on a 15 s sweep), and give the same
selection as one after another. The fits are stubbed: each set's held-out error is given, and each takes a
moment, so that fits run together are seen in progress at the same time."""

from __future__ import annotations

import math
import threading
import time
from types import SimpleNamespace

import pytest

import workbench.diagnose._fit_cache as fit_cache
import workbench.diagnose._forward_selection as fs
from plant.effect import registered_effects
from workbench.fit import CandidateResult, CandidateSpec, parameter_candidate

N = 2000
RSS0 = 400.0 ** 2 * N


def _spec(*names: str) -> CandidateSpec:
    reg = registered_effects()
    return CandidateSpec(tuple(reg[n] for n in names if n in reg),
                         tuple(parameter_candidate(n) for n in names if n not in reg))


def _result(held_sigma: float, s: CandidateSpec) -> CandidateResult:
    o = SimpleNamespace(held_rss=held_sigma ** 2 * N, held_rms_sigma=held_sigma, n_held=N, n_train=N,
                        train_rss=held_sigma ** 2 * N, rho1_held=0.0, values={n: 1.0 for n in s.members})
    c = CandidateResult(s.label, "", "", "", [object()] * len(s.members), o, spec=s)  # type: ignore[arg-type]
    c.stable, c.status = True, "fitted"
    return c


#: held-out σ of each set (by its members): dropping k1 from the four costs nothing, everything else costs much
HELD = {frozenset({"dielectric_leakage", "piezo_creep", "k1", "k2"}): 5.0,
        frozenset({"piezo_creep", "k1", "k2"}): 80.0, frozenset({"dielectric_leakage", "k1", "k2"}): 90.0,
        frozenset({"dielectric_leakage", "piezo_creep", "k2"}): 5.0,
        frozenset({"dielectric_leakage", "piezo_creep", "k1"}): 70.0,
        frozenset({"piezo_creep", "k2"}): 60.0, frozenset({"dielectric_leakage", "k2"}): 65.0,
        frozenset({"dielectric_leakage", "piezo_creep"}): 50.0}


class _Overlap:
    """How many stubbed fits were in progress at once, at most."""

    def __init__(self) -> None:
        self.now = self.most = 0
        self.lock = threading.Lock()

    def __enter__(self) -> None:
        with self.lock:
            self.now += 1
            self.most = max(self.most, self.now)
        time.sleep(0.1)

    def __exit__(self, *exc: object) -> None:
        with self.lock:
            self.now -= 1


def _stub(monkeypatch, parallel: int) -> tuple[list[str], _Overlap]:
    calls: list[str] = []
    overlap = _Overlap()

    def fake_fit(s, base, targets, data, rss0_held, *, start, min_reduction, max_nfev=30, **kw):
        with overlap:
            calls.append(s.label)
        held = HELD.get(frozenset(s.members), 30.0 if "air_damping" in s.members else 40.0)
        r = _result(held * (0.9 if max_nfev > fs.TRY_NFEV else 1.0), s)
        fs.score(r, rss0_held, min_reduction)
        return r

    monkeypatch.setattr(fit_cache, "fit_spec", fake_fit)
    monkeypatch.setattr(fs, "PARALLEL_FITS", parallel)
    monkeypatch.setattr(fs.os, "cpu_count", lambda: 2)
    return calls, overlap


def _tries():
    current = _result(20.0, _spec("dielectric_leakage"))
    fs.score(current, RSS0, 0.02)
    return current, [(_spec(n), {}) for n in ("air_damping", "piezo_creep", "geometric_stiffening")]


def test_a_steps_quick_tries_run_two_at_a_time_and_pick_the_same_best(monkeypatch):
    current, tries = _tries()
    _, alone = _stub(monkeypatch, 1)
    serial = fs._best_try(current, tries, None, [], {}, RSS0, fs.FitCache(), min_reduction=0.02, max_nfev=30,
                          threads=None, seed=0)
    calls, overlap = _stub(monkeypatch, 2)
    both = fs._best_try(current, tries, None, [], {}, RSS0, fs.FitCache(), min_reduction=0.02, max_nfev=30,
                        threads=None, seed=0)
    assert serial is not None and both is not None
    assert both.members == serial.members and "air_damping" in both.members
    assert both.held_rms_sigma == pytest.approx(serial.held_rms_sigma)
    assert len(calls) == 4  # three quick tries (two of them together), the best fitted in full
    assert alone.most == 1 and overlap.most == 2


def test_the_backward_steps_drop_one_fits_run_two_at_a_time_and_prune_the_same(monkeypatch):
    four = _result(5.0, _spec("dielectric_leakage", "piezo_creep", "k1", "k2"))
    fs.score(four, RSS0, 0.02)
    kw = dict(min_reduction=0.02, threads=None, max_nfev=30, seed=0)
    serial_calls, alone = _stub(monkeypatch, 1)
    without_serial: dict[str, CandidateResult] = {}
    serial = fs._prune(four, None, [], {}, RSS0, without_serial, fits=fs.FitCache(), **kw)
    calls, overlap = _stub(monkeypatch, 2)
    without: dict[str, CandidateResult] = {}
    fits = fs.FitCache()
    both = fs._prune(four, None, [], {}, RSS0, without, fits=fits, **kw)
    assert set(both.members) == set(serial.members) == {"dielectric_leakage", "piezo_creep", "k2"}
    assert {m: r.held_rms_sigma for m, r in without.items()} == \
        {m: r.held_rms_sigma for m, r in without_serial.items()}
    # the drops of the four members in pairs (k1's and k2's together); k1 goes, so the drop of k2 from the four,
    # fitted alongside, is the one fit more than one after another; nothing is fitted twice
    assert alone.most == 1 and overlap.most == 2
    assert len(calls) == len(set(calls)) == len(serial_calls) + 1
    assert set(calls) - set(serial_calls) == {_spec("dielectric_leakage", "piezo_creep", "k1").label}
    assert math.isfinite(both.delta_bic_held)
