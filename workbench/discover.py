"""``shm discover``: find a missing correction term beyond the effects library, name it, and write it as an effect.

1. **Dictionary.** Candidate terms from the model's own signals along the records
   (:mod:`workbench.discovery_dictionary`: forces on masses and sections, currents into the patch charges, changes
   of the drive and of the measurement; linear, sign, |x|·x, polynomial, one-sided, dead-zone, clipped, saturating,
   time-weighted and delayed forms), with thresholds set from each signal's scale. All of them live in *one*
   generated effect whose coefficients are 0 (the nominal model), compiled once per machine whatever the records.
2. **Sensitivities.** One batch through the compiled integrator: member 0 is the current model, member k switches term
   k on with a small coefficient ε_k; (y_k − y_0)/ε_k is the change of the measured channels per unit coefficient —
   the term's *output sensitivity*. The search lives in this output space, where the data are (one tip laser), not in
   state derivatives.
3. **Screen (held-out).** Each term's coefficient by least squares on the training blocks; terms ranked by the
   held-out residual they leave.
4. **Refit.** The best few are refitted on the full nonlinear model (the fit engine's :class:`~workbench.fit.Objective`,
   coefficient and threshold/delay free, together with terms already kept) and judged on held-out data; a term is
   kept when it removes a clear share of what is left above the noise. Forward selection: with a term kept, the
   sensitivities are recomputed around the new model and the next term is sought (up to ``max_terms``).
5. **Guards.** The kept model must run free (full rate, every record) without diverging; "not found" is an answer.

The result (:class:`Discovery`) names each kept term in words and units and carries the source of a readable effect
(:func:`workbench.effect_writer.emit_effect_source`) that ``shm fit --add FILE.py`` refits.
"""

from __future__ import annotations

import hashlib
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from board_config import ParameterSet, load_parameter_set
from plant import PhysicalEffect, PlantModel
from plant import layout as L
from plant.compose import kernel_dir
from plant.effect import EffectError, load_effect_file, resolve_effect
from workbench.candidate_fit import explained, noise_tolerance
from workbench.discovery_dictionary import (
    FORMS,
    Term,
    build_dictionary,
    dictionary_parameter_names,
    dictionary_source,
    form_values,
)
from workbench.effect_library import FreeParameter, resolve_candidates
from workbench.effect_writer import describe_term, emit_effect_source, parameter_names
from workbench.fit_objective import Objective, rms
from workbench.fit_optimiser import FitOutcome, outcome_at, train_residual_and_jacobian
from workbench.fit_targets import DEFAULT_BLOCKS, DEFAULT_MAX_RATE_HZ, FitError, Target, model_factory, prepare_targets
from workbench.records import Record

#: a term is kept when its refit removes at least this share of the held-out energy left above the noise
MIN_SHARE = 0.25
#: relative size of the switched-on coefficient in the sensitivity batch (of the placement's reference magnitude)
EPS_REL = 2e-3
#: integrator tolerance of the sensitivity batch (tighter than the fits: differences of near-equal runs)
SENS_RTOL = 1e-7


class DiscoverError(FitError):
    """Discovery cannot start (bad records or effects)."""


@dataclass
class FoundTerm:
    """A kept term: its fitted coefficient and shape, its size along the records, and what it means."""

    term: Term
    coef: float
    shape: float
    scale: float
    words: str

    def to_dict(self) -> dict[str, Any]:
        return {"key": self.term.key, "placement": self.term.placement, "index": self.term.index,
                "signal": self.term.signal, "form": self.term.form, "coefficient": self.coef,
                "coefficient_unit": self.term.unit, "shape": self.shape if FORMS[self.term.form].shape else None,
                "signal_scale": self.scale, "words": self.words}


@dataclass
class ScreenRow:
    term: Term
    coef: float
    held_rms_sigma: float
    train_rms_sigma: float


