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

:func:`discover` runs the rounds; the pieces live beside it: :mod:`workbench.discover._results` (what it returns),
:mod:`workbench.discover._dictionary_effect` (the generated dictionary effect) and :mod:`workbench.discover._search`
(refits, nonlinear probes, the stability guard).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from board_config import ParameterSet, load_parameter_set
from board_config.parameter import freed
from plant import PhysicalEffect
from plant.effect import EffectError, resolve_effect
from workbench.discover._dictionary import DELAY_FORMS, Term, build_dictionary
from workbench.discover._dictionary_code import dictionary_parameter_names, dictionary_source
from workbench.discover._dictionary_effect import (
    generated_effect,
    reference_magnitudes,
    signal_scales,
    term_scale,
)
from workbench.discover._effect_writer import describe_term
from workbench.discover._gates import TIME_GATES
from workbench.discover._onset import change_point, onset_probe, onset_scan, with_onsets
from workbench.discover._results import (
    DiscoverError,
    Discovery,
    FoundTerm,
    ScreenRow,
    describe_units,
    excess_share_removed,
    noise_free_match,
)
from workbench.discover._search import (
    SearchState,
    free_for,
    free_run_check,
    nonlinear_check,
    other_delay_order,
    refine,
    refit_list,
)
from workbench.fit import (
    DEFAULT_BLOCKS,
    DEFAULT_MAX_RATE_HZ,
    FitOutcome,
    Objective,
    explained,
    model_factory,
    noise_tolerance,
    prepare_targets,
    resolve_candidates,
    rms,
)
from workbench.records import FrfRecord, Record

