"""The search's steps: refining a few free parameters, probing screened terms on the full nonlinear model, choosing
what to refit (and with which free parameters), and the free-run stability guard."""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from board_config.parameter import Parameter, freed
from plant import PlantModel
from workbench.discover._dictionary import Term
from workbench.discover._results import ScreenRow
from workbench.fit import FitOutcome, Objective, Target, outcome_at, train_residual_and_jacobian
from workbench.records import Record


@dataclass
class SearchState:
    """The current model: the dictionary effect's parameter values (coefficients of kept terms, every shape)."""

    values: dict[str, float]
    kept: list[int]


def refine(obj: Objective, guess: dict[str, float], max_nfev: int) -> FitOutcome:
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
HARD_FORMS = ("sign", "pos", "neg", "dead", "clip", "sat", "on_pos", "on_neg", "on_pos_soft", "on_neg_soft",
              "on_pos_grow", "on_neg_grow", "on_pos_sat", "on_neg_sat", "on_gap",
              "on_excess", "on_pos_grow2", "on_neg_grow2")
#: forms probed at several multiples of the linearised coefficient: the hard forms, and the polynomial ones whose
#: strong cases change the motion they act on (strong velocity-squared drag halves the velocity the linearisation
#: was taken along: the drag on mass 2 was screened out, a viscous term stood in at 94 sigma)
PROBED_FORMS = (*HARD_FORMS, "absx", "cube", "square")
#: how many probed terms (best by the linearised screen; state-gated damage terms aside) get every multiple
MAX_HARD_PROBED = 20
#: the multiples of the linearised coefficient every probed term gets; the first :data:`MAX_HARD_PROBED` of them
#: get :data:`FINE_MULTIPLES` as well
MULTIPLES = (1.0, 3.0, 10.0)
FINE_MULTIPLES = (0.1, 1.0 / 3.0, 0.6, 1.7)
#: how many probed terms get :data:`MULTIPLES` — beyond the first :data:`MAX_HARD_PROBED`, only a friction force
#: (a sign of a velocity; ×10 probes of the other hard forces made a 15 s sweep's screen 12 s longer): strong tip
#: friction linearises 45th of the 51 hard terms on an MBIT.b step (its stick is nowhere in a sensitivity taken
#: along the nominal run; its best probe is at ×10, the weak one's at ×3) and was neither probed nor refitted with
#: 20 (a damping gated by δ3 stood in at 11.6 σ; the friction term leaves 1.04 σ)
MAX_MULTIPLIED = 64
#: relative changes a damage term (a core parameter's fraction, gated by a state or the drive) is also probed at:
#: damage changes a parameter by tens of percent, where the linearisation along the nominal run misleads most (it
#: cannot move a resonance) — a crack in section 3 (k3 −20 % for δ3 < 0) was screened at 642 σ from its linearised
#: coefficient, 50th of 292 terms, and found only after 50 refits of forces on the masses; refitted, 1.02 σ. Up to
#: half lost or a third gained; a damping (:data:`GROWN_PROBES`) also up to four times as much (faces that rub or
#: touch: +170 % and more)
DAMAGE_PROBES = (-0.5, -0.25, 0.3)
GROWN_PROBES = (1.0, 3.0)
#: how many damage terms of each parameter (the best by the linearised screen) get :data:`DAMAGE_PROBES`
DAMAGE_PROBED_PER_PARAM = 2


def _state_gated_damage(term: Term) -> bool:
    """A core parameter's fraction switched by a state or the drive (not by time)."""
    return term.placement == "damage" and term.signal != "one"


def damage_probed(rows: Sequence[ScreenRow]) -> set[int]:
    """The rows (indices, ranked by the linearised screen) probed at :data:`DAMAGE_PROBES`: for each parameter, its
    best :data:`DAMAGE_PROBED_PER_PARAM` damage terms gated by a state or the drive (an onset in time is probed
    where the residual changes its level instead; a ramp's coefficient is a rate)."""
    taken: dict[str, int] = {}
    out = set()
    for j, r in enumerate(rows):
        t = r.term
        if not _state_gated_damage(t) or t.unit != "1":
            continue
        label = f"{t.param}{t.index}"
        if taken.get(label, 0) < DAMAGE_PROBED_PER_PARAM:
            taken[label] = taken.get(label, 0) + 1
            out.add(j)
    return out