@dataclass
class Discovery:
    """What ``shm discover`` found (``verdict``: ``found`` | ``partial`` | ``not_found``)."""

    verdict: str
    message: str
    terms: list[FoundTerm]
    train_before: float
    held_before: float
    train_after: float
    held_after: float
    screen: list[ScreenRow]
    n_terms_searched: int
    stable: bool
    stability_note: str
    records: list[str]
    outcome: FitOutcome | None
    targets: list[Target]
    n_sims: int
    timings: dict[str, float] = field(default_factory=dict)
    rounds: list[dict[str, Any]] = field(default_factory=list)

    def effect_source(self, class_name: str | None = None, effect_name: str = "discovered") -> str | None:
        """The readable effect module for the kept terms (None when nothing was found)."""
        if not self.terms:
            return None
        values: dict[str, float] = {}
        for ft in self.terms:
            cname, gname = parameter_names(ft.term)
            values[cname] = ft.coef
            if gname:
                values[gname] = ft.shape
        return emit_effect_source([ft.term for ft in self.terms], values, class_name=class_name,
                                  effect_name=effect_name, words=[ft.words for ft in self.terms],
                                  records=self.records, held_before=self.held_before, held_after=self.held_after)

    def to_dict(self) -> dict[str, Any]:
        return {
            "verdict": self.verdict, "message": self.message, "terms": [t.to_dict() for t in self.terms],
            "train_rms_sigma": {"before": self.train_before, "after": self.train_after},
            "held_rms_sigma": {"before": self.held_before, "after": self.held_after},
            "screen": [{"key": r.term.key, "placement": r.term.placement, "form": r.term.form, "signal": r.term.signal,
                        "coefficient": r.coef, "coefficient_unit": r.term.unit, "held_rms_sigma": r.held_rms_sigma,
                        "train_rms_sigma": r.train_rms_sigma} for r in self.screen],
            "terms_searched": self.n_terms_searched, "stable": self.stable, "stability": self.stability_note,
            "records": self.records, "simulations": self.n_sims, "timings_s": self.timings, "rounds": self.rounds,
        }


# ----------------------------------------------------------------------------------------------------------------
# the dictionary effect for a set of records


def _signal_scales(targets: Sequence[Target]) -> tuple[dict[str, float], dict[str, list[np.ndarray]]]:
    """99th percentile of |signal| along the records (nominal free run) and the signals themselves."""
    sig: dict[str, list[np.ndarray]] = {}
    for tg in targets:
        res = tg.model.simulate(tg.inputs, t_out=tg.t, record_states=True, record_bus=True,
                                max_steps=Objective.max_steps(tg))
        if not res.ok:
            raise DiscoverError(f"{tg.name}: the starting model fails to integrate on the record "
                                f"({'; '.join(res.failures())})")
        bus, xs = res.bus[0], res.states[0]
        for j in range(3):
            sig.setdefault(f"z{j + 1}", []).append(bus[:, L.B_Z + j])
            sig.setdefault(f"zd{j + 1}", []).append(bus[:, L.B_ZD + j])
            sig.setdefault(f"delta{j + 1}", []).append(xs[:, L.X_DELTA + j])
            sig.setdefault(f"ddelta{j + 1}", []).append(xs[:, L.X_DDELTA + j])
        sig.setdefault("vc", []).append(bus[:, L.B_VC])
        sig.setdefault("va", []).append(bus[:, L.B_VA_DEMAND])
        sig.setdefault("one", []).append(np.ones(tg.t.size))
    scales = {k: float(np.percentile(np.abs(np.concatenate(v)), 99)) for k, v in sig.items()}
    return scales, sig


def _generated_effect(source: str, stem: str) -> type[PhysicalEffect]:
    """Write generated effect source to the kernel cache (content-addressed) and load it as a file effect."""
    d = kernel_dir() / "discover"
    d.mkdir(parents=True, exist_ok=True)
    path = d / f"{stem}_{hashlib.sha256(source.encode()).hexdigest()[:16]}.py"
    if not path.exists() or path.read_text() != source:
        tmp = path.with_suffix(f".{time.time_ns()}.tmp")
        tmp.write_text(source)
        tmp.replace(path)
    mod = load_effect_file(path)
    return next(o for o in vars(mod).values() if isinstance(o, type) and issubclass(o, PhysicalEffect)
                and o.__module__ == mod.__name__)


