"""Where a change over time happened, when the records leave it open (issue 26 point 3): the kept change — a
step, a window of two ramps, two steps, an S-curve, a ramp that settles — refitted as the same change of the same
parameter in each other section (mass, patch), timing and shape held (:func:`place_refit`).

Why it is needed: a record that excites one mode (an MBIT) moves the beam alike for a stiffness lost in section 2
and in section 3, only the size differs. The round's place family (:func:`~workbench.discover._event_check.
place_family`) refits a *step* in the other places; once the step is given an end or a time scale
(:mod:`workbench.discover._kept_change`) the step's twins are no twins of the refined change, and a straight loss of
k2 over 8–12 s of MBIT.a was said "section 3 lost 30 % of its stiffness between t = 8.000 s and t = 11.99 s" (1.04 σ
held out), section 2 never named — the step in section 2 had trailed the step in section 3 before either had an end.
So after the refinement, when the change nearly explains the records (:data:`~workbench.discover._twins.
PLACE_BELOW_SIGMA`), its counterpart in each other place is probed at a few sizes on the full model and, when it
comes near, refitted (sizes free, onsets within :data:`~workbench.discover._finite_change.ONSET_FREE_S`). One that
fits clearly better takes the change's place (the old place named as its twin); one within the twins' tolerance is
named as a twin (:func:`place_change`). On a sweep the places are told apart and the probes stop it.

Pure logic on the fit engine's objects; the rounds (:mod:`workbench.discover._kept_change`) keep the result.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from board_config.parameter import Parameter, freed
from workbench.discover._dictionary import Term
from workbench.discover._dictionary_code import since_name, width_name
from workbench.discover._event_check import PLACE_NEAR, PLACE_PROBES, is_timed
from workbench.discover._finite_change import (
    ONSET_FREE_S,
    finite_changes,
    found_term,
    lowest,
    others_free,
    whole_rms,
    whole_scores,
)
from workbench.discover._gates import SIDED_GATES, onset_floor
from workbench.discover._onset import MAX_LOSS
from workbench.discover._search import SearchState, refine
from workbench.discover._twins import MAX_TWINS, PLACE_BELOW_SIGMA, twin_tolerance
from workbench.fit import FitOutcome, Objective

#: places (sections, masses, patches) a per-place parameter has
N_PLACES = 3
#: a change that leaves more than PLACE_BELOW_SIGMA moves to another place only when there it leaves at most this
#: share of its held-out error (far from the noise a place that fits a little better is the next round's business:
#: a tip stop kept as c3 × [δ̇3 > 0] at 95 σ fitted 79.6 σ in section 2's place, and the stop was 0.98 σ)
FAR_MOVE_SHARE = 0.5


def change_slots(terms: Sequence[Term], kept: Sequence[int], term: Term) -> list[int]:
    """The kept time-gated damage terms of ``term``'s parameter and place (dictionary indices, in kept order): the
    pieces of one change (a window's two ramps, two steps, a step and its settling); a switch on a voltage
    (:func:`placeable`) is its own one piece."""
    if not is_timed(term):
        return [k for k in kept if terms[k] == term]
    return [k for k in kept if terms[k].placement == "damage" and is_timed(terms[k])
            and (terms[k].param, terms[k].index) == (term.param, term.index)]


def placeable(term: Term) -> bool:
    """Whether a kept term is placed by :func:`place_change`: a per-place damage term gated in time, or gated by a
    voltage — a sign switch, a smooth edge, a change growing with the voltage (the drive's, a patch's own: the same
    volts in each patch, so the switching point, edge or saturation moves with the change; a deflection's switching
    point would need mapping between sections)."""
    if term.placement != "damage" or term.index < 0:
        return False
    on_volts = term.form in SIDED_GATES
    return is_timed(term) or (on_volts and (term.signal in ("va", "ic") or term.signal.startswith("vc")))


def counterpart(terms: Sequence[Term], slot: int, index: int) -> int | None:
    """The dictionary index of ``slot``'s term at another ``index`` (section, mass, patch): same placement, parameter
    and form, the same rank among that form's slots there (a window's second ramp maps to the second ramp)."""
    t = terms[slot]

    def slots_at(i: int) -> list[int]:
        return [k for k, u in enumerate(terms)
                if (u.placement, u.param, u.form, u.index) == (t.placement, t.param, t.form, i)]

    mine, there = slots_at(t.index), slots_at(index)
    rank = mine.index(slot)
    return there[rank] if rank < len(there) else None


def transplant(values: Mapping[str, float], names: Sequence[tuple[str, str | None]], mapping: Mapping[int, int],
               size: float, keep: float = 0.0) -> dict[str, float]:
    """The dictionary parameters that move a change from its slots to theirs (``mapping``): each counterpart's
    coefficient ``size`` × the slot's, its onset and fitted width the slot's, the slot's own coefficient ``keep`` ×
    itself (0: moved; above: the change in both places)."""
    out: dict[str, float] = {}
    for k, k2 in mapping.items():
        (c, g), (c2, g2) = names[k], names[k2]
        out[c], out[c2] = keep * float(values[c]), size * float(values[c])
        if g is not None and g2 is not None:
            out[g2] = float(values[g])
        if width_name(k) in values:
            out[width_name(k2)] = float(values[width_name(k)])
        if since_name(k) in values and since_name(k2) in values:  # a switched change begun at an instant
            out[since_name(k2)] = float(values[since_name(k)])
    return out


@dataclass(frozen=True)
class PlacedChange:
    """The change refitted in another place: its slots (in the order of the slots it mirrors), the refit, every
    dictionary value with it and the simulations run."""

    slots: tuple[int, ...]
    outcome: FitOutcome
    values: dict[str, float]
    n_sims: int


def placed_free(terms: Sequence[Term], names: Sequence[tuple[str, str | None]], kept: Sequence[int],
                start: dict[str, float], slots: Sequence[int], t_end: float) -> list[Parameter]:
    """Free parameters of a moved change's refit: the other kept terms' coefficients (±1.5 × their size), each
    moved slot's coefficient (±2 × it, a loss never past ``MAX_LOSS``) and onset (± ``ONSET_FREE_S``; a switch's
    point stays where it was copied: a voltage at −2.4 V is no instant of the record)."""
    out = others_free(terms, names, SearchState(start, list(kept)), start, (-1, -1), -1)
    for k in slots:
        cname, gname = names[k]
        c = start[cname]
        lo = max(c - 2.0 * abs(c), MAX_LOSS) if terms[k].unit == "1" else c - 2.0 * abs(c)
        out.append(freed(cname, terms[k].unit, lo, c + 2.0 * abs(c), False, "discover"))
        if gname is not None and is_timed(terms[k]):  # a switch keeps its switching point (volts, copied)
            g = start[gname]
            out.append(freed(gname, "s", onset_floor(g, ONSET_FREE_S), min(g + ONSET_FREE_S, t_end), False,
                             "discover"))
    return out


def place_refit(setup: Any, state: SearchState, slots: Sequence[int], index: int | Sequence[int], near: float,
                threads: int | None, max_nfev: int) -> PlacedChange | None:
    """The change held by ``slots`` moved to ``index`` (another section, mass or patch; or one place per slot, a
    slot at its own place staying there): probed at :data:`~workbench.discover._event_check.PLACE_PROBES` × its
    size over the whole record, refitted when the best probe leaves at most ``near`` (σ, whole record); None when a
    counterpart is missing or kept already, no probe integrates or none comes near. ``setup``: the rounds'
    objects."""
    places = [index] * len(slots) if isinstance(index, int) else list(index)
    stay = {k for k, i in zip(slots, places) if setup.terms[k].index == i}
    mapping = {k: counterpart(setup.terms, k, i) for k, i in zip(slots, places) if k not in stay}
    if not mapping or any(k2 is None or k2 in state.kept for k2 in mapping.values()):
        return None
    moves = {k: int(k2) for k, k2 in mapping.items() if k2 is not None}
    settings = [transplant(state.values, setup.names, moves, m) for m in PLACE_PROBES]
    found = lowest(settings, whole_scores(setup.targets, setup.models, state.values, settings, threads))
    n_sims = len(settings) * len(setup.targets)
    if found is None or found[1] > near:
        return None
    start = dict(state.values) | found[0]
    new = tuple(k if k in stay else moves[k] for k in slots)
    others = [k for k in state.kept if k not in slots]
    obj = Objective(setup.targets, setup.models, placed_free(setup.terms, setup.names, others, start, new,
                                                             setup.scales["t"]), base_values=start, threads=threads)
    out = refine(obj, start, max_nfev)
    if not out.ok:
        return None
    return PlacedChange(new, out, start | out.values, n_sims + obj.n_sims)


def change_twin(setup: Any, values: Mapping[str, float], stderr: Mapping[str, float], slots: Sequence[int],
                held: float) -> dict[str, Any]:
    """The change held by ``slots`` at ``values`` as a twin (in :func:`~workbench.discover._twins.twins_of`'s
    format): said as the verdict says a kept change (a window's two ramps as one change)."""
    found = finite_changes([found_term(setup.terms, setup.names, setup.scales, values, stderr, [], k) for k in slots])
    lead = next(f for f in found if not f.said_with)
    term = lead.term
    return {"key": term.key, "placement": term.placement, "param": term.param, "index": term.index,
            "signal": term.signal,
            "form": term.form, "held_rms_sigma": held, "judged_by": "refitted",
            "words": "; ".join(f.words for f in found if not f.said_with)}


def lead_slot(values: Mapping[str, float], names: Sequence[tuple[str, str | None]], slots: Sequence[int]) -> int:
    """The slot whose words lead a change (the earliest onset: a window's rise, the first of two steps)."""
    return min(slots, key=lambda k: float(values.get(str(names[k][1]), math.inf)))


def place_choices(index: int, forms: Sequence[str]) -> list[int | tuple[int, ...]]:
    """Where a change of pieces of ``forms`` at place ``index`` is refitted: each other place whole, and a change of
    two steps (two losses, a loss and its partial recovery) also each step in its own place (a window's two ramps,
    a step and its settling are one change: they move whole) — two losses in two
    sections at two instants (MBIT.a, k1 −6 % at 5 s and k3 −6 % at 12 s, was kept as two steps of k3 and said
    "section 3 lost 5.99 % … at 4.997 s; and section 3 lost 5.33 % … at 11.998 s", 0.984 σ, section 1 never named:
    its place was probed only for both steps at once, 1.394 σ)."""
    whole: list[int | tuple[int, ...]] = [i for i in range(N_PLACES) if i != index]
    if list(forms) != ["on_step", "on_step"]:
        return whole
    return whole + [ij for ij in itertools.product(range(N_PLACES), repeat=2) if ij[0] != ij[1]]


def place_change(setup: Any, progress: Any, settings: Any) -> None:
    """The change the round kept last (``progress.state.kept[-1]``, :func:`placeable`) refitted in each other place
    (:func:`place_refit`). When it leaves at most :data:`PLACE_BELOW_SIGMA`, a place that fits clearly better
    (beyond the twins' tolerance) takes it, the old place named as its twin, and places within the tolerance are
    named as twins of the change; farther from the noise a place takes it only when it leaves at most
    :data:`FAR_MOVE_SHARE` of its error (no twins named). ``setup``, ``progress``, ``settings``: the rounds'
    objects."""
    state = progress.state
    term = setup.terms[state.kept[-1]]
    if not placeable(term):
        return
    slots = change_slots(setup.terms, state.kept, term)
    h, tol = progress.current_held, twin_tolerance(setup.n_held)
    far = h > PLACE_BELOW_SIGMA  # far from the noise: a place that halves the error takes it, no twins named
    tol = 1.0 / FAR_MOVE_SHARE if far else tol
    near = PLACE_NEAR * max(whole_rms(setup.targets, progress.outcome), 1.0) if progress.outcome else math.inf
    placed = [p for i in place_choices(term.index, [setup.terms[k].form for k in slots])
              if (p := place_refit(setup, state, slots, i, near, settings.threads, settings.max_nfev)) is not None]
    progress.n_sims += sum(p.n_sims for p in placed)
    for p in placed:
        where = " and ".join(dict.fromkeys(f"{setup.terms[k].key}'s" for k in p.slots))
        settings.say(f"  the change in {where} place: {p.outcome.held_rms_sigma:.4g} σ held-out (here {h:.4g} σ)")
    best = min(placed, key=lambda p: p.outcome.held_rms_sigma, default=None)
    old_lead = lead_slot(state.values, setup.names, slots)  # its twins: a plain step's, refitted with its onset
    old: list[dict[str, Any]] = []
    if best is not None and best.outcome.held_rms_sigma * tol < h:  # the old place is no twin: clearly worse
        state.kept = [k for k in state.kept if k not in slots] + list(best.slots)
        state.values.update(best.values)
        progress.adopt(best.outcome)
        for k in slots:
            progress.twins.pop(k, None)
        settings.say(f"  the change moves to {setup.terms[best.slots[0]].key}'s place: it fits clearly better")
        slots, h = list(best.slots), best.outcome.held_rms_sigma
        placed = [p for p in placed if p is not best]
    elif not far:
        old = progress.twins.pop(old_lead, [])
    if far:
        return
    alike = [change_twin(setup, p.values, {e.name: e.stderr for e in p.outcome.estimates}, p.slots,
                         p.outcome.held_rms_sigma)
             for p in sorted(placed, key=lambda p: p.outcome.held_rms_sigma)
             if p.outcome.held_rms_sigma <= max(h, 1.0) * tol]
    named = list({t["key"]: t for t in [*alike, *old]}.values())[:MAX_TWINS]
    if named:
        progress.twins[lead_slot(state.values, setup.names, slots)] = named