#: a term is kept when its refit removes at least this share of the held-out energy left above the noise
MIN_SHARE = 0.25
#: integrator tolerance of the sensitivity batch (tighter than the fits: differences of near-equal runs)
SENS_RTOL = 1e-7


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
    stderr: dict[str, float] = {}  # standard errors of the kept terms' parameters, from the refit that kept them
    for k, (cname, gname) in enumerate(names):
        state.values[cname] = 0.0
        if gname is not None:
            state.values[gname] = terms[k].shape if terms[k].shape > 0 else 1.0
    ref = reference_magnitudes(targets[0].model, scales)
    eps = np.array([ref[t.placement] / max(term_scale(t, sig, targets), 1e-300) for t in terms])
    n_sims = 0
    base_obj = Objective(targets, models, [], base_values=state.values)
    base_sim = base_obj.simulate(np.zeros((1, 0)))
    n_sims += base_obj.n_sims
    train_before = rms(base_obj.residuals(base_sim, "train")[0])
    held_before = rms(base_obj.residuals(base_sim, "held")[0])
    n_held = sum(int(tg.held.sum()) * len(tg.channels) for tg in targets)
    say(f"nominal model: training {train_before:.4g} σ, held-out {held_before:.4g} σ; {len(terms)} candidate terms")
    current_train, current_held = train_before, held_before
    outcome: FitOutcome | None = None
    screen_rows: list[ScreenRow] = []
    rounds: list[dict[str, Any]] = []
    twins: dict[int, list[dict[str, Any]]] = {}
    timings["screen_s"] = 0.0
    timings["refit_s"] = 0.0
    for round_no in range(max_terms):
        if explained(current_held, held_before, n_held) and round_no > 0:
            break
        if held_before <= 1.0 + noise_tolerance(n_held) or noise_free_match(targets, held_before):
            break  # at the noise floor (or a noise-free record matched numerically): among 200 terms one fits noise
        # --- sensitivities: one batch, member k+1 switches term k on with eps_k
        t0 = time.perf_counter()
        cand = [k for k in range(len(terms)) if k not in state.kept]
        names_free = [freed(names[k][0], terms[k].unit, -1e300, 1e300, False, "discover") for k in cand]
        obj = Objective(targets, models, names_free, base_values=state.values, rtol=SENS_RTOL, threads=threads)
        U = np.zeros((len(cand) + 1, len(cand)))
        # unit box of a linear [-1e300, 1e300] range: u = 0.5 + v / 2e300 — set the values directly instead
        P_rows = []
        for i in range(len(targets)):
            P = np.tile(obj._p0[i], (len(cand) + 1, 1))
            for j, k in enumerate(cand):
                P[j + 1, obj._cols[i][j]] += eps[k]
            P_rows.append(P)
        ys, ok = [], np.ones(len(cand) + 1, bool)
        for tg, m, P in zip(targets, models, P_rows):
            res = m.simulate(tg.inputs, t_out=tg.t, params=P, rtol=SENS_RTOL, threads=threads,
                             max_steps=Objective.max_steps(tg))
            y = res.y[:, :, tg.out_idx(m)].transpose(0, 2, 1)
            ok &= (res.status == 0) & np.all(np.isfinite(y), axis=(1, 2))
            ys.append(y)
        del U
        n_sims += (len(cand) + 1) * len(targets)
        if not ok[0]:
            if round_no == 0:
                raise DiscoverError("the current model fails to integrate on the records")
            # the model with the kept terms integrated in the refit but not at the sensitivities' tighter tolerance
            # (a stiff hard-form term): keep what was found, say why the search stopped
            say(f"round {round_no + 1}: the model with the kept terms fails to integrate at rtol {SENS_RTOL:g}; "
                "the search stops with what it kept")
            rounds.append({"stopped": f"the model with the kept terms fails to integrate at rtol {SENS_RTOL:g}"})
            break
        r_tr: list[np.ndarray] = []
        r_he: list[np.ndarray] = []
        X_tr: list[np.ndarray] = []
        X_he: list[np.ndarray] = []
        for tg, y in zip(targets, ys):
            for part, rr, XX in (("train", r_tr, X_tr), ("held", r_he, X_he)):
                mask = tg.train if part == "train" else tg.held
                meas = tg.measured[:, mask] / tg.sigma[:, None]
                y0 = y[0][:, mask] / tg.sigma[:, None]
                rr.append((meas - y0).ravel())
                sens = (y[1:, :, :][:, :, mask] - y[0][None, :, mask]) / tg.sigma[None, :, None]
                XX.append(sens.reshape(sens.shape[0], -1) / eps[cand][:, None])
        r_tr_v, r_he_v = np.concatenate(r_tr), np.concatenate(r_he)
        Xtr, Xhe = np.concatenate(X_tr, axis=1), np.concatenate(X_he, axis=1)
        rows = []
        for j, k in enumerate(cand):
            if not ok[j + 1]:
                continue
            x = Xtr[j]
            den = float(x @ x)
            if not den > 0 or not np.isfinite(den):
                continue
            a = float(x @ r_tr_v) / den
            rows.append(ScreenRow(terms[k], a, rms(r_he_v - a * Xhe[j]), rms(r_tr_v - a * x)))
        rows.sort(key=lambda r: r.held_rms_sigma)

        def refit_row(row: ScreenRow) -> FitOutcome | None:
            nonlocal n_sims
            k = terms.index(row.term)
            start = dict(state.values)
            start[names[k][0]] = row.coef
            if row.term.form in TIME_GATES:  # an onset time: start the refit from a scan around its onset
                scan, n_probes = onset_scan(row, names[k], targets, models, state.values, (0.0, scales["t"]),
                                            threads)
                start.update(scan)
                n_sims += n_probes * len(targets)
            free = free_for(terms, names, [*state.kept, k], start, k)
            robj = Objective(targets, models, free, base_values=state.values, threads=threads)
            out = refine(robj, start, max_nfev)
            n_sims += robj.n_sims
            if not out.ok:
                return None
            # a coefficient at its range bound: widen once (the linearised start underestimated it)
            if any(e.at_bound and e.name.startswith("a_") for e in out.estimates):
                start2 = dict(start) | out.values
                free2 = free_for(terms, names, [*state.kept, k], start2, k)
                robj2 = Objective(targets, models, free2, base_values=state.values, threads=threads)
                out2 = refine(robj2, start2, max_nfev)
                n_sims += robj2.n_sims
                if out2.ok and out2.train_rms_sigma < out.train_rms_sigma:
                    out = out2
            return out

        best: tuple[float, int, FitOutcome] | None = None
        tried = []
        # fast path: the linearised screen already reaches the noise floor with one term — confirm it on the full
        # model before probing every term nonlinearly
        fast = bool(rows) and explained(rows[0].held_rms_sigma, held_before, n_held) and not expect_change
        if fast:
            t1 = time.perf_counter()
            # the best row, for a delay the best row of its other Padé order (the linearised screen barely tells
            # them apart; a strong delay needs the second order), and the next rows that also explain the records on
            # the screen: a term acting through the (hysteretic) structure is linearised less exactly than one in the
            # measurement, so its refit, not its screen value, says whether it is a twin
            also = [r for r in rows[1:1 + FAST_ALSO] if explained(r.held_rms_sigma, held_before, n_held)]
            todo: list[ScreenRow] = []
            for row in [rows[0], *other_delay_order(rows, rows[0]), *also]:
                if all(row is not r for r in todo):
                    todo.append(row)
            for row in todo:
                out = refit_row(row)
                if out is not None and explained(out.held_rms_sigma, held_before, n_held):
                    tried.append({"term": row.term.key, "held_rms_sigma": out.held_rms_sigma,
                                  "train_rms_sigma": out.train_rms_sigma})
                    if best is None or out.held_rms_sigma < best[0]:
                        best = (out.held_rms_sigma, terms.index(row.term), out)
            timings["refit_s"] += time.perf_counter() - t1
        onset_rows: list[ScreenRow] = []
        if best is None:
            # a damage event: where the residual changes its level, every time-gated key probed there
            t_hat = max((change_point(tg.t, (tg.measured - y[0]) / tg.sigma[:, None]) for tg, y in zip(targets, ys)),
                        key=lambda cp: cp[1])[0]
            onset_rows, n_probes = onset_probe(rows, dict(zip(terms, names)), targets, models, state.values, t_hat,
                                               scales["t"], threads)
            n_sims += n_probes * len(targets)
            rows, n_probes = nonlinear_check(rows, terms, targets, models, state.values, names, threads)
            n_sims += n_probes * len(targets)
        timings["screen_s"] += time.perf_counter() - t0
        if round_no == 0:
            screen_rows = rows[:12]
        say(f"round {round_no + 1}: screened {len(rows)} terms in {time.perf_counter() - t0:.2g} s; best "
            + ("by the linearised screen, confirmed on the full model" if best is not None else
               "on the full model at the screened coefficients") + " (held-out): "
            + ", ".join(f"{r.term.key} {r.held_rms_sigma:.3g} σ" for r in rows[:4]))
        # --- refit the best few on the full nonlinear model
        t0 = time.perf_counter()
        todo = [] if best is not None else with_onsets(refit_list(rows, n_refit), onset_rows, first=expect_change)
        for row in todo:
            k = terms.index(row.term)
            out = refit_row(row)
            if out is None:
                continue
            tried.append({"term": row.term.key, "held_rms_sigma": out.held_rms_sigma,
                          "train_rms_sigma": out.train_rms_sigma})
            if best is None or out.held_rms_sigma < best[0]:
                best = (out.held_rms_sigma, k, out)
            if out.held_rms_sigma <= 1.0 + noise_tolerance(n_held):  # at the noise floor: nothing can do better
                break
        timings["refit_s"] += time.perf_counter() - t0
        rounds.append({"screened": [(r.term.key, r.held_rms_sigma) for r in rows[:n_refit]], "refitted": tried})
        if best is None:
            break
        h_new, k_new, out = best
        twins[k_new] = _twins(terms[k_new], h_new, rows, tried, n_held, scales, linearised=fast)
        gain = excess_share_removed(current_held, h_new, noise_tolerance(n_held))
        say(f"  best refit: {terms[k_new].key}: held-out {current_held:.4g} σ → {h_new:.4g} σ "
            + (f"({100 * gain:.0f} % of the excess removed)" if gain is not None else "(no excess over the noise)"))
        if gain is None or gain < MIN_SHARE or h_new >= current_held:
            break
        state.kept.append(k_new)
        state.values.update(out.values)
        stderr.update({e.name: e.stderr for e in out.estimates})
        current_train, current_held = out.train_rms_sigma, h_new
        outcome = out
    # --- backward step: a later term alone may explain more than the set its first pick led to (a strong stop at
    # the tip was first taken for a clearance in section 3, and the stop found second carried the record alone)
    if len(state.kept) > 1 and current_held > 1.0 + noise_tolerance(n_held):
        t0 = time.perf_counter()
        for k in state.kept[1:]:
            start = dict(state.values) | {names[j][0]: 0.0 for j in state.kept if j != k}
            robj = Objective(targets, models, free_for(terms, names, [k], start, k), base_values=start,
                             threads=threads)
            alone = refine(robj, start, max_nfev)
            n_sims += robj.n_sims
            if alone.ok and alone.held_rms_sigma < current_held:
                say(f"backward step: {terms[k].key} alone leaves {alone.held_rms_sigma:.4g} σ held-out, the set "
                    f"{current_held:.4g} σ: the set is replaced by it")
                rounds.append({"backward": {"kept_alone": terms[k].key, "held_rms_sigma": alone.held_rms_sigma,
                                            "set_held_rms_sigma": current_held}})
                state.kept = [k]
                state.values = start | alone.values
                stderr.update({e.name: e.stderr for e in alone.estimates})
                current_train, current_held, outcome = alone.train_rms_sigma, alone.held_rms_sigma, alone
                break
        timings["refit_s"] += time.perf_counter() - t0
    # --- stability guard: the kept model in free run at the records' full rate
    t0 = time.perf_counter()
    stable, note = True, "no term kept"
    if state.kept:
        stable, note = free_run_check([tg.record for tg in targets], models, targets, state.values)  # checked
    timings["stability_s"] = time.perf_counter() - t0
    found = []
    for k in state.kept:
        cname, gname = names[k]
        coef = state.values[cname]
        shape = state.values[gname] if gname else 0.0
        scale = scales.get(terms[k].signal, 1.0)
        found.append(FoundTerm(terms[k].with_shape(shape), coef, shape, scale,
                               describe_term(terms[k], coef, shape, scale, stderr.get(gname) if gname else None),
                               twins.get(k, [])))
    if found and not stable:
        verdict = "not_found"
        msg = (f"The best terms ({', '.join(f.term.key for f in found)}) make the model diverge in free run "
               f"({note}): rejected. Nothing in the dictionary explains the residual safely.")
        found = []
    elif found and explained(current_held, held_before, n_held):
        verdict = "found"
        msg = ("Found: " + "; and ".join(f.description for f in found)
               + f". Held-out error {held_before:.4g} σ → {current_held:.4g} σ (noise floor 1 σ).")
    elif found:
        verdict = "partial"
        msg = ("Partly found: " + "; and ".join(f.description for f in found)
               + f". Held-out error {held_before:.4g} σ → {current_held:.4g} σ — above the noise floor "
               f"(≤ {1 + noise_tolerance(n_held):.3g} σ): something else is missing too.")
    else:
        verdict = "not_found"
        best_row = screen_rows[0] if screen_rows else None
        msg = (f"Not found: no term of the dictionary ({len(terms)} terms) removes at least {100 * MIN_SHARE:.0f} % "
               f"of the held-out error above the noise (nominal {held_before:.4g} σ)"
               + (f"; the closest was {best_row.term.key} ({best_row.held_rms_sigma:.4g} σ, linearised)."
                  if best_row else "."))
        if held_before <= 1.0 + noise_tolerance(n_held):
            msg = f"Nothing to find: the nominal model is already at the noise floor ({held_before:.4g} σ held-out)."
        elif noise_free_match(targets, held_before):
            msg = ("Nothing to find: the records are noise-free and the nominal model matches them within the "
                   "simulation's own accuracy (held-out residual below 1e-5 of each channel's range).")
    timings["total_s"] = time.perf_counter() - t_start
    return Discovery(verdict, msg, found, train_before, held_before,
                     current_train if found else train_before, current_held if found else held_before,
                     screen_rows, len(terms), stable, note, [tg.name for tg in targets], outcome if found else None,
                     targets, n_sims, timings, rounds)


