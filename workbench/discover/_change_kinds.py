"""One event, two places, another kind (issue 26 point 3): an impact cracks two sections at the same instant, and the
round's best single step is a third thing that mimics both — on a 15 s sweep sections 2 and 3 each losing 12 % at
7.5 s (blind set 6) were kept as "mass m3 rose at t = 7.48 s" (116 σ held out): a heavier tip lowers the modes as
the two softer sections do, better than either section's loss alone. Every later step then works on the mass: its
places (m1, m2), its split into two masses, the other parameters changing alone at that instant (none within 348 σ).

So when the kept change is a step that still leaves far more than the noise, each other kind of damage step (a
section's stiffness or damping, a patch's own authority, a mass) is probed in every *pair* of places at the kept
instant, the kept step removed — both places changed alike or one twice the other, over a grid of the sizes damage
takes (:data:`SIZES`) — scored on the whole record; the best pair is refitted (both sizes and onsets free) and
replaces the kept step when it removes the round's share of the excess (:func:`kind_split_change`).

Pure logic on the fit engine's objects; :func:`~workbench.discover._kept_change.refine_kept` calls it.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
from typing import Any

from workbench.discover._change_pair import free_step
from workbench.discover._change_place import N_PLACES, change_slots, placed_free
from workbench.discover._dictionary import Term
from workbench.discover._event_check import DAMAGE_SIGN
from workbench.discover._finite_change import lowest, whole_scores
from workbench.discover._onset import shifted_onsets
from workbench.discover._results import excess_share_removed
from workbench.discover._search import refine
from workbench.fit import FitOutcome, Objective, noise_tolerance

#: the kinds of a damage step probed in pairs of places (a mass may move either way: a part lost, ice gained)
KINDS = ("k", "c", "m", "d_ep_i")
#: relative changes probed (in the way damage moves each kind, :data:`~workbench.discover._event_check.DAMAGE_SIGN`;
#: a mass both ways), and the second place's share of the first's change
SIZES = (0.05, 0.1, 0.2, 0.3)
DAMPING_SIZES = (0.5, 1.0, 2.0)
SECOND_SHARE = (0.5, 1.0, 2.0)
#: the pair's common onset is scanned (span either side, step; s) and the pair refitted, twice: first around the
#: kept onset with the grid's sizes, then around the refit's with its sizes (sections 2 and 3 losing 12 % at 7.5 s,
#: kept as a mass step at 7.48 s: one scan and refit left their onsets at 7.488 and 7.497 s, 2.69 σ)
ONSET_PASSES = ((0.1, 0.005), (0.02, 0.001))
#: a kept step is probed as another kind in two places only while the round leaves more than this (σ held out)
KIND_ABOVE_SIGMA = 3.0


def kind_sizes(param: str) -> tuple[float, ...]:
    """The relative changes a step of ``param`` is probed at: the way damage moves it, or both ways."""
    sign = DAMAGE_SIGN.get(param)
    sizes = DAMPING_SIZES if param == "c" else SIZES
    return tuple(sign * s for s in sizes) if sign is not None else (*(-s for s in sizes), *sizes)


def kind_tries(terms: Sequence[Term], names: Sequence[tuple[str, str | None]], slots: Sequence[int],
               t0: float) -> list[tuple[tuple[int, int], dict[str, float]]]:
    """Every pair of places of every other kind, stepping at ``t0`` with the kept ``slots`` off: ((slot a, slot
    b), the dictionary parameters)."""
    kept = terms[slots[0]]
    off = {names[k][0]: 0.0 for k in slots}
    out: list[tuple[tuple[int, int], dict[str, float]]] = []
    for param in KINDS:
        for a, b in itertools.combinations(range(N_PLACES), 2):
            like = Term("damage", a, "one", "on_step", t0, param)
            ka, kb = free_step(terms, like, a, slots), free_step(terms, like, b, slots)
            if ka is None or kb is None or (param == kept.param and kept.index in (a, b)):
                continue
            (ca, ga), (cb, gb) = names[ka], names[kb]
            for c in kind_sizes(param):
                for share in SECOND_SHARE:
                    setting = off | {ca: c, cb: share * c}
                    setting |= {str(g): t0 for g in (ga, gb) if g is not None}
                    if share * c > -0.9:  # no loss of the whole (a rise of damping may be several-fold)
                        out.append(((ka, kb), setting))
    return out


def common_onset(setup: Any, values: Mapping[str, float], pair: tuple[int, int], setting: dict[str, float],
                 threads: int | None, span_s: float, step_s: float) -> tuple[dict[str, float], int]:
    """``setting`` with the pair's common onset moved to where the whole record's RMS is lowest within ± ``span_s``
    of the first slot's (steps of ``step_s``): the kept step's onset fitted a mimic, and a least-squares refit hardly
    moves a sharp step's instant (its Jacobian is zero but for a sample or two). Also the simulations run."""
    tries = shifted_onsets(setting, [str(setup.names[k][1]) for k in pair], span_s, step_s)
    found = lowest(tries, whole_scores(setup.targets, setup.models, dict(values), tries, threads))
    return (found[0] if found is not None else setting), len(tries) * len(setup.targets)