def probe_plan(rows: Sequence[ScreenRow]) -> list[tuple[int, list[float]]]:
    """Each row's probe coefficients (rows ranked by the linearised screen): its linearised coefficient; the first
    :data:`MAX_MULTIPLIED` rows of a :data:`PROBED_FORMS` form also at ×3 and ×10, the first :data:`MAX_HARD_PROBED`
    at ×0.1 … ×1.7 too — a state-gated damage term not (~200 of them took every slot from the forces: strong tip
    friction on an MBIT.b step went unprobed and unrefitted, a damping ramp left 4.47 σ where the friction term
    leaves 1.04 σ); each parameter's best damage terms (:func:`damage_probed`) at :data:`DAMAGE_PROBES`."""
    probes: list[tuple[int, list[float]]] = []
    n_hard = 0
    damage = damage_probed(rows)
    for j, r in enumerate(rows):
        ranked = r.term.form in PROBED_FORMS and n_hard < MAX_MULTIPLIED and not _state_gated_damage(r.term)
        fine = ranked and n_hard < MAX_HARD_PROBED
        n_hard += ranked
        # beyond the first few, only a force that sticks (a sign of a velocity: friction) gets ×3 and ×10
        sticks = r.term.placement.startswith("force") and r.term.form == "sign"
        mult = (*MULTIPLES, *FINE_MULTIPLES) if fine else MULTIPLES if ranked and sticks else (1.0,)
        grown = GROWN_PROBES if r.term.param == "c" else ()
        probes.append((j, [r.coef * m for m in mult] + (list(DAMAGE_PROBES + grown) if j in damage else [])))
    return probes


def nonlinear_check(rows: list[ScreenRow], terms: Sequence[Term], targets: Sequence[Target],
                    models: Sequence[PlantModel], values: dict[str, float], names: list[tuple[str, str | None]],
                    threads: int | None) -> tuple[list[ScreenRow], int]:
    """Every screened term simulated on the full nonlinear model at its linearised coefficient (hard forms also at
    ×0.1 … ×10, each parameter's best damage terms also at :data:`DAMAGE_PROBES`), in one batch; rows re-ranked by
    the error they really leave, at their best probe, and the number of probes per record (for the simulation
    count)."""
    probes = probe_plan(rows)
    flat = [(j, c) for j, cs in probes for c in cs]
    if not flat:
        return rows, 0
    cols = [names[terms.index(rows[j].term)][0] for j, _ in flat]
    held, train, ok = probe_batch(targets, models, values, [{col: c} for (_, c), col in zip(flat, cols)], threads)
    best: dict[int, ScreenRow] = {}
    for i, (j, c) in enumerate(flat):
        if not ok[i]:
            continue
        row = ScreenRow(rows[j].term, c, float(held[i]), float(train[i]))
        if j not in best or row.train_rms_sigma < best[j].train_rms_sigma:
            best[j] = row
    return sorted(best.values(), key=lambda r: r.train_rms_sigma), len(flat)


