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
from dataclasses import replace
from typing import Any

import numpy as np

from workbench.discover._dictionary import Term
from workbench.discover._effect_writer import describe_term
from workbench.discover._gates import SIGN_GATES, TIME_GATES
from workbench.discover._onset import shifted_onsets, whole_scores
from workbench.discover._results import ScreenRow
from workbench.discover._search import probe_batch
from workbench.discover._twins import place_first, twin_tolerance
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
#: an event's kind family (another parameter changing at the kept instant) is probed at these relative changes, and
#: at the kept change c, −c and the static twin −c / (1 + c) (on a slow record a stiffness lost by 15 % and a patch's
#: authority gained by 17.6 % bend the section alike)
KIND_PROBES = (-0.3, -0.15, -0.05, 0.05, 0.15, 0.3)
#: a member that comes near is scanned for its own instant before its refit (span either side, step; s), one batch per
#: pass: the kept instant is its mimic's, off by milliseconds, and a refit hardly moves a sharp step's instant —
#: section 3 losing 20 % at 14.000 s of MBIT.a, kept as d_ep rising at 14.008 s: k3's step refitted from there stopped
#: at 14.011 s (9.54 σ); from 14.000 s it reaches 1.2 σ
FAMILY_ONSET_PASSES = ((0.04, 0.004), (0.004, 0.001))
#: when the kept event moves its parameter the way damage does not, the best :data:`MAX_DAMAGE_KINDS` kinds that move
#: theirs the way damage does are refitted when their probe leaves at most DAMAGE_NEAR × the kinds' limit: probed at
#: the kept instant and the kept change's static twin they sit off their own — section 3 losing 2 %/s from 11.0 s of
#: MBIT.a, kept as patch 3's authority rising 2.37 %/s from 11.23 s (1.73 σ): k3's ramp probed at −2.32 %/s from
#: 11.23 s, 6.58 σ (beyond the 5.2 σ limit); at −2 %/s from 11.0 s, 0.98 σ
DAMAGE_NEAR = 3.0
MAX_DAMAGE_KINDS = 2
#: the way damage moves a core parameter (the sign of its relative change): a section's stiffness and a patch's
#: authority are lost, damping is gained; the other parameters may move either way
DAMAGE_SIGN = {"k": -1.0, "c": 1.0, "d_ep": -1.0, "d_ep_i": -1.0}


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


def record_span(targets: Sequence[Any]) -> tuple[float, float]:
    """(first, last) instant (s) over the records of ``targets``."""
    return min(float(tg.t[0]) for tg in targets), max(float(tg.t[-1]) for tg in targets)


def onset_issue(targets: Sequence[Target], outcome: FitOutcome, gname: str) -> str | None:
    """Why the refit ``outcome`` of a time-gated term (onset parameter ``gname``) is no plausible event, in words;
    None when it is one (see the module docstring)."""
    est = next((e for e in outcome.estimates if e.name == gname), None)
    if est is None:
        return None  # the onset was not free in this refit: nothing to judge
    t0, se = float(est.value), float(est.stderr)
    start, end = record_span(targets)
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
                 values: Mapping[str, float], done: set[str], kinds: bool = False) -> list[ScreenRow]:
    """The kept time-gated term's change at the same instant in the other sections (or masses, patches): rows of the
    same form and parameter at the kept onset, whose slot's refit range holds it, not refitted yet (``done``: keys).
    A record that excites one mode (an MBIT) moves it alike for a loss in section 1 and in section 2 — k2 −15 % at
    11 s of MBIT.a (10 µm) was named "section 1 lost 15 % of its stiffness at t = 11.00 s", section 2 never said —
    so each gets its own refit and the verdict names the ones the records cannot rule out.

    ``kinds``: the other *parameters* changing at that instant instead (every place): on MBIT.b a section 1 that lost
    15 % of its stiffness at 1.2 s was named "authority d_ep of patch 1 rose by 17.7 %" — a slow record bends the
    section alike for both, and only a refit of each says which the records can tell apart."""
    term = terms[kept]
    cname, gname = names[kept]
    if not is_timed(term) or (term.index < 0 and not kinds) or gname is None or gname not in values:
        return []
    t0 = float(values[gname])
    out: list[ScreenRow] = []
    for t in terms:
        rng = t.shape_range
        other = t.param != term.param if kinds else (t.param == term.param and t.index != term.index)
        if (t.placement, t.form) != (term.placement, term.form) or not other \
                or t.key in done or rng is None or not rng[0] <= t0 <= rng[1]:
            continue
        done.add(t.key)
        out.append(ScreenRow(t, float(values[cname]), math.inf, math.inf, shape=t0, placed=True))
    return out