def _reference_magnitudes(model: PlantModel, scales: dict[str, float]) -> dict[str, float]:
    """A small magnitude per placement (SI) whose effect on the tip is ~EPS_REL of its motion."""
    k3 = model.param_value("k3")
    r = model.param_value("R_ep")
    z3 = max(scales.get("z3", 0.0), 1e-9)
    va = max(scales.get("va", 0.0), scales.get("vc", 0.0), 1e-3)
    return {"force_mass": EPS_REL * k3 * z3, "force_section": EPS_REL * k3 * z3, "current": EPS_REL * va / r,
            "drive": EPS_REL * va, "measurement": EPS_REL * z3}


def _term_scale(term: Term, sig: dict[str, list[np.ndarray]], targets: Sequence[Target]) -> float:
    """RMS of the form's value along the records (for the sensitivity step)."""
    vals = []
    for s, tg in zip(sig[term.signal], targets):
        dt = float(np.median(np.diff(tg.t))) if tg.t.size > 1 else 1.0
        vals.append(form_values(term.form, s, term.shape if term.shape > 0 else 1.0, tg.t, dt))
    v = np.concatenate(vals)
    return float(np.sqrt(np.mean(v * v)))


# ----------------------------------------------------------------------------------------------------------------
# the search


@dataclass
class _State:
    """The current model: the dictionary effect's parameter values (coefficients of kept terms, every shape)."""

    values: dict[str, float]
    kept: list[int]


def _refine(obj: Objective, guess: dict[str, float], max_nfev: int) -> FitOutcome:
    """Least squares from ``guess`` with the batched Jacobian (no multi-start: the screen gave the start)."""
    t0 = time.perf_counter()
    sims0 = obj.n_sims
    k = obj.k
    u0 = np.array([float(fp.to_unit(guess[fp.name])) for fp in obj.free])
    fun, jac = train_residual_and_jacobian(obj)

    try:
        res = least_squares(fun, u0, jac=jac, bounds=(np.zeros(k), np.ones(k)), method="trf", x_scale=1.0,
                            max_nfev=max_nfev, ftol=1e-5, xtol=1e-6, gtol=1e-8)
        u, msg = res.x, str(res.message)
    except (ValueError, FloatingPointError) as exc:
        u, msg = u0, f"optimiser failed: {exc}"
    sim = obj.simulate(u[None])
    return outcome_at(obj, u, sim, jac if sim.ok.all() else None, [], msg, t0, sims0)


#: forms whose linearisation along the nominal run misleads (stick, contact, play, saturation): probed at a
#: 0.1, 1/3, 0.6, 1.7, 3 and 10 times the linearised coefficient as well
HARD_FORMS = ("sign", "pos", "neg", "dead", "clip", "sat")
_LAST_PROBES: list[tuple[int, list[float]]] = []
#: how many hard-form terms (best by the linearised screen) get the extra probes
MAX_HARD_PROBED = 14


def _nonlinear_check(rows: list[ScreenRow], terms: Sequence[Term], targets: Sequence[Target],
                     models: Sequence[PlantModel], values: dict[str, float], names: list[tuple[str, str | None]],
                     threads: int | None) -> list[ScreenRow]:
    """Every screened term simulated on the full nonlinear model at its linearised coefficient (hard forms also at
    ×0.1 … ×10), in one batch; rows re-ranked by the error they really leave, at their best probe."""
    probes: list[tuple[int, list[float]]] = []
    n_hard = 0
    for j, r in enumerate(rows):  # rows come ranked by the linearised screen
        hard = r.term.form in HARD_FORMS and n_hard < MAX_HARD_PROBED
        n_hard += hard
        mult = (1.0, 0.1, 1.0 / 3.0, 0.6, 1.7, 3.0, 10.0) if hard else (1.0,)
        probes.append((j, [r.coef * m for m in mult]))
    _LAST_PROBES[:] = probes
    flat = [(j, c) for j, cs in probes for c in cs]
    if not flat:
        return rows
    cols = [names[terms.index(rows[j].term)][0] for j, _ in flat]
    held = np.zeros(len(flat))
    train = np.zeros(len(flat))
    ok = np.ones(len(flat), bool)
    for tg, m in zip(targets, models):
        p0 = m.p_nominal.copy()
        for n, v in values.items():
            p0[m.param_index(n)] = v
        P = np.tile(p0, (len(flat), 1))
        for i, ((_, c), col) in enumerate(zip(flat, cols)):
            P[i, m.param_index(col)] = c
        res = m.simulate(tg.inputs, t_out=tg.t, params=P, threads=threads, max_steps=Objective.max_steps(tg))
        y = res.y[:, :, tg.out_idx(m)].transpose(0, 2, 1)
        good = (res.status == 0) & np.all(np.isfinite(y), axis=(1, 2))
        ok &= good
        for part, acc in (("held", held), ("train", train)):
            mask = tg.held if part == "held" else tg.train
            e = (tg.measured[None][:, :, mask] - np.nan_to_num(y[:, :, mask])) / tg.sigma[None, :, None]
            acc += np.sum(e * e, axis=(1, 2))
    n_h = sum(int(tg.held.sum()) * len(tg.channels) for tg in targets)
    n_t = sum(int(tg.train.sum()) * len(tg.channels) for tg in targets)
    best: dict[int, ScreenRow] = {}
    for i, (j, c) in enumerate(flat):
        if not ok[i]:
            continue
        row = ScreenRow(rows[j].term, c, math.sqrt(held[i] / n_h), math.sqrt(train[i] / n_t))
        if j not in best or row.train_rms_sigma < best[j].train_rms_sigma:
            best[j] = row
    return sorted(best.values(), key=lambda r: r.train_rms_sigma)