#: on the fast path, up to this many further rows that also reach the noise floor on the screen are refitted too
FAST_ALSO = 3
#: at most this many twins are named per kept term
MAX_TWINS = 2
#: a twin's held-out RMS may exceed the chosen term's by this share (model tolerance) plus three standard
#: deviations of the RMS of white noise over the held-out samples
TWIN_MODEL_SHARE = 0.02


def twin_tolerance(n_held: int) -> float:
    """Factor on the chosen term's held-out RMS within which another term explains the records as well."""
    return 1.0 + TWIN_MODEL_SHARE + 3.0 / math.sqrt(2.0 * max(n_held, 1))


def _twins(chosen: Term, held: float, rows: Sequence[ScreenRow], tried: Sequence[dict[str, Any]], n_held: int,
           scales: Mapping[str, float], linearised: bool) -> list[dict[str, Any]]:
    """Other terms that explain the records as well as ``chosen`` (held-out RMS ``held``) within the noise
    (:func:`twin_tolerance`): refitted ones by their refit; when the chosen term came from the linearised screen
    (``linearised``: the fast path), the rest by that screen against the chosen term's own screen value. Same-key
    terms (another shape of the same form) and the other Padé order of the same delay are not twins."""
    tol = twin_tolerance(n_held)
    refitted = {t["term"]: t["held_rms_sigma"] for t in tried}
    mine = next((r.held_rms_sigma for r in rows if r.term.key == chosen.key), held)
    out: list[dict[str, Any]] = []
    seen = {chosen.key}
    for r in rows:
        key = r.term.key
        same_delay = ((r.term.placement, r.term.signal) == (chosen.placement, chosen.signal)
                      and {r.term.form, chosen.form} <= set(DELAY_FORMS))  # the same delay, another Padé order
        if key in seen or same_delay:
            continue
        seen.add(key)
        if key in refitted:
            h, how = refitted[key], "refitted"
            ok = h <= max(held, 1.0) * tol
        elif not linearised:  # screened on the full model at a linearised coefficient: not comparable to a refit
            continue
        else:
            h, how = r.held_rms_sigma, "screen"
            ok = h <= max(mine, 1.0) * tol  # the screen against the chosen term's own screen value
        if ok:
            scale = scales.get(r.term.signal, 1.0)
            out.append({"key": key, "placement": r.term.placement, "index": r.term.index, "signal": r.term.signal,
                        "form": r.term.form, "held_rms_sigma": h, "judged_by": how,
                        "words": describe_term(r.term, r.coef, r.term.shape, scale)})
        if len(out) >= MAX_TWINS:
            break
    return out


def load_emitted(path: str) -> type[PhysicalEffect]:
    """Load an emitted effect file through the documented seam (``resolve_effect('FILE.py')``)."""
    return resolve_effect(str(path))


__all__ = ["DiscoverError", "Discovery", "FoundTerm", "describe_units", "discover", "load_emitted"]