def family_probes(coef: float, kinds: bool) -> tuple[float, ...]:
    """The changes a place (the kept change ``coef`` times :data:`PLACE_PROBES`) or a kind (:data:`KIND_PROBES`,
    ``coef``, ``−coef`` and ``−coef / (1 + coef)``) of an event's family is probed at."""
    if not kinds:
        return tuple(m * coef for m in PLACE_PROBES)
    return (*KIND_PROBES, coef, -coef, static_twin(coef))


def static_twin(coef: float) -> float:
    """The relative change of a stiffness that bends a section as a change ``coef`` of its patch's authority does
    (and back): −c / (1 + c) — a loss of 15 % and a gain of 17.6 %; −c where 1 + c is near 0."""
    return -coef / (1.0 + coef) if coef > -0.9 else -coef


def damage_kinds(setup: Any, progress: Any, kept: int) -> list[int]:
    """The dictionary indices of this round's refitted time-gated terms of the same form as ``kept`` but another
    parameter, moving it the way damage does (:func:`damage_like`), best first — the kinds the kept change may be
    said as when it moves its own the way damage does not."""
    term = setup.terms[kept]
    best: dict[tuple[str, int], Any] = {}
    for b in progress.refits:
        t, cname = setup.terms[b.index], setup.names[b.index][0]
        if t.form == term.form and t.placement == "damage" and t.param != term.param \
                and damage_like(t, float(b.outcome.values.get(cname, 0.0))) \
                and ((t.param, t.index) not in best or b.held_rms_sigma < best[(t.param, t.index)].held_rms_sigma):
            best[(t.param, t.index)] = b
    return [b.index for b in sorted(best.values(), key=lambda b: b.held_rms_sigma)]


def place_rows(setup: Any, progress: Any, settings: Any, best: Any, done: set[str],
               kinds: bool = False) -> list[ScreenRow]:
    """:func:`place_family` of the round's ``best`` refit (``kinds``: its kind family), each member probed first on
    the full model at the kept instant (:func:`family_probes`, in place of the kept change) and kept for a refit only
    when it comes near it (:data:`PLACE_NEAR`): each refit costs seconds, and on a sweep the sections (and the kinds)
    are told apart anyway. ``setup``, ``progress``, ``settings``: the rounds' objects."""
    rows = place_family(setup.terms, setup.names, best.index, best.outcome.values, done, kinds)
    if not rows:
        return rows
    t0 = float(best.outcome.values[setup.names[best.index][1]])
    names = {r.term.key: setup.names[setup.terms.index(r.term)] for r in rows}  # (coefficient, onset) names
    trials: list[tuple[ScreenRow, dict[str, float]]] = [
        (r, {names[r.term.key][0]: c, str(names[r.term.key][1]): t0})
        for r in rows for c in family_probes(r.coef, kinds)]
    held, _, ok = probe_batch(setup.targets, setup.models, progress.state.values, [t[1] for t in trials],
                              settings.threads)
    progress.n_sims += len(trials) * len(setup.targets)
    limit = PLACE_NEAR * max(best.held_rms_sigma, 1.0)
    probed: dict[str, tuple[float, float]] = {}  # key: (held-out σ, change) of its best probe
    damage: dict[str, tuple[float, float]] = {}  # ... of its best probe moving its parameter the way damage does
    for i, (r, trial) in enumerate(trials):
        h, change = float(held[i]), trial[names[r.term.key][0]]
        if ok[i] and h <= limit and h < probed.get(r.term.key, (math.inf, 0.0))[0]:
            probed[r.term.key] = (h, change)
        if ok[i] and damage_like(r.term, change) and h < damage.get(r.term.key, (math.inf, 0.0))[0]:
            damage[r.term.key] = (h, change)
    kept_coef = float(best.outcome.values.get(setup.names[best.index][0], 0.0))
    if kinds and not damage_like(setup.terms[best.index], kept_coef):
        near = sorted((v, k) for k, v in damage.items() if k not in probed and v[0] <= DAMAGE_NEAR * limit)
        probed |= {k: v for v, k in near[:MAX_DAMAGE_KINDS]}
    if kinds:
        settings.say(f"  other parameters changing at t = {t0:.4g} s: {len(rows)} probed, {len(probed)} within "
                     f"{limit:.3g} σ or moving theirs the way damage does" + "".join(f", {k} {h:.3g} σ" for k, (h, _) in
                                                 sorted(probed.items(), key=lambda kv: kv[1])[:3]))
    # each refit starts from its best probe's change (the kept change may have the other sign for another kind)
    return own_onsets(setup, progress, settings, [replace(r, coef=probed[r.term.key][1]) for r in rows
                                                  if r.term.key in probed])