def _refit_list(rows: list[ScreenRow], n_refit: int, n_siblings: int = 2) -> list[ScreenRow]:
    """The best ``n_refit`` rows, then the best ``n_siblings`` *siblings* of the first: the same form acting on
    another mass or section (a force on mass 3 and one in section 3 look alike on one sensor; the probe's coarse
    coefficient can rank the wrong one first)."""
    out = list(rows[:n_refit])
    if rows and rows[0].term.placement in ("force_mass", "force_section"):
        top = rows[0].term
        sib = [r for r in rows[n_refit:] if r.term.form == top.form
               and r.term.placement in ("force_mass", "force_section")]
        sib.sort(key=lambda r: r.term.index != top.index)  # the same mass/section number first (stable)
        out += sib[:n_siblings]
    return out


def _free_for(terms: Sequence[Term], names: list[tuple[str, str | None]], idx: Sequence[int],
              start: dict[str, float], new: int | None, shapes_free: bool = True) -> list[FreeParameter]:
    """Free parameters of the refit: the coefficients of ``idx`` (around their start) and the shapes of the new
    term (a factor of four either way; the smoothing width of a sign term stays)."""
    out = []
    for k in idx:
        cname, gname = names[k]
        c = start[cname]
        span = max(abs(c), 1e-300)
        wide = 4.0 if k == new else 1.5
        out.append(FreeParameter(cname, terms[k].unit, c - wide * span, c + wide * span, False, "discover"))
        if shapes_free and gname is not None and k == new:
            g = start[gname]
            lo, hi = (g / 20.0, g * 2.0) if terms[k].form == "sign" else (g / 4.0, g * 4.0)
            out.append(FreeParameter(gname, "SI", lo, hi, True, "discover"))
    return out