def _pair_refit(setup: Any, progress: Any, settings: Any, others: list[int], pair: tuple[int, int],
                setting: dict[str, float]) -> tuple[dict[str, float], FitOutcome] | None:
    """The pair refitted from ``setting`` (sizes and onsets free, the other kept terms' sizes too): the start and
    the outcome, None when it fails. Each of :data:`ONSET_PASSES` scans the common onset first (its sizes the
    grid's, then the refit's) and refits; the best refit is returned."""
    state, best = progress.state, None
    for span_s, step_s in ONSET_PASSES:
        setting, n_scan = common_onset(setup, state.values, pair, setting, settings.threads, span_s, step_s)
        start = dict(state.values) | setting
        obj = Objective(setup.targets, setup.models,
                        placed_free(setup.terms, setup.names, others, start, list(pair), setup.scales["t"]),
                        base_values=start, threads=settings.threads)
        out = refine(obj, start, settings.max_nfev)
        progress.n_sims += n_scan + obj.n_sims
        if not out.ok:
            break
        if best is None or out.held_rms_sigma < best[1].held_rms_sigma:
            best = (start, out)
        setting = setting | {n: out.values[n] for k in pair for n in setup.names[k] if n in out.values}
    return best


def kind_split_change(setup: Any, progress: Any, settings: Any, min_share: float) -> None:
    """The step the round kept last, still far from the noise (:data:`KIND_ABOVE_SIGMA`), probed as another kind in
    two places at its instant (:func:`kind_tries`); the best pair refitted and kept in its stead when it removes
    ``min_share`` of the excess. ``setup``, ``progress``, ``settings``: the rounds' objects."""
    state = progress.state
    k = state.kept[-1]
    term = setup.terms[k]
    gname = setup.names[k][1]
    if (term.placement != "damage" or term.form != "on_step" or gname is None
            or progress.current_held <= KIND_ABOVE_SIGMA):
        return
    slots = change_slots(setup.terms, state.kept, term)
    tries = kind_tries(setup.terms, setup.names, slots, float(state.values[gname]))
    if not tries:
        return
    scores = whole_scores(setup.targets, setup.models, state.values, [s for _, s in tries], settings.threads)
    progress.n_sims += len(tries) * len(setup.targets)
    found = lowest(tries, scores)
    if found is None:
        return
    (pair, setting), _ = found
    others = [j for j in state.kept if j not in slots]
    refit = _pair_refit(setup, progress, settings, others, pair, setting)
    if refit is None:
        return
    start, out = refit
    h = out.held_rms_sigma
    gain = excess_share_removed(progress.current_held, h, noise_tolerance(setup.n_held))
    keep = gain is not None and gain >= min_share and h < progress.current_held
    keys = [setup.terms[j].key for j in pair]
    settings.say(f"  {term.key} as {' and '.join(keys)} at its instant ({h:.4g} σ held-out, here "
                 f"{progress.current_held:.4g} σ): " + ("they replace it" if keep else "not kept"))
    progress.rounds.append({"kind_split": {"term": term.key, "as": keys, "held_rms_sigma": h, "kept": keep}})
    if not keep:
        return
    state.kept[:] = [*others, *pair]
    state.values.update(start | out.values)
    progress.twins.pop(k, None)
    progress.adopt(out)