def probe_batch(targets: Sequence[Target], models: Sequence[PlantModel], values: Mapping[str, float],
                settings: Sequence[Mapping[str, float]], threads: int | None
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One batch on the full nonlinear model: member i is the model at ``values`` with ``settings[i]`` on top;
    its held-out and training RMS (σ) and whether it integrated on every record."""
    n = len(settings)
    held = np.zeros(n)
    train = np.zeros(n)
    ok = np.ones(n, bool)
    if n == 0:  # nothing to probe (a zoom whose every neighbour left the record)
        return held, train, ok
    for tg, m in zip(targets, models):
        p0 = m.p_nominal.copy()
        for name, v in values.items():
            p0[m.param_index(name)] = v
        P = np.tile(p0, (n, 1))
        for i, setting in enumerate(settings):
            for name, v in setting.items():
                P[i, m.param_index(name)] = v
        res = m.simulate(tg.inputs, t_out=tg.t, params=P, threads=threads, max_steps=Objective.max_steps(tg))
        y = res.y[:, :, tg.out_idx(m)].transpose(0, 2, 1)
        ok &= (res.status == 0) & np.all(np.isfinite(y), axis=(1, 2))
        for part, acc in (("held", held), ("train", train)):
            mask = tg.held if part == "held" else tg.train
            e = (tg.measured[None][:, :, mask] - np.nan_to_num(y[:, :, mask])) / tg.sigma[None, :, None]
            acc += np.sum(e * e, axis=(1, 2))
    n_h = sum(int(tg.held.sum()) * len(tg.channels) for tg in targets)
    n_t = sum(int(tg.train.sum()) * len(tg.channels) for tg in targets)
    return np.sqrt(held / n_h), np.sqrt(train / n_t), ok


def refit_list(rows: list[ScreenRow], n_refit: int, n_siblings: int = 2) -> list[ScreenRow]:
    """The best ``n_refit`` rows, then the best ``n_siblings`` *siblings* of the first (all of them for a hard
    form) and every sibling of each hard-form force among them: the same form acting on another mass or section (a
    force on mass 3 and one in section 3 look alike on one sensor; the probe's coarse coefficient can rank the wrong
    one first — strong tip friction on an MBIT.b step screened as friction in section 2, its mass-3 twin never
    refitted)."""
    out = list(rows[:n_refit])
    forces = ("force_mass", "force_section")
    leaders = [r.term for r in out[:1] if r.term.placement in forces]
    leaders += [r.term for r in out[1:] if r.term.placement in forces and r.term.form in HARD_FORMS
                and all(r.term.form != t.form for t in leaders)]
    for top in leaders:
        sib = [r for r in rows[n_refit:] if r.term.form == top.form and r.term.placement in forces
               and r not in out]
        sib.sort(key=lambda r: r.term.index != top.index)  # the same mass/section number first (stable)
        out += sib if top.form in HARD_FORMS else sib[:n_siblings]  # a hard form: every sibling (≤ 5)
    for r in list(out):
        out += [o for o in other_delay_order(rows, r) if o not in out]
    return out


def other_delay_order(rows: Sequence[ScreenRow], row: ScreenRow) -> list[ScreenRow]:
    """For a delay term, the best row of the same placement and signal with the other Padé order (else [])."""
    pair = {"delay": "delay2", "delay2": "delay"}
    if row.term.form not in pair:
        return []
    other = [r for r in rows if r.term.form == pair[row.term.form] and r.term.placement == row.term.placement
             and r.term.signal == row.term.signal]
    return other[:1]


def free_for(terms: Sequence[Term], names: list[tuple[str, str | None]], idx: Sequence[int],
             start: dict[str, float], new: int | None, shapes_free: bool = True) -> list[Parameter]:
    """Free parameters of the refit: the coefficients of ``idx`` (around their start) and the shapes of the new
    term (a factor of four either way; the smoothing width of a sign term stays; an onset time over its term's
    ``shape_range``). A damage term's relative change stays above −95 % (a parameter that keeps its sign)."""
    out = []
    for k in idx:
        cname, gname = names[k]
        c = start[cname]
        span = max(abs(c), 1e-300)
        wide = 4.0 if k == new else 1.5
        lo_c = c - wide * span
        if terms[k].placement == "damage" and terms[k].unit == "1":
            lo_c = max(lo_c, -0.95) if c > -0.95 else c - 0.04 * span
        out.append(freed(cname, terms[k].unit, lo_c, c + wide * span, False, "discover"))
        if shapes_free and gname is not None and k == new:
            g = start[gname]
            rng = terms[k].shape_range
            if rng is not None:  # an onset or a switching point: a window as wide as its term's range, centred on
                half = 0.5 * (rng[1] - rng[0])  # the (scanned) start; an onset stays ≥ 0, a switching point not
                lo_g = max(g - half, min(rng[0], 0.0))
                out.append(freed(gname, terms[k].shape_unit, lo_g, g + half, False, "discover"))
                continue
            lo, hi = (g / 20.0, g * 2.0) if terms[k].form == "sign" else (g / 4.0, g * 4.0)
            out.append(freed(gname, terms[k].shape_unit, lo, hi, True, "discover"))
    return out


def free_run_check(records: Sequence[Record], models: Sequence[PlantModel], targets: Sequence[Target],
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