def discover(records: Sequence[Record], params: ParameterSet | str = "table2",
             add: Sequence[str | type[PhysicalEffect]] = (), *, max_terms: int = 2, n_refit: int = 4,
             holdout: str = "blocks", n_blocks: int = DEFAULT_BLOCKS, max_rate_Hz: float = DEFAULT_MAX_RATE_HZ,
             max_nfev: int = 12, threads: int | None = None,
             on_progress: Callable[[str], None] | None = None) -> Discovery:
    """Search the dictionary for the terms the model lacks on ``records`` (see the module docstring)."""
    t_start = time.perf_counter()
    say = on_progress or (lambda _msg: None)
    timings: dict[str, float] = {}
    base = params if isinstance(params, ParameterSet) else load_parameter_set(params)
    try:
        classes = resolve_candidates(add)
    except EffectError as exc:
        raise DiscoverError(str(exc)) from None
    targets = prepare_targets(records, model_factory(base, classes), holdout=holdout, n_blocks=n_blocks,
                              max_rate_Hz=max_rate_Hz)
    t0 = time.perf_counter()
    scales, sig = _signal_scales(targets)
    driven = all(next(c.name for c in tg.model.effects if c.role == "terminal") == "amplifier" for tg in targets)
    terms = build_dictionary(scales, driven=driven)
    names = dictionary_parameter_names(terms)
    dict_cls = _generated_effect(dictionary_source(terms), "dictionary_" + ("driven" if driven else "open"))
    dict_build = model_factory(base, [*classes, dict_cls])
    models = [dict_build(tg.record) for tg in targets]
    timings["dictionary_s"] = time.perf_counter() - t0
    state = _State({}, [])
    for k, (cname, gname) in enumerate(names):
        state.values[cname] = 0.0
        if gname is not None:
            state.values[gname] = terms[k].shape if terms[k].shape > 0 else 1.0
    ref = _reference_magnitudes(targets[0].model, scales)
    eps = np.array([ref[t.placement] / max(_term_scale(t, sig, targets), 1e-300) for t in terms])
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
    timings["screen_s"] = 0.0
    timings["refit_s"] = 0.0
    for round_no in range(max_terms):
        if explained(current_held, held_before, n_held) and round_no > 0:
            break
        # --- sensitivities: one batch, member k+1 switches term k on with eps_k
        t0 = time.perf_counter()
        cand = [k for k in range(len(terms)) if k not in state.kept]
        names_free = [FreeParameter(names[k][0], terms[k].unit, -1e300, 1e300, False, "discover") for k in cand]
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
            raise DiscoverError("the current model fails to integrate on the records")
        r_tr, r_he, X_tr, X_he = [], [], [], []
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
            free = _free_for(terms, names, [*state.kept, k], start, k)
            robj = Objective(targets, models, free, base_values=state.values, threads=threads)
            out = _refine(robj, start, max_nfev)
            n_sims += robj.n_sims
            if not out.ok:
                return None
            # a coefficient at its range bound: widen once (the linearised start underestimated it)
            if any(e.at_bound and e.name.startswith("a_") for e in out.estimates):
                start2 = dict(start) | out.values
                free2 = _free_for(terms, names, [*state.kept, k], start2, k)
                robj2 = Objective(targets, models, free2, base_values=state.values, threads=threads)
                out2 = _refine(robj2, start2, max_nfev)
                n_sims += robj2.n_sims
                if out2.ok and out2.train_rms_sigma < out.train_rms_sigma:
                    out = out2
            return out

        best: tuple[float, int, FitOutcome] | None = None
        tried = []
        # fast path: the linearised screen already reaches the noise floor with one term — confirm it on the full
        # model before probing every term nonlinearly
        fast = bool(rows) and explained(rows[0].held_rms_sigma, held_before, n_held)
        if fast:
            t1 = time.perf_counter()
            out = refit_row(rows[0])
            timings["refit_s"] += time.perf_counter() - t1
            if out is not None and explained(out.held_rms_sigma, held_before, n_held):
                best = (out.held_rms_sigma, terms.index(rows[0].term), out)
                tried.append({"term": rows[0].term.key, "held_rms_sigma": out.held_rms_sigma,
                              "train_rms_sigma": out.train_rms_sigma})
        if best is None:
            rows = _nonlinear_check(rows, terms, targets, models, state.values, names, threads)
            n_sims += sum(len(r[1]) for r in _LAST_PROBES) * len(targets)
        timings["screen_s"] += time.perf_counter() - t0
        if round_no == 0:
            screen_rows = rows[:12]
        say(f"round {round_no + 1}: screened {len(rows)} terms in {time.perf_counter() - t0:.2g} s; best "
            + ("by the linearised screen, confirmed on the full model" if best is not None else
               "on the full model at the screened coefficients") + " (held-out): "
            + ", ".join(f"{r.term.key} {r.held_rms_sigma:.3g} σ" for r in rows[:4]))
        # --- refit the best few on the full nonlinear model
        t0 = time.perf_counter()
        for row in ([] if best is not None else _refit_list(rows, n_refit)):
            k = terms.index(row.term)
            out = refit_row(row)
            if out is None:
                continue
            tried.append({"term": row.term.key, "held_rms_sigma": out.held_rms_sigma,
                          "train_rms_sigma": out.train_rms_sigma})
            if best is None or out.held_rms_sigma < best[0]:
                best = (out.held_rms_sigma, k, out)
            if explained(out.held_rms_sigma, held_before, n_held):
                break
        timings["refit_s"] += time.perf_counter() - t0
        rounds.append({"screened": [(r.term.key, r.held_rms_sigma) for r in rows[:n_refit]], "refitted": tried})
        if best is None:
            break
        h_new, k_new, out = best
        gain = (current_held ** 2 - h_new ** 2) / max(current_held ** 2 - 1.0, 1e-12)
        say(f"  best refit: {terms[k_new].key}: held-out {current_held:.4g} σ → {h_new:.4g} σ "
            f"({100 * gain:.0f} % of the excess removed)")
        if gain < MIN_SHARE or h_new >= current_held:
            break
        state.kept.append(k_new)
        state.values.update(out.values)
        current_train, current_held = out.train_rms_sigma, h_new
        outcome = out
    # --- stability guard: the kept model in free run at the records' full rate
    t0 = time.perf_counter()
    stable, note = True, "no term kept"
    if state.kept:
        stable, note = _free_run_check(records, models, targets, state.values)
    timings["stability_s"] = time.perf_counter() - t0
    found = []
    for k in state.kept:
        cname, gname = names[k]
        coef = state.values[cname]
        shape = state.values[gname] if gname else 0.0
        scale = scales.get(terms[k].signal, 1.0)
        found.append(FoundTerm(terms[k].with_shape(shape), coef, shape, scale,
                               describe_term(terms[k], coef, shape, scale)))
    if found and not stable:
        verdict = "not_found"
        msg = (f"The best terms ({', '.join(f.term.key for f in found)}) make the model diverge in free run "
               f"({note}): rejected. Nothing in the dictionary explains the residual safely.")
        found = []
    elif found and explained(current_held, held_before, n_held):
        verdict = "found"
        msg = ("Found: " + "; and ".join(f.words for f in found)
               + f". Held-out error {held_before:.4g} σ → {current_held:.4g} σ (noise floor 1 σ).")
    elif found:
        verdict = "partial"
        msg = ("Partly found: " + "; and ".join(f.words for f in found)
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
    timings["total_s"] = time.perf_counter() - t_start
    return Discovery(verdict, msg, found, train_before, held_before,
                     current_train if found else train_before, current_held if found else held_before,
                     screen_rows, len(terms), stable, note, [tg.name for tg in targets], outcome if found else None,
                     targets, n_sims, timings, rounds)


def _free_run_check(records: Sequence[Record], models: Sequence[PlantModel], targets: Sequence[Target],
                    values: dict[str, float]) -> tuple[bool, str]:
    """Every record at its full rate, free run from rest: integrates, finite, and no more than 10× the measured
    range."""
    for tg, m in zip(targets, models):
        rec = tg.record
        p = m.p_nominal.copy()
        for n, v in values.items():
            p[m.param_index(n)] = v
        res = m.simulate(rec.input_signals(), t_out=rec.t, params=p, max_steps=Objective.max_steps(tg) * 2)
        if not res.ok:
            return False, f"{tg.name}: {'; '.join(res.failures())}"
        for j, o in enumerate(tg.outputs):
            y = res[o][0]
            span = float(np.ptp(tg.measured[j])) + 10 * float(tg.sigma[j])
            if not np.all(np.isfinite(y)) or float(np.max(np.abs(y - np.mean(tg.measured[j])))) > 10 * span:
                return False, f"{tg.name}: {o} leaves 10× the measured range"
    return True, "free run at the full rate stays bounded on every record"


def load_emitted(path: str) -> type[PhysicalEffect]:
    """Load an emitted effect file through the documented seam (``resolve_effect('FILE.py')``)."""
    return resolve_effect(str(path))


def describe_units(found: Sequence[FoundTerm]) -> list[str]:
    """One line per kept term: coefficient with unit and, for a shaped form, its shape."""
    out = []
    for f in found:
        line = f"{f.term.key}: coefficient {f.coef:.4g} {f.term.unit}"
        if FORMS[f.term.form].shape:
            unit = "s" if f.term.form == "delay" else ("m/s" if f.term.signal.startswith(("zd", "dd")) else
                                                        "V" if f.term.signal in ("va", "vc") else "m")
            line += f", {FORMS[f.term.form].shape} {f.shape:.4g} {unit}"
        out.append(line)
    return out


__all__ = ["DiscoverError", "Discovery", "FoundTerm", "describe_units", "discover", "load_emitted"]
