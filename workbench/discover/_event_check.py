"""Whether a damage *event* may lead a round of ``shm discover`` (issue 26 point 1, for the dictionary's time gates).

On a sweep, time is also frequency: a step or a ramp of a section's stiffness at some instant soaks up part of a
stiffness that changes with the sign of the section's deflection (a crack in section 3 open for δ3 < 0 was named
"section 3 lost 11.1 % of its stiffness at t = 0.73 ± 0.04 s", 91 σ left), and on a one-way step test a crack that
opens for δ2 > 0 and a loss at the test's own step instant are twins. So a time-gated term leads only when it is
plausible and better:

* the members of the same parameter that are constant in time (its sign gates and its gap:
  :func:`invariant_siblings`) are refitted too, and one that comes within the twins' tolerance is kept instead —
  the event is then named as what the records cannot tell it from (:func:`event_twin`);
* an event that does not reach the noise floor must look like one (:func:`onset_issue`): the model with it matches
  the record before its onset to the noise (a real event leaves the model right before it), the onset is not
  pinned to the record's edge nor to its refit range's bound, and its standard error is small against the record.

Pure logic: the refits themselves are :mod:`workbench.discover._rounds`' job.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from workbench.discover._dictionary import Term
from workbench.discover._effect_writer import describe_term
from workbench.discover._gates import TIME_GATES
from workbench.discover._results import ScreenRow
from workbench.discover._search import probe_batch
from workbench.fit import FitOutcome, Target

#: an onset within this share of the record from either end is pinned to the edge: no instant was found
EDGE_SHARE = 0.02
#: an onset whose standard error exceeds this share of the record is not placed
ONSET_SE_SHARE = 0.05
#: the model with the event may leave at most this RMS (σ) before its onset (the cure's 1.5 σ)
QUIET_BEFORE_SIGMA = 1.5
#: fewer samples than this before the onset cannot show the model matched there
MIN_BEFORE_SAMPLES = 20
#: an event's place family is probed at the kept instant at these multiples of the kept change; a place whose best
#: probe leaves more than PLACE_NEAR × the kept term's held-out RMS is not refitted (a sweep tells sections apart)
PLACE_PROBES = (0.5, 0.75, 1.0, 1.5, 2.0)
PLACE_NEAR = 3.0


def is_timed(term: Term) -> bool:
    """Whether ``term`` is gated in time (a step or a ramp from an onset)."""
    return term.form in TIME_GATES


def invariant_siblings(rows: Sequence[ScreenRow], term: Term) -> list[ScreenRow]:
    """The damage terms of ``term``'s parameter (same core parameter and section/mass) whose gate is constant in
    time — its sign gates and its gap — each by its best row in ``rows`` (rows of one key differ only in shape)."""
    best: dict[str, ScreenRow] = {}
    for r in rows:
        t = r.term
        if t.placement != "damage" or (t.param, t.index) != (term.param, term.index) or is_timed(t):
            continue
        if t.key not in best or r.train_rms_sigma < best[t.key].train_rms_sigma:
            best[t.key] = r
    return list(best.values())


def before_onset_rms(targets: Sequence[Target], ys: Sequence[np.ndarray], t0: float) -> tuple[float, int]:
    """RMS (σ) of the residual ``measured − y`` over every channel and sample before ``t0`` (s) of every target
    (``ys[i]``: channels × samples of target i), and the number of samples it is taken over."""
    ss, n = 0.0, 0
    for tg, y in zip(targets, ys):
        before = np.asarray(tg.t) < t0
        if not before.any():
            continue
        r = (tg.measured[:, before] - np.asarray(y)[:, before]) / tg.sigma[:, None]
        ss += float(np.sum(r * r))
        n += int(before.sum())
    n_ch = max(len(targets[0].channels), 1) if targets else 1
    return (math.sqrt(ss / (n * n_ch)) if n else math.inf), n


def onset_issue(targets: Sequence[Target], outcome: FitOutcome, gname: str) -> str | None:
    """Why the refit ``outcome`` of a time-gated term (onset parameter ``gname``) is no plausible event, in words;
    None when it is one (see the module docstring)."""
    est = next((e for e in outcome.estimates if e.name == gname), None)
    if est is None:
        return None  # the onset was not free in this refit: nothing to judge
    t0, se = float(est.value), float(est.stderr)
    start = min(float(tg.t[0]) for tg in targets)
    end = max(float(tg.t[-1]) for tg in targets)
    duration = max(end - start, 1e-9)
    if est.at_bound:
        return f"its onset t = {t0:.4g} s sits at the bound of the range it was fitted in"
    if t0 - start < EDGE_SHARE * duration or end - t0 < EDGE_SHARE * duration:
        return f"its onset t = {t0:.4g} s is pinned to the record's edge"
    if not (math.isfinite(se) and se <= ONSET_SE_SHARE * duration):
        return f"its onset t = {t0:.4g} ± {se:.2g} s is not placed within {100 * ONSET_SE_SHARE:.0f} % of the record"
    quiet, n = before_onset_rms(targets, [y[0] for y in outcome.sim.y], t0)
    if n < MIN_BEFORE_SAMPLES:
        return f"its onset t = {t0:.4g} s leaves too few samples before it to show the model matched there"
    if quiet > QUIET_BEFORE_SIGMA:
        return (f"the model with it still leaves {quiet:.3g} σ before its onset t = {t0:.4g} s (a real event leaves "
                "the model right before it)")
    return None


def place_family(terms: Sequence[Term], names: Sequence[tuple[str, str | None]], kept: int,
                 values: Mapping[str, float], done: set[str]) -> list[ScreenRow]:
    """The kept time-gated term's change at the same instant in the other sections (or masses, patches): rows of the
    same form and parameter at the kept onset, whose slot's refit range holds it, not refitted yet (``done``: keys).
    A record that excites one mode (an MBIT) moves it alike for a loss in section 1 and in section 2 — k2 −15 % at
    11 s of MBIT.a (10 µm) was named "section 1 lost 15 % of its stiffness at t = 11.00 s", section 2 never said —
    so each gets its own refit and the verdict names the ones the records cannot rule out."""
    term = terms[kept]
    cname, gname = names[kept]
    if not is_timed(term) or term.index < 0 or gname is None or gname not in values:
        return []
    t0 = float(values[gname])
    out: list[ScreenRow] = []
    for t in terms:
        rng = t.shape_range
        if (t.placement, t.form, t.param) != (term.placement, term.form, term.param) or t.index == term.index \
                or t.key in done or rng is None or not rng[0] <= t0 <= rng[1]:
            continue
        done.add(t.key)
        out.append(ScreenRow(t, float(values[cname]), math.inf, math.inf, shape=t0, placed=True))
    return out


def place_rows(setup: Any, progress: Any, settings: Any, best: Any, done: set[str]) -> list[ScreenRow]:
    """:func:`place_family` of the round's ``best`` refit, each place probed first on the full model at the kept
    instant (:data:`PLACE_PROBES`, in place of the kept change) and kept for a refit only when it comes near it
    (:data:`PLACE_NEAR`): each refit costs seconds, and on a sweep the sections are told apart anyway.
    ``setup``, ``progress``, ``settings``: the rounds' objects."""
    rows = place_family(setup.terms, setup.names, best.index, best.outcome.values, done)
    if not rows:
        return rows
    t0 = float(best.outcome.values[setup.names[best.index][1]])
    trials: list[tuple[ScreenRow, dict[str, float]]] = [
        (r, {setup.names[setup.terms.index(r.term)][0]: m * r.coef, str(setup.names[setup.terms.index(r.term)][1]): t0})
        for r in rows for m in PLACE_PROBES]
    held, _, ok = probe_batch(setup.targets, setup.models, progress.state.values, [t[1] for t in trials],
                              settings.threads)
    progress.n_sims += len(trials) * len(setup.targets)
    limit = PLACE_NEAR * max(best.held_rms_sigma, 1.0)
    near = {trials[i][0].term.key for i in range(len(trials)) if ok[i] and held[i] <= limit}
    return [r for r in rows if r.term.key in near]


def event_twin(term: Term, outcome: FitOutcome, names: tuple[str, str | None],
               scales: Mapping[str, float]) -> dict[str, Any]:
    """The refitted time-gated ``term`` as a twin of the term kept instead (the record cannot tell it from that),
    in :func:`workbench.discover._twins.twins_of`'s format, in words with its fitted size and onset."""
    cname, gname = names
    values = outcome.values
    coef = float(values.get(cname, 0.0))
    shape = float(values.get(gname, term.shape)) if gname else term.shape
    se = next((e.stderr for e in outcome.estimates if e.name == gname), None)
    words = describe_term(term, coef, shape, scales.get(term.signal, 1.0), se)
    return {"key": term.key, "placement": term.placement, "index": term.index, "signal": term.signal,
            "form": term.form, "held_rms_sigma": outcome.held_rms_sigma, "judged_by": "refitted", "words": words}
