"""The onset of a damage event inside a record: where the residual leaves the noise (:func:`change_point`), every
time-gated key of the dictionary probed there (:func:`onset_probe`), the best few parameters' steps and ramps chosen
for a refit (:func:`with_onsets`) and each scanned around its onset (:func:`onset_scan`) as the refit's start."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

from plant import PlantModel
from workbench.discover._dictionary import Term
from workbench.discover._gates import TIME_GATES
from workbench.discover._results import ScreenRow
from workbench.discover._search import probe_batch
from workbench.fit import Target

#: a time-gated term's onset: found in the residual (:func:`change_point`), every time-gated key probed there
#: (:func:`onset_probe`), the best few scanned around it (ONSET_ZOOM onsets over ± 1/ONSET_SCAN of the record and
#: multiples of the coefficient, then zoomed in, the spacing shrinking each time, down to a few milliseconds) and
#: refitted. Neither least squares nor a screen at fixed onsets can place t0: the error of a mistimed step rings in
#: the lightly damped modes — a 25 % loss of k2 at 20 s of a sweep leaves 0.06 σ at the right instant, 8 σ 10 ms off,
#: 23 σ 50 ms off, 28 σ 0.1 s off (refitted from the 18.75 s onset: 325 σ held-out; at 10 s of a 15 s sweep the
#: linearised screen ranked damping steps first and the probes at fixed onsets ranked contact terms first)
ONSET_SCAN = 24
ONSET_MULTIPLIERS = (0.4, 0.8, 1.4, 2.5)
ONSET_ZOOM = 9  # odd: the best onset so far is on the next grid
#: half-width of the first grid around an onset found in the residual (s; that onset is within a few samples)
ONSET_NEAR_S = 0.1
ONSET_RESOLUTION_S = 2e-3
#: time-gated keys refitted per round (each after a scan around its onset)
MAX_ONSET_KEYS = 2


def change_point(t: np.ndarray, r: np.ndarray) -> tuple[float, float]:
    """The instant the residual ``r`` (channels × samples, in σ) leaves the noise — the first where its RMS over
    ten samples exceeds 3 σ, when that is past the record's first 2 % (a change point by variance lags an event:
    the error of a lost stiffness grows from 0) — else where it changes its level most (two segments of constant
    variance, maximum likelihood); and the log-likelihood gained over one segment."""
    e = np.sum(np.asarray(r, float) ** 2, axis=0) / max(np.shape(r)[0], 1) + 1e-12
    n = e.size
    if n < 20:
        return float(t[0]), 0.0
    win = 10
    mean = np.convolve(e, np.ones(win) / win, mode="valid")
    over = np.flatnonzero(mean > 9.0)
    first = int(over[0]) + win - 2 if over.size else n  # the window's last samples made it exceed
    c = np.cumsum(e)
    k = np.unique(np.linspace(0.02 * n, 0.98 * n, 400).astype(int))
    cost = k * np.log(c[k - 1] / k) + (n - k) * np.log((c[-1] - c[k - 1]) / (n - k))
    i = int(np.argmin(cost))
    gain = float(n * math.log(c[-1] / n) - cost[i])
    if 0.02 * n < first < n:
        return float(t[first]), gain
    return float(t[k[i]]), gain


#: an event inside the record (:func:`event_onset`): the nominal model matches the record to within this RMS (σ)
#: before the instant its residual leaves the noise, that quiet part is at least :data:`QUIET_SHARE` of the record,
#: and after it the residual is above :data:`LOUD_SIGMA` RMS
QUIET_SIGMA = 1.2
QUIET_SHARE = 0.2
LOUD_SIGMA = 3.0


def event_onset(t: np.ndarray, r: np.ndarray) -> float | None:
    """The instant (s) a damage event inside the record would have happened, from the nominal model's residual
    ``r`` (channels × samples, in σ): where it first leaves the noise (its RMS over ten samples above 3 σ, as in
    :func:`change_point`) when the record before that is at the noise level (:data:`QUIET_SIGMA`) over at least
    :data:`QUIET_SHARE` of it and the rest is well above it (:data:`LOUD_SIGMA`); else None (a model wrong from the
    start, or nothing wrong)."""
    e = np.sum(np.asarray(r, float) ** 2, axis=0) / max(np.shape(r)[0], 1)
    n = e.size
    win = 10
    if n < 20 * win:
        return None
    over = np.flatnonzero(np.convolve(e, np.ones(win) / win, mode="valid") > 9.0)
    if not over.size:
        return None
    first = int(over[0]) + win - 2
    if first < QUIET_SHARE * n:
        return None
    quiet = math.sqrt(float(np.mean(e[:first])))
    loud = math.sqrt(float(np.mean(e[first:])))
    return float(t[first]) if quiet <= QUIET_SIGMA and loud > LOUD_SIGMA else None


#: relative changes a step is probed at first (not the linearised coefficient: a 25 % loss of k2 is far from
#: linear), and the total changes over the rest of the record a ramp is probed at; a key whose best probe is the
#: largest of its sign is probed further out (:data:`EDGE_OUT`: a damping ×4 is +300 %), a loss never past
#: :data:`MAX_LOSS` (the refit's own bound: a parameter keeps its sign)
STEP_PROBES = (-0.3, -0.1, -0.03, 0.03, 0.1, 0.3)
RAMP_PROBES = (-0.3, -0.1, 0.1, 0.3)
EDGE_OUT = (3.0, 10.0)
MAX_LOSS = -0.95
#: how much earlier than the residual leaves the noise a step is probed (s): the error of an event needs a moment,
#: and a stiffness step probed a few milliseconds off rings in the lightly damped modes while a gain-like mimic does
#: not — k2 −30 % at 1.350 s of an MBIT.b probed only at the detection (1.356 s) and 20 ms before it ranked 4th
#: (27 σ; α_h and d_ep steps first, refitted to 22 σ and named); probed also 3, 6 and 10 ms before: 1.07 σ, first
STEP_LEADS_S = (0.0, 0.003, 0.006, 0.01, 0.02)
#: multiples of each key's best probe tried next
COEF_REFINE = (0.7, 0.85, 1.15, 1.3)
#: rounds of probing: the first probes, then refinement and probes further out while a key's best is at its edge
PROBE_ROUNDS = 4


def _total_change(row: ScreenRow, coef: float, rest: float) -> float:
    """A probe's relative change of its parameter at the record's end (a ramp's rate × the time left)."""
    return coef * rest if row.term.form == "on_ramp" else coef


def _next_probes(best: Mapping[str, ScreenRow], probed: Mapping[str, list[float]], refined: set[tuple[str, float]],
                 rests: Mapping[str, float]) -> list[tuple[ScreenRow, float, float]]:
    """Each key's next probes: its best refined by :data:`COEF_REFINE` (once per best), and, when the best is the
    largest probe of its sign (the change may be larger), :data:`EDGE_OUT` times it (a loss up to
    :data:`MAX_LOSS`); ``rests``: each key's time from its onset to the record's end (s)."""
    out: list[tuple[ScreenRow, float, float]] = []
    for key, b in best.items():
        at, rest = float(b.shape if b.shape is not None else 0.0), rests[key]
        total = _total_change(b, b.coef, rest)
        same_sign = [v for v in probed[key] if v * total > 0]
        coefs: list[float] = []
        if same_sign and abs(total) >= max(abs(v) for v in same_sign) * (1 - 1e-9):
            coefs += [b.coef * m for m in EDGE_OUT]
        if (key, b.coef) not in refined:
            coefs += [b.coef * m for m in COEF_REFINE]
        for c in coefs:
            c = max(c, MAX_LOSS / (rest if b.term.form == "on_ramp" else 1.0))
            if all(abs(_total_change(b, c, rest) - v) > 1e-9 for v in probed[key]):
                out.append((b, c, at))
    return out


def probe_key(term: Term) -> str:
    """The key a time-gated term is probed under: its own, the ramp begun before the record apart."""
    return term.key + (" before" if term.before_record else "")


def onset_probe(rows: Sequence[ScreenRow], names: Mapping[Term, tuple[str, str | None]], targets: Sequence[Target],
                models: Sequence[PlantModel], values: Mapping[str, float], t0: float, t_end: float,
                threads: int | None) -> tuple[list[ScreenRow], int]:
    """Every time-gated key probed at the onset ``t0`` (s; ``t_end`` the record's end) at the relative changes of
    :data:`STEP_PROBES` / :data:`RAMP_PROBES`, then refined and followed outwards (:func:`_next_probes`), one batch a
    round; one row per key at its best probe (``shape`` = t0), best first, and the number of probes per record. The
    ramp begun before the record is probed at its own onset (its term's shape, before t = 0) at the same total
    changes over the time from there to the record's end."""
    firsts: dict[str, ScreenRow] = {}
    for r in rows:
        if r.term.form in TIME_GATES and names[r.term][1] is not None:
            firsts.setdefault(probe_key(r.term), r)
    # a ramp begun before the record is no event at t0: it is probed at its own onset, with the time left from it
    onset = {k: (r.term.shape if r.term.before_record else t0) for k, r in firsts.items()}
    rests = {k: max(t_end - at, 1e-3) for k, at in onset.items()}
    flat = [(r, v, t0 - lead) for r in firsts.values() if r.term.form == "on_step" for v in STEP_PROBES
            for lead in STEP_LEADS_S]
    flat += [(r, v / rests[k], onset[k]) for k, r in firsts.items() if r.term.form == "on_ramp" for v in RAMP_PROBES]
    best: dict[str, ScreenRow] = {}
    probed: dict[str, list[float]] = {k: [] for k in firsts}
    refined: set[tuple[str, float]] = set()
    n = 0
    for _ in range(PROBE_ROUNDS):
        if not flat:
            break
        at_or_0 = [at if r.term.before_record else max(at, 0.0) for r, _, at in flat]
        settings = [{names[r.term][0]: c, str(names[r.term][1]): at} for (r, c, _), at in zip(flat, at_or_0)]
        held, train, ok = probe_batch(targets, models, values, settings, threads)
        n += len(flat)
        refined |= {(k, b.coef) for k, b in best.items()}
        for (r, c, _), at, h, e, good in zip(flat, at_or_0, held, train, ok):
            key = probe_key(r.term)
            probed[key].append(_total_change(r, c, rests[key]))
            if good and (key not in best or e < best[key].train_rms_sigma):
                best[key] = ScreenRow(r.term, c, float(h), float(e), at)
        flat = _next_probes(best, probed, refined, rests)
    return sorted(best.values(), key=lambda r: r.train_rms_sigma), n


#: the coefficient's spread in the first zoom of :func:`onset_scan` (the first grid's ×0.92/×1.08 is too coarse: a
#: damping rise ×3 in section 3 at 5 s of a 10 s sweep, zoomed at 0.966 of its size, came out 31 ms late)
ZOOM_COEF = (0.97, 1.0, 1.03)


def whole_scores(targets: Sequence[Target], models: Sequence[PlantModel], values: Mapping[str, float],
                 settings: Sequence[Mapping[str, float]], threads: int | None) -> list[float]:
    """The whole record's RMS (σ) with each of ``settings`` on top of ``values``, one batch on the full model (inf
    where a member does not integrate): how every probe of the search that places a change is scored."""
    held, train, ok = probe_batch(targets, models, values, settings, threads)
    return [float(e) if good else math.inf for e, good in zip(whole_record_rms(targets, held, train), ok)]


def whole_record_rms(targets: Sequence[Target], held: np.ndarray, train: np.ndarray) -> np.ndarray:
    """The RMS (σ) over every sample of ``targets`` from the held-out and training RMS of each member."""
    n_h = sum(int(tg.held.sum()) * len(tg.channels) for tg in targets)
    n_t = sum(int(tg.train.sum()) * len(tg.channels) for tg in targets)
    return np.sqrt((n_h * np.asarray(held) ** 2 + n_t * np.asarray(train) ** 2) / max(n_h + n_t, 1))


def onset_scan(row: ScreenRow, name: tuple[str, str | None], targets: Sequence[Target],
               models: Sequence[PlantModel], values: Mapping[str, float], span: tuple[float, float],
               threads: int | None) -> tuple[dict[str, float], int]:
    """The best (coefficient, onset) of a time-gated term — around the row's probed onset (else a grid over
    ``span``, s, the record), then zoomed in — as a refit's start, and the number of probes per record.

    Scored over the *whole* record, held-out blocks too: half of the instants an event can happen at lie in a
    held-out block, where the training error is blind to the onset (the error of a mistimed step is largest right
    after it) — a damping rise at 5.0 s, the start of a held-out block of a 10 s sweep, was placed at 5.031 s by
    the training error (training 0.98 σ, held-out 1.68 σ). One coordinate chosen on the held-out samples, of
    thousands: the held-out error stays a fair judge of the term; the refit that follows fits on training only."""
    cname, gname = name
    if gname is None:
        return {cname: row.coef}, 0
    lo, hi = span
    step = (hi - lo) / ONSET_SCAN
    if row.shape is not None:  # probed on the full model at that onset: its coefficient is close already
        step = min(step, ONSET_NEAR_S)
        grid = [(c * row.coef, min(max(row.shape + (k / (ONSET_ZOOM - 1) * 2.0 - 1.0) * step, lo), hi))
                for k in range(ONSET_ZOOM) for c in (0.92, 1.0, 1.08)]
        step /= 0.5 * (ONSET_ZOOM - 1)
    else:
        grid = [(c * row.coef, lo + (k + 0.5) * step) for k in range(ONSET_SCAN) for c in ONSET_MULTIPLIERS]
    best: tuple[float, float, float] | None = None  # (training RMS, coefficient, onset)
    n = 0
    spread: tuple[float, ...] = ZOOM_COEF
    while True:
        scores = whole_scores(targets, models, values, [{cname: c, gname: t0} for c, t0 in grid], threads)
        n += len(grid)
        for (c, t0), e in zip(grid, scores):
            if math.isfinite(e) and (best is None or e < best[0]):
                best = (float(e), c, t0)
        if best is None or step <= ONSET_RESOLUTION_S:
            break
        _, c, t0 = best
        grid = [(c * m, min(max(t0 + (k / (ONSET_ZOOM - 1) * 2.0 - 1.0) * step, lo), hi)) for k in range(ONSET_ZOOM)
                for m in spread]
        spread = (1.0,)
        step /= 0.5 * (ONSET_ZOOM - 1)
    if best is None:
        return {cname: row.coef}, n
    return {cname: best[1], gname: best[2]}, n


def with_onsets(todo: list[ScreenRow], leads: Sequence[ScreenRow], first: bool = False) -> list[ScreenRow]:
    """The refit list with its time-gated rows (probed at fixed onsets: ranked too low or too high) replaced by the
    rows of the probe at the residual's onset (:func:`onset_probe`) of its best :data:`MAX_ONSET_KEYS` *parameters*,
    each with its step and its ramp: the probe sits at one onset, where a step a few milliseconds off rings in the
    lightly damped modes and a ramp does not, so the probe cannot tell them apart (a k2 loss of 15 % probed 8 ms
    early: the step 55 σ, the ramp 38 σ; scanned and refitted: the step 1 σ); the scan and the refit do. ``first``:
    the time-gated rows lead the list (a change during the record is expected)."""
    params: list[tuple[str, int]] = []
    for r in leads:
        if (r.term.param, r.term.index) not in params:
            params.append((r.term.param, r.term.index))
    chosen = params[:MAX_ONSET_KEYS]
    timed = [r for r in leads if (r.term.param, r.term.index) in chosen]
    rest = [r for r in todo if r.term.form not in TIME_GATES]
    return timed + rest if first else rest + timed


def shifted_onsets(setting: dict[str, float], gnames: Sequence[str], span_s: float, step_s: float
                   ) -> list[dict[str, float]]:
    """``setting`` with the onsets ``gnames`` moved together by every multiple of ``step_s`` within ± ``span_s`` of
    the first one's, unmoved first, then the nearest either side (a tie keeps the instant it has: the first of the
    lowest score)."""
    t0 = float(setting[gnames[0]])
    n = round(span_s / step_s)
    shifts = sorted(range(-n, n + 1), key=lambda i: (abs(i), i))
    return [setting | {g: t0 + i * step_s for g in gnames} for i in shifts]