def own_onsets(setup: Any, progress: Any, settings: Any, rows: list[ScreenRow]) -> list[ScreenRow]:
    """``rows`` (probed at the kept instant) each with its onset moved to where the whole record's RMS is lowest
    near it (:data:`FAMILY_ONSET_PASSES`; at its change, within its slot's refit range). ``setup``, ``progress``,
    ``settings``: the rounds' objects."""
    if not rows:
        return rows
    slots = [setup.names[setup.terms.index(r.term)] for r in rows]
    found = [{cname: r.coef, str(gname): float(r.shape or 0.0)} for r, (cname, gname) in zip(rows, slots)]
    for span_s, step_s in FAMILY_ONSET_PASSES:
        tries = [[t for t in shifted_onsets(f, [str(g)], span_s, step_s) if _in_range(r.term, t[str(g)])]
                 for f, r, (_, g) in zip(found, rows, slots)]
        flat = [t for ts in tries for t in ts]
        scores = whole_scores(setup.targets, setup.models, progress.state.values, flat, settings.threads)
        progress.n_sims += len(flat) * len(setup.targets)
        at = 0
        for j, ts in enumerate(tries):
            mine = scores[at:at + len(ts)]
            if len(ts) and np.isfinite(mine).any():
                found[j] = ts[int(np.argmin(mine))]
            at += len(ts)
    return [replace(r, shape=f[str(g)]) for r, f, (_, g) in zip(rows, found, slots)]


def _in_range(term: Term, t0: float) -> bool:
    rng = term.shape_range
    return rng is None or rng[0] <= t0 <= rng[1]


def damage_like(term: Term, coef: float) -> bool:
    """Whether ``term`` at relative change ``coef`` moves its parameter the way damage does (:data:`DAMAGE_SIGN`;
    True for a parameter that may move either way and for terms that are not a parameter's own)."""
    sign = DAMAGE_SIGN.get(term.param) if term.placement == "damage" else None
    return sign is None or sign * coef > 0


#: the one-sided forms of a force on a mass: with a positive coefficient it lets go past its point (the words of
#: :func:`workbench.discover._effect_writer.describe_term`: "a support that lets go"; negative, "a stop")
LETS_GO = ("pos", "neg")


#: core parameters that no damage raises on one side of the motion or the drive: a patch does not gain authority
#: while its section bends one way (a stiffness may: a contact, a crack that closes)
NO_SWITCHED_GAIN = ("d_ep", "d_ep_i")


