"""``shm discover``: find a missing correction term beyond the effects library, name it, and write it as an effect.

1. **Dictionary.** Candidate terms from the model's own signals along the records
   (:mod:`workbench.discover._dictionary`: forces on masses and sections, currents into the patch charges, changes
   of the drive and of the measurement; linear, sign, |x|·x, polynomial, one-sided, dead-zone, clipped, saturating,
   time-weighted and delayed forms), with thresholds set from each signal's scale, and damage forms — every core
   parameter's own term switched by a gate (:mod:`workbench.discover._gates`: a breathing crack, free play, a
   polarity, a step or ramp at an onset t0 inside the record). All of them live in *one*
   generated effect whose coefficients are 0 (the nominal model), compiled once per machine whatever the records.
2. **Sensitivities.** One batch through the compiled integrator: member 0 is the current model, member k switches term
   k on with a small coefficient ε_k; (y_k − y_0)/ε_k is the change of the measured channels per unit coefficient —
   the term's *output sensitivity*. The search lives in this output space, where the data are (one tip laser), not in
   state derivatives.
3. **Screen (held-out).** Each term's coefficient by least squares on the training blocks; terms ranked by the
   held-out residual they leave.
4. **Refit.** The best few are refitted on the full nonlinear model (the fit engine's
   :class:`~workbench.fit._fitting.Objective`,
   coefficient and threshold/delay free, together with terms already kept) and judged on held-out data; a term is
   kept when it removes a clear share of what is left above the noise. A time-gated term's onset comes from the
   residual (where it leaves the noise), a probe of every time-gated term there and a scan around it
   (:func:`~workbench.discover._onset.onset_scan`): least squares alone cannot place a step. Forward selection:
   with a term kept, the sensitivities are recomputed around the new model and the next term is sought (up to
   ``max_terms``).
5. **Guards.** The kept model must run free (full rate, every record) without diverging; "not found" is an answer.

The result (:class:`Discovery`) names each kept term in words and units and carries the source of a readable effect
(:func:`workbench.discover._effect_writer.emit_effect_source`) that ``shm fit --add FILE.py`` refits.

:func:`discover` runs named stages: :func:`prepare_search` (dictionary, models, sensitivity steps, the nominal
residuals), the rounds of :mod:`workbench.discover._rounds` (sensitivities, screen, probes, refits, keep the best;
the backward step), the stability guard, and :func:`judge` (the verdict in words). The pieces live beside it:
:mod:`workbench.discover._results` (what it returns), :mod:`workbench.discover._dictionary_effect` (the generated
dictionary effect) and :mod:`workbench.discover._search` (refits, nonlinear probes, the stability guard).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence

import numpy as np

from board_config import ParameterSet, load_parameter_set
from plant import PhysicalEffect
from plant.effect import EffectError, resolve_effect
from workbench.discover._backward import backward_step, drop_idle
from workbench.discover._dictionary import build_dictionary
from workbench.discover._dictionary_code import (
    dictionary_parameter_names,
    dictionary_since_names,
    dictionary_source,
    dictionary_width_names,
    term_default_width,
)
from workbench.discover._dictionary_effect import (
    generated_effect,
    reference_magnitudes,
    signal_scales,
    term_scale,
)
from workbench.discover._event_side import side_step
from workbench.discover._finite_change import finite_changes, found_term
from workbench.discover._form_swap import placed_swap_step, swap_step
from workbench.discover._gates import SINCE_NEVER_S
from workbench.discover._joint_polish import polish_step
from workbench.discover._pair_refit import pair_step
from workbench.discover._patch_place import patch_step
from workbench.discover._place_swap import ABOVE_SIGMA as PLACE_ABOVE_SIGMA
from workbench.discover._place_swap import place_step
from workbench.discover._results import (
    DiscoverError,
    Discovery,
    FoundTerm,
    describe_units,
    in_one_sentence,
    noise_free_match,
)
from workbench.discover._rounds import (
    MIN_SHARE,
    SearchProgress,
    SearchSettings,
    SearchSetup,
    search_round,
)
from workbench.discover._search import SearchState, free_run_check
from workbench.discover._since_onset import since_step
from workbench.fit import (
    DEFAULT_BLOCKS,
    DEFAULT_MAX_RATE_HZ,
    Objective,
    explained,
    model_factory,
    noise_tolerance,
    prepare_targets,
    resolve_candidates,
    rms,
)
from workbench.records import FrfRecord, Record


def discover(records: Sequence[Record | FrfRecord], params: ParameterSet | str = "table2",
             add: Sequence[str | type[PhysicalEffect]] = (), *, max_terms: int = 2, n_refit: int = 4,
             holdout: str = "blocks", n_blocks: int = DEFAULT_BLOCKS, max_rate_Hz: float = DEFAULT_MAX_RATE_HZ,
             max_nfev: int = 12, threads: int | None = None, expect_change: bool = False,
             on_progress: Callable[[str], None] | None = None) -> Discovery:
    """Search the dictionary for the terms the model lacks on ``records`` (see the module docstring).

    ``expect_change``: the caller found the physics changed during the record (a split-record refit,
    :mod:`workbench.diagnose._time_change`): the time-gated terms are probed at the residual's onset and refitted
    first, before any term constant in time (whose refit may already reach the noise floor's tolerance, as a constant
    extra damping does for a damping that doubled half way)."""
    t_start = time.perf_counter()
    say = on_progress or (lambda _msg: None)
    timings: dict[str, float] = {}
    setup, state, n_sims = prepare_search(records, params, add, holdout=holdout, n_blocks=n_blocks,
                                          max_rate_Hz=max_rate_Hz, timings=timings)
    say(f"nominal model: training {setup.train_before:.4g} σ, held-out {setup.held_before:.4g} σ; "
        f"{len(setup.terms)} candidate terms")
    progress = SearchProgress(state, setup.train_before, setup.held_before, n_sims, timings)
    settings = SearchSettings(n_refit, max_nfev, threads, expect_change, say)
    timings["screen_s"] = 0.0
    timings["refit_s"] = 0.0
    for round_no in range(max_terms):
        if not search_round(setup, progress, settings, round_no):
            break
    polish_step(setup, progress, settings)
    swap_step(setup, progress, settings)
    moved = place_step(setup, progress, settings)
    for _ in range(2 if moved else 0):  # shapes chosen beside the old place, tried again (one swap may free another)
        if not swap_step(setup, progress, settings, above=PLACE_ABOVE_SIGMA):
            break
    patch_step(setup, progress, settings)
    side_step(setup, progress, settings)
    since_step(setup, progress, settings)
    placed_swap_step(setup, progress, settings)
    backward_step(setup, progress, settings)
    pair_step(setup, progress, settings)
    drop_idle(setup, progress, settings)
    # --- stability guard: the kept model in free run at the records' full rate
    t0 = time.perf_counter()
    stable, note = True, "no term kept"
    if progress.state.kept:
        stable, note = free_run_check([tg.record for tg in setup.targets], setup.models, setup.targets,
                                      progress.state.values)  # checked
    timings["stability_s"] = time.perf_counter() - t0
    verdict, msg, found = judge(setup, progress, found_terms(setup, progress), stable, note)
    timings["total_s"] = time.perf_counter() - t_start
    return Discovery(verdict, msg, found, setup.train_before, setup.held_before,
                     progress.current_train if found else setup.train_before,
                     progress.current_held if found else setup.held_before,
                     progress.screen_rows, len(setup.terms), stable, note, [tg.name for tg in setup.targets],
                     progress.outcome if found else None, setup.targets, progress.n_sims, timings, progress.rounds)


def prepare_search(records: Sequence[Record | FrfRecord], params: ParameterSet | str,
                   add: Sequence[str | type[PhysicalEffect]], *, holdout: str, n_blocks: int, max_rate_Hz: float,
                   timings: dict[str, float]) -> tuple[SearchSetup, SearchState, int]:
    """The records cut into targets, the dictionary for their signals' scales as one generated effect in every
    record's model (``timings["dictionary_s"]``), every term off (coefficient 0, shapes at the dictionary's), each
    term's sensitivity step and the nominal model's residuals; also the simulations that took."""
    base = load_parameter_set(params)
    try:
        classes = resolve_candidates(add)
    except EffectError as exc:
        raise DiscoverError(str(exc)) from None
    targets = prepare_targets(records, model_factory(base, classes), holdout=holdout, n_blocks=n_blocks,
                              max_rate_Hz=max_rate_Hz)
    t0 = time.perf_counter()
    scales, sig = signal_scales(targets)
    driven = all(next(c.name for c in tg.model.effects if c.role == "terminal") == "amplifier" for tg in targets)
    terms = build_dictionary(scales, driven=driven)
    names = dictionary_parameter_names(terms)
    dict_cls = generated_effect(dictionary_source(terms), "dictionary_" + ("driven" if driven else "open"))
    dict_build = model_factory(base, [*classes, dict_cls])
    models = [dict_build(tg.record) for tg in targets]
    timings["dictionary_s"] = time.perf_counter() - t0
    state = SearchState({}, [])
    for k, (cname, gname) in enumerate(names):
        state.values[cname] = 0.0
        if gname is not None:
            shaped = terms[k].shape > 0 or terms[k].shape_range is not None  # a switching point may be 0
            state.values[gname] = terms[k].shape if shaped else 1.0
    state.values.update({h: term_default_width(terms[k]) for k, h in dictionary_width_names(terms).items()})
    state.values.update(dict.fromkeys(dictionary_since_names(terms).values(), SINCE_NEVER_S))
    ref = reference_magnitudes(targets[0].model, scales)
    eps = np.array([ref[t.placement] / max(term_scale(t, sig, targets), 1e-300) for t in terms])
    base_obj = Objective(targets, models, [], base_values=state.values)
    base_sim = base_obj.simulate(np.zeros((1, 0)))
    train_before = rms(base_obj.residuals(base_sim, "train")[0])
    held_before = rms(base_obj.residuals(base_sim, "held")[0])
    n_held = sum(int(tg.held.sum()) * len(tg.channels) for tg in targets)
    setup = SearchSetup(targets, models, terms, names, scales, eps, n_held, train_before, held_before)
    return setup, state, base_obj.n_sims


def found_terms(setup: SearchSetup, progress: SearchProgress) -> list[FoundTerm]:
    """The kept terms with their fitted coefficients and shapes, in words (an onset time with its standard error)."""
    return finite_changes([found_term(setup.terms, setup.names, setup.scales, progress.state.values, progress.stderr,
                                      progress.twins.get(k, []), k) for k in progress.state.kept])


def judge(setup: SearchSetup, progress: SearchProgress, found: list[FoundTerm], stable: bool,
          note: str) -> tuple[str, str, list[FoundTerm]]:
    """The verdict (``found`` | ``partial`` | ``not_found``), its message, and the terms that stand (none when the
    kept model diverges in free run)."""
    held_before, n_held, current_held = setup.held_before, setup.n_held, progress.current_held
    if found and not stable:
        keys = ", ".join(f.term.key for f in found)
        return "not_found", (f"The best terms ({keys}) make the model diverge in free run ({note}): rejected. "
                             "Nothing in the dictionary explains the residual safely."), []
    if found and explained(current_held, held_before, n_held):
        return "found", ("Found: " + in_one_sentence(found)
                         + f". Held-out error {held_before:.4g} σ → {current_held:.4g} σ (noise floor 1 σ)."), found
    if found:
        return "partial", ("Partly found: " + in_one_sentence(found)
                           + f". Held-out error {held_before:.4g} σ → {current_held:.4g} σ — above the noise floor "
                           f"(≤ {1 + noise_tolerance(n_held):.3g} σ): something else is missing too."), found
    if held_before <= 1.0 + noise_tolerance(n_held):
        return "not_found", (f"Nothing to find: the nominal model is already at the noise floor ({held_before:.4g} σ "
                             "held-out)."), found
    if noise_free_match(setup.targets, held_before):
        return "not_found", ("Nothing to find: the records are noise-free and the nominal model matches them within "
                             "the simulation's own accuracy (held-out residual below 1e-5 of each channel's range)."), \
            found
    best_row = progress.screen_rows[0] if progress.screen_rows else None
    return "not_found", (f"Not found: no term of the dictionary ({len(setup.terms)} terms) removes at least "
                         f"{100 * MIN_SHARE:.0f} % of the held-out error above the noise (nominal {held_before:.4g} σ)"
                         + (f"; the closest was {best_row.term.key} ({best_row.held_rms_sigma:.4g} σ, linearised)."
                            if best_row else ".")), found


def load_emitted(path: str) -> type[PhysicalEffect]:
    """Load an emitted effect file through the documented seam (``resolve_effect('FILE.py')``)."""
    return resolve_effect(str(path))


__all__ = ["DiscoverError", "Discovery", "FoundTerm", "describe_units", "discover", "load_emitted"]