def damage_lead(setup: Any, progress: Any, settings: Any, best: Any) -> Any:
    """The refit that leads the verdict among a change and the changes the records cannot tell from it: when the
    kept event moves its parameter the way damage does not (a stiffness or a patch's authority gained, damping lost)
    and an event refitted at the same instant in this round (its place or kind family) moves its own the way damage
    does and explains the records alike (within the twins' tolerance), that one leads — the records cannot choose,
    and damage is what a monitor is there to see; the other stays named as its twin. The same for a patch's
    authority *gained* on one side of a switch (:data:`NO_SWITCHED_GAIN`; on MBIT.a a crack at the root opening for
    δ1 < 0 was said as "patch 3 … 25 % higher for δ3 < 0"): a damage-like switched change refitted this round
    leads. And a one-sided force on a mass that lets go past a point (:data:`LETS_GO`): a section's own stiffness
    lost past a point of its deflection, refitted this round (:mod:`workbench.discover._section_reading`) and alike,
    leads — a root crack held shut by a preload, opening past δ1 = 0.3 mm on the sweep, was said "a one-sided force
    on mass 1 (the root) … acting only when z1 > 298 µm: a support that lets go", the crack its twin at the same
    1.33 σ. ``best``: a ``BestRefit``."""
    term = setup.terms[best.index]
    cname, gname = setup.names[best.index]
    coef = float(best.outcome.values.get(cname, 0.0))
    why = "moves its parameter the way damage does not"
    if term.placement == "force_mass" and term.form in LETS_GO and coef > 0:
        def same(t: Term, b: Any, g: str | None) -> bool:
            return t.placement == "damage" and t.param == "k" and t.form in SIGN_GATES
        where, why = "(a section's own switch)", "is a force on a mass from outside the beam"
    elif term.placement != "damage" or damage_like(term, coef):
        return best
    elif is_timed(term) and gname is not None:
        t0 = float(best.outcome.values[gname])
        start, end = record_span(setup.targets)

        def same(t: Term, b: Any, g: str | None) -> bool:
            return is_timed(t) and g is not None \
                and abs(float(b.outcome.values.get(g, math.inf)) - t0) <= EDGE_SHARE * (end - start)
        where = "at the same instant"
    elif not is_timed(term) and term.param in NO_SWITCHED_GAIN:
        def same(t: Term, b: Any, g: str | None) -> bool:
            return t.placement == "damage" and not is_timed(t) and t.param in DAMAGE_SIGN
        where = "switched too"
    else:
        return best
    limit = max(best.held_rms_sigma, 1.0) * twin_tolerance(setup.n_held)
    alike = [b for b in progress.refits if b.held_rms_sigma <= limit
             and same(setup.terms[b.index], b, setup.names[b.index][1])
             and damage_like(setup.terms[b.index], float(b.outcome.values.get(setup.names[b.index][0], 0.0)))]
    if not alike:
        return best
    lead = min(alike, key=lambda b: b.held_rms_sigma)
    settings.say(f"  {term.key} ({best.held_rms_sigma:.4g} σ) {why}; "
                 f"{setup.terms[lead.index].key} ({lead.held_rms_sigma:.4g} σ) {where} explains the records alike "
                 "and moves its own the way damage does: it leads, the other is named as its twin")
    return lead


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
    return {"key": term.key, "placement": term.placement, "param": term.param, "index": term.index,
            "signal": term.signal,
            "form": term.form, "held_rms_sigma": outcome.held_rms_sigma, "judged_by": "refitted", "words": words}


def refit_twins(setup: Any, progress: Any, twins: list[dict[str, Any]], displaced: Any,
                chosen: Term) -> list[dict[str, Any]]:
    """``twins`` (of the ``chosen`` term) with each refitted one in the words of its own refit (its onset, switching
    point, size fitted, not the screen's), the ``displaced`` event first — and, beside it, the twin in another
    place that :func:`~workbench.discover._twins.place_first` picks (the displaced event took the first place and
    the list was cut to the first two: sections 1 and 2 losing 7 % at once on MBIT.a were said with the patches'
    authority as twins, section 2's own loss, 0.984 σ, cut)."""
    refits = {setup.terms[b.index].key: b for b in progress.refits}
    if displaced is not None:
        first = setup.terms[displaced.index].key
        twins = [{"key": first}, *(t for t in twins if t["key"] != first)]
    out = []
    for t in twins:
        b = refits.get(t["key"])
        out.append(event_twin(setup.terms[b.index], b.outcome, setup.names[b.index], setup.scales)
                   if b is not None else t)
    return out if displaced is None else place_first(chosen, out)
