"""What ``shm diagnose`` tries: library effects, core-parameter re-estimations and their combinations.

A :class:`CandidateSpec` is one hypothesis about what the model lacks: effects to add (with the parameters the
workbench fits for each) and core parameters to re-estimate — one parameter (``m3``), several independently
(``R_ep`` and ``C_ep``), or a *tied group* scaled by one common factor (all three stiffnesses ×s). Every spec is
fitted and scored the same way (:func:`workbench.diagnose._pipeline.fit_spec`), whatever it holds.

Re-estimation candidates (:data:`PARAMETER_CANDIDATES`) cover every identifiable core parameter of Table 2 and
small physically meaningful groups. Their search range is a factor :data:`CORE_RANGE_FACTOR` around the current
value (log), widened up to :data:`CORE_WIDE_FACTOR` (and the parameter's own bounds) when a fit ends at the range
bound (:func:`widen`).

Screening (:func:`screen_parameters`): every parameter candidate is first judged from one batched simulation — the
sensitivity of the training residual to a 2 % change of each (one Jacobian column per candidate), a Gauss–Newton
step from it and two probe points either side — and only the most promising are fitted in full. The same cheap
design (the effect's own guess and a small Latin hypercube) screens the library effects (:func:`screen_effects`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from board_config import CORE_SCHEMA, ParameterSet
from board_config.parameter import Parameter, freed
from plant import PhysicalEffect, PlantModel
from workbench.fit._effect_library import LIBRARY, effect_free_parameters
from workbench.fit._fitting import Objective, SimBatch, Target, rms
from workbench.fit._optimiser import zoom_design

#: default search range of a re-estimated core parameter: a factor around its current value
CORE_RANGE_FACTOR = 4.0
#: how far a re-estimation may be widened when its fit ends at the range bound
CORE_WIDE_FACTOR = 25.0


@dataclass(frozen=True)
class ParameterCandidate:
    """A re-estimation: ``members`` freed independently, or (``tied``) scaled together by one factor."""

    name: str
    members: tuple[str, ...]
    tied: bool = False
    description: str = ""

    @property
    def scale_name(self) -> str:
        return f"{self.name}_scale"


def _single(name: str, what: str) -> ParameterCandidate:
    return ParameterCandidate(name, (name,), False, what)


#: every core parameter the records can speak to, and small physical groups (A_h, n_h and γ_h are literature
#: assumptions — γ_h = 0 — whose role β_h and α_h already cover; they are not candidates)
PARAMETER_CANDIDATES: tuple[ParameterCandidate, ...] = (
    _single("k1", "root-section bending stiffness"),
    _single("k2", "intermediate-section bending stiffness"),
    _single("k3", "tip-section bending stiffness"),
    _single("c1", "root-section damping"),
    _single("c2", "intermediate-section damping"),
    _single("c3", "tip-section damping"),
    _single("m1", "root-section mass"),
    _single("m2", "intermediate-section mass"),
    _single("m3", "tip-section mass"),
    _single("d_ep", "patch piezoelectric coefficient"),
    _single("R_ep", "patch resistance"),
    _single("C_ep", "patch capacitance"),
    _single("alpha_h", "Bouc-Wen linearity factor"),
    _single("beta_h", "Bouc-Wen shape factor β"),
    ParameterCandidate("stiffness", ("k1", "k2", "k3"), True, "all three section stiffnesses, scaled together"),
    ParameterCandidate("damping", ("c1", "c2", "c3"), True, "all three section dampings, scaled together"),
    ParameterCandidate("mass", ("m1", "m2", "m3"), True, "all three section masses, scaled together"),
    ParameterCandidate("electrical", ("R_ep", "C_ep"), False, "the patch's electrical pair R_ep, C_ep"),
)
PARAMETER_CANDIDATE_NAMES = tuple(c.name for c in PARAMETER_CANDIDATES)


def parameter_candidate(name: str) -> ParameterCandidate:
    for c in PARAMETER_CANDIDATES:
        if c.name == name:
            return c
    if name in CORE_SCHEMA:
        return _single(name, "core parameter")
    raise KeyError(f"unknown parameter candidate '{name}' (known: {', '.join(PARAMETER_CANDIDATE_NAMES)})")


def core_range(name: str, value: float, factor: float = CORE_RANGE_FACTOR) -> Parameter:
    """Search range of core parameter ``name`` at ``value``: ×/÷ ``factor`` (log) clipped to its own bounds; a
    parameter at zero (γ_h) or of either sign gets a linear range."""
    spec = CORE_SCHEMA[name]
    unit = spec.unit
    lo_b, hi_b = spec.lower, spec.upper
    if value > 0:
        lo, hi = value / factor, value * factor
        lo = max(lo, lo_b if lo_b > 0 else 0.0)
        hi = min(hi, hi_b)
        if lo > 0 and (hi_b == math.inf or hi < hi_b):
            return freed(name, unit, lo, hi, True, "core")
        return freed(name, unit, max(lo, 1e-12 * value), hi, lo > 0 and hi / max(lo, 1e-300) > 3.0, "core")
    span = max(abs(value), 1.0) * factor / 4.0
    return freed(name, unit, max(value - span, lo_b), min(value + span, hi_b), False, "core")


@dataclass(frozen=True)
class CandidateSpec:
    """One hypothesis: effects to add (``extras[effect]``: parameters freed beyond the effect's defaults) and
    parameter re-estimations."""

    effects: tuple[type[PhysicalEffect], ...] = ()
    params: tuple[ParameterCandidate, ...] = ()
    extras: tuple[tuple[str, tuple[str, ...]], ...] = ()

    @property
    def label(self) -> str:
        parts = [e.name + (f"(+{','.join(self.extra_for(e))})" if self.extra_for(e) else "") for e in self.effects]
        parts += [p.name for p in self.params]
        return " + ".join(parts)

    @property
    def kind(self) -> str:
        n = len(self.effects) + len(self.params)
        if n > 1:
            return "combination"
        return "effect" if self.effects else "parameter"

    @property
    def members(self) -> tuple[str, ...]:
        return tuple(e.name for e in self.effects) + tuple(p.name for p in self.params)

    def extra_for(self, cls: type[PhysicalEffect]) -> tuple[str, ...]:
        return dict(self.extras).get(cls.name, ())

    def plus(self, other: CandidateSpec) -> CandidateSpec:
        order = {n: i for i, n in enumerate(LIBRARY)}
        effects = sorted({*self.effects, *other.effects}, key=lambda c: (order.get(c.name, 99), c.name))
        # tied groups first: a single parameter that is also in a group is then set after the group's scale
        params = tuple(sorted(dict.fromkeys((*self.params, *other.params)), key=lambda p: not p.tied))
        extras = dict(self.extras) | dict(other.extras)
        return CandidateSpec(tuple(effects), params, tuple(extras.items()))

    def free_parameters(self, base_values: Mapping[str, float],
                        ranges: Mapping[str, Parameter] | None = None) -> tuple[list[Parameter], list]:
        """(free parameters, ties): ``ties[j]`` is None for a parameter set directly, or the member names a tied
        scale factor multiplies."""
        ranges = ranges or {}
        free: list[Parameter] = []
        ties: list = []
        for cls in self.effects:
            names = list(cls.default_fit_names())
            names += [n for n in self.extra_for(cls) if n not in names]
            for fp in effect_free_parameters(cls, names):
                free.append(ranges.get(fp.name, fp))
                ties.append(None)
        for pc in self.params:
            if pc.tied:
                fp = freed(pc.scale_name, "1", 1.0 / CORE_RANGE_FACTOR, CORE_RANGE_FACTOR, True, pc.name)
                free.append(ranges.get(fp.name, fp))
                ties.append(pc.members)
            else:
                for n in pc.members:
                    if any(f.name == n for f in free):
                        continue  # the same parameter freed twice (an independent pair and a single)
                    free.append(ranges.get(n, core_range(n, float(base_values[n]))))
                    ties.append(None)
        return free, ties


class TiedObjective(Objective):
    """:class:`workbench.fit._fitting.Objective` whose free parameters may also be common scale factors of several model
    parameters (``ties[j]``: the names scaled by free parameter j, or None for a parameter set directly)."""

    def __init__(self, targets: Sequence[Target], models: Sequence[PlantModel], free: Sequence[Parameter],
                 ties: Sequence[tuple[str, ...] | None], base_values: Mapping[str, float] | None = None,
                 threads: int | None = None, rtol: float = 1e-6):
        super().__init__(targets, models, [], base_values=base_values, threads=threads, rtol=rtol)
        self.free = list(free)
        self._ties = list(ties)
        self._tcols = []
        for m in self.models:
            cols = []
            for fp, tie in zip(self.free, self._ties):
                names = (fp.name,) if tie is None else tie
                cols.append(np.array([m.param_index(n) for n in names], dtype=int))
            self._tcols.append(cols)

    def param_rows(self, i: int, U: np.ndarray) -> np.ndarray:
        U = np.atleast_2d(U)
        p0 = self._p0[i]
        P = np.tile(p0, (U.shape[0], 1))
        for j, (fp, tie) in enumerate(zip(self.free, self._ties)):
            v = fp.from_unit(U[:, j])
            cols = self._tcols[i][j]
            if tie is None:
                P[:, cols[0]] = v
            else:
                P[:, cols] = p0[cols][None, :] * np.asarray(v)[:, None]
        return P


class RowsObjective(Objective):
    """Simulates given parameter rows (one matrix per target) — for screening designs that change different
    parameters in different rows."""

    def __init__(self, targets: Sequence[Target], models: Sequence[PlantModel], threads: int | None = None,
                 rtol: float = 1e-6, base_values: Mapping[str, float] | None = None):
        super().__init__(targets, models, [], threads=threads, rtol=rtol, base_values=base_values)
        self.rows: list[np.ndarray] = []

    @property
    def k(self) -> int:
        return 1 if self.rows else 0

    def param_rows(self, i: int, U: np.ndarray) -> np.ndarray:
        return self.rows[i]

    def nominal(self, i: int) -> np.ndarray:
        return self._p0[i]

    def run(self, rows: Sequence[np.ndarray]) -> SimBatch:
        self.rows = list(rows)
        try:
            return self.simulate(np.zeros((rows[0].shape[0], 1)))
        finally:
            self.rows = []


@dataclass
class ScreenResult:
    """A candidate judged from a few simulations: best training and held-out residual RMS (σ) seen, where."""

    spec: CandidateSpec
    train_rms_sigma: float
    held_rms_sigma: float
    start: dict[str, float] = field(default_factory=dict)  # values of the best point (free-parameter names)
    predicted_rms_sigma: float = float("nan")  # linearised (Gauss–Newton) prediction, parameters only
    n_sims: int = 0
    nominal_train_rms_sigma: float = float("nan")  # the nominal model at the screening tolerance


#: integration tolerance of the screening simulations (the full fits use the objective's default, 1e-6): on the
#: 60 s bench sweep 1e-4 is twice as fast and within 9 µm of the 1e-6 run — enough to rank candidates
SCREEN_RTOL = 1e-4
#: probe points of the parameter screen, in ln(value / current); the dense line search of the most promising
_PROBES = (-0.5, -0.25, -0.1, 0.1, 0.25, 0.5)
_DENSE = (-0.9, -0.7, -0.4, -0.32, -0.18, -0.05, 0.05, 0.18, 0.32, 0.4, 0.7, 0.9)
_ZOOM = (-0.06, -0.04, -0.02, 0.02, 0.04, 0.06)
_FD_LN = 0.02


def screen_parameters(targets: Sequence[Target], candidates: Sequence[ParameterCandidate],
                      base_values: Mapping[str, float], refine_top: int = 6, threads: int | None = None,
                      models: Sequence[PlantModel] | None = None,
                      overrides: Mapping[str, float] | None = None) -> list[ScreenResult]:
    """Screen re-estimation candidates from batched simulations (see the module docstring); each candidate
    is moved along one direction (a tied group: all members by the same factor; an independent pair: both).
    ``models``/``overrides``: screen on top of another model (forward selection: the current set, fitted)."""
    models = list(models) if models is not None else [tg.model for tg in targets]
    overrides = dict(overrides or {})
    base_values = {**base_values, **{k: v for k, v in overrides.items() if k in base_values}}
    ro = RowsObjective(targets, models, threads=threads, rtol=SCREEN_RTOL, base_values=overrides)
    cands = list(candidates)
    # the nominal model's residual at the screening tolerance (differences are taken at one tolerance)
    r0_train = ro.residuals(ro.run([ro.nominal(i)[None] for i in range(len(models))]), "train")[0]

    def rows_for(steps: Sequence[tuple[ParameterCandidate, float]]) -> list[np.ndarray]:
        out = []
        for i, m in enumerate(models):
            p0 = ro.nominal(i)
            P = np.tile(p0, (len(steps), 1))
            for r, (pc, s) in enumerate(steps):
                for n in pc.members:
                    j = m.param_index(n)
                    P[r, j] = _moved(n, p0[j], s)
            out.append(P)
        return out

    sim_j = ro.run(rows_for([(pc, _FD_LN) for pc in cands]))
    R = ro.residuals(sim_j, "train")
    J = (R - r0_train[None]) / _FD_LN  # (n_cand, M): d r / d ln(value) — r = measured − simulated
    newton = []
    pred = []
    rss0 = float(np.dot(r0_train, r0_train))
    for c in range(len(cands)):
        jj = float(np.dot(J[c], J[c]))
        if not sim_j.ok[c] or jj <= 0:
            newton.append(0.0)
            pred.append(math.sqrt(rss0 / max(r0_train.size, 1)))
            continue
        g = float(np.dot(J[c], r0_train))
        step = float(np.clip(-g / jj, -math.log(CORE_RANGE_FACTOR), math.log(CORE_RANGE_FACTOR)))
        newton.append(step)
        pred.append(math.sqrt(max(rss0 - g * g / jj, 0.0) / max(r0_train.size, 1)))
    # a candidate whose largest move (×/÷ CORE_RANGE_FACTOR, with a factor 2 for nonlinearity) changes the training
    # residual by less than 1 % of its norm cannot remove the 2 % of its energy acceptance asks for (masses and
    # stiffnesses on a quasi-static test): its Newton point is enough
    need = max(1.0, 0.01 * float(np.linalg.norm(r0_train)))
    visible = [2.0 * float(np.linalg.norm(J[c])) * math.log(CORE_RANGE_FACTOR) >= need for c in range(len(cands))]
    steps = []
    for c, pc in enumerate(cands):
        steps.append((pc, newton[c]))
        if visible[c]:
            steps.extend((pc, s) for s in _PROBES)
    best = _best_of(ro, rows_for(steps), steps, cands)
    # second stage: a dense line search for the most promising (a stiffness or mass that moves a resonance has a
    # narrow basin that two probes and a linear step can miss)
    order = sorted((c for c in range(len(cands)) if visible[c]), key=lambda c: best[c][0])[:refine_top]
    dense = [(cands[c], s) for c in order for s in _DENSE]
    if dense:
        best2 = _best_of(ro, rows_for(dense), dense, cands)
        for c in order:
            if best2[c][0] < best[c][0]:
                best[c] = best2[c]
        # third stage: zoom around each one's best point (a resonance crossed by a sweep: basins ~0.1 wide in ln)
        zoom = [(cands[c], best[c][2] + dz) for c in order for dz in _ZOOM]
        best3 = _best_of(ro, rows_for(zoom), zoom, cands)
        for c in order:
            if best3[c][0] < best[c][0]:
                best[c] = best3[c]
    out = []
    for c, pc in enumerate(cands):
        train, held, best_s = best[c]
        start = ({pc.scale_name: math.exp(best_s)} if pc.tied else
                 {n: _moved(n, float(base_values[n]), best_s) for n in pc.members})
        n_sims = 2 + (len(_PROBES) if visible[c] else 0) + (len(_DENSE) + len(_ZOOM) if c in order else 0)
        out.append(ScreenResult(CandidateSpec(params=(pc,)), train, held, start, pred[c], n_sims, rms(r0_train)))
    return out


def _best_of(ro: RowsObjective, rows: list[np.ndarray], steps: Sequence[tuple[ParameterCandidate, float]],
             cands: Sequence[ParameterCandidate]) -> dict[int, tuple[float, float, float]]:
    """Per candidate index: (best training RMS, its held-out RMS, its ln-step) over the simulated ``steps``."""
    sim = ro.run(rows)
    Rt = ro.residuals(sim, "train")
    Rh = ro.residuals(sim, "held")
    index = {id(pc): c for c, pc in enumerate(cands)}
    best: dict[int, tuple[float, float, float]] = {c: (math.inf, math.inf, 0.0) for c in range(len(cands))}
    for r, (pc, s) in enumerate(steps):
        if not sim.ok[r]:
            continue
        c = index[id(pc)]
        cost = rms(Rt[r])
        if cost < best[c][0]:
            best[c] = (cost, rms(Rh[r]), s)
    return best


def _moved(name: str, value: float, s: float) -> float:
    """``value`` moved by ``s`` in ln-space (a value at zero: by ``s`` × a unit scale), within its own bounds."""
    spec = CORE_SCHEMA.get(name)
    if value != 0.0:
        v = value * math.exp(s)
    else:
        v = s * 10.0  # γ_h (C^-n) at zero: an additive probe of the scale of β_h
    if spec is not None:
        v = max(min(v, spec.upper), spec.lower)
    return v


def screen_effects(targets: Sequence[Target], effect_models: Mapping[str, Sequence[PlantModel]],
                   specs: Sequence[CandidateSpec], guesses: Mapping[str, Mapping[str, float]],
                   base_values: Mapping[str, float], n_design: int = 7, seed: int = 0,
                   threads: int | None = None, overrides: Mapping[str, float] | None = None,
                   on_screened: Callable[[str], None] | None = None) -> list[ScreenResult]:
    """Screen effect candidates: the effect's guess and a Latin hypercube of ``n_design`` points, then as many
    around the best of them (a zoom, unless the best is already at the noise floor), one batch each
    (``overrides``: values of other parameters of the models, e.g. the current set's in forward selection;
    ``on_screened(label)``: called after each candidate, for progress).

    The zoom is what finds a narrow basin: a root-clamp compliance that puts a mode where the record has it is a
    window a few percent wide in the parameter, which the coarse design brackets but rarely hits (a 174 σ root
    compliance on an MBIT.b step was screened out at 124 σ and never fitted)."""
    rng = np.random.default_rng(seed)
    out = []
    for spec in specs:
        models = effect_models[spec.label]
        free, ties = spec.free_parameters(base_values)
        obj = TiedObjective(targets, models, free, ties, threads=threads, rtol=SCREEN_RTOL, base_values=overrides)
        k = len(free)
        g = guesses.get(spec.label, {})
        u_guess = np.array([float(fp.to_unit(g.get(fp.name, fp.from_unit(0.5)))) for fp in free])
        perms = np.column_stack([rng.permutation(n_design) for _ in range(k)])
        U = np.vstack([u_guess[None], (perms + rng.uniform(0.15, 0.85, size=(n_design, k))) / n_design])
        U, Rt, Rh, cost = _screen_batch(obj, U)
        b = int(np.argmin(cost))
        if k and np.isfinite(cost[b]) and cost[b] > SCREEN_ZOOM_ABOVE:
            Uz = zoom_design(U[b], n_design, n_design, rng, jitter=(0.15, 0.85))
            Uz, Rtz, Rhz, costz = _screen_batch(obj, Uz)
            U, Rt, Rh, cost = np.vstack([U, Uz]), [*Rt, *Rtz], [*Rh, *Rhz], np.concatenate([cost, costz])
            b = int(np.argmin(cost))
        start = obj.values(U[b]) if np.isfinite(cost[b]) else dict(g)
        out.append(ScreenResult(spec, float(cost[b]), rms(Rh[b]) if np.isfinite(cost[b]) else math.inf, start,
                                n_sims=U.shape[0] * len(targets)))
        if on_screened is not None:
            on_screened(spec.label)
    return out


#: a screened effect whose best design point leaves more than this training RMS (σ) gets the zoom batch
SCREEN_ZOOM_ABOVE = 1.05


def _screen_batch(obj: TiedObjective, U: np.ndarray) -> tuple[np.ndarray, list[np.ndarray], list[np.ndarray],
                                                                 np.ndarray]:
    """(U, training residuals, held-out residuals, training RMS — inf where the simulation failed) of one batch."""
    sim = obj.simulate(U)
    Rt = obj.residuals(sim, "train")
    Rh = obj.residuals(sim, "held")
    cost = np.array([rms(r) if ok else math.inf for r, ok in zip(Rt, sim.ok)])
    return U, list(Rt), list(Rh), cost


def widen(fp: Parameter, at_upper: bool, cls: type[PhysicalEffect] | None, value: float) -> Parameter | None:
    """``fp`` with the bound it hit pushed out to the parameter's own bound (an effect parameter) or
    :data:`CORE_WIDE_FACTOR` (a core parameter or tied scale); None when it cannot move further."""
    lo, hi = fp.lower, fp.upper
    own_lo, own_hi = -math.inf, math.inf
    if cls is not None:
        par = next((p for p in cls.own_parameters() if p.name == fp.name), None)
        if par is not None:
            own_lo, own_hi = par.lower, par.upper
    elif fp.name in CORE_SCHEMA:
        spec = CORE_SCHEMA[fp.name]
        own_lo, own_hi = spec.lower, spec.upper
        ref = abs(value) if value != 0 else max(abs(lo), abs(hi))
        own_lo = max(own_lo, ref / CORE_WIDE_FACTOR if lo > 0 else lo - 5 * (hi - lo))
        own_hi = min(own_hi, ref * CORE_WIDE_FACTOR if hi > 0 else hi + 5 * (hi - lo))
    else:  # a tied scale factor
        own_lo, own_hi = 1.0 / CORE_WIDE_FACTOR, CORE_WIDE_FACTOR
    if at_upper:
        new_hi = own_hi if math.isfinite(own_hi) else hi + 10 * (hi - lo)
        if not new_hi > hi * (1 + 1e-9) + 1e-300:
            return None
        hi = new_hi
    else:
        new_lo = own_lo if math.isfinite(own_lo) else lo - 10 * (hi - lo)
        if fp.log and new_lo <= 0:
            new_lo = lo / 100.0
        if not new_lo < lo - 1e-12 * abs(lo):
            return None
        lo = new_lo
    return fp.free(lo, hi, log=fp.log, linthresh=fp.linthresh)


def neutral_end(fp: Parameter, cls: type[PhysicalEffect] | None) -> tuple[bool, bool]:
    """(lower, upper): whether each end of ``fp`` is the effect's neutral value (a fit there means 'absent',
    not 'beyond the range')."""
    if cls is None:
        return False, False
    neutral = cls.neutral_values()
    if fp.name not in neutral:
        return False, False
    v = float(neutral[fp.name])
    tol = 1e-9 * max(abs(fp.upper - fp.lower), 1e-300)
    return abs(v - fp.lower) <= tol, abs(v - fp.upper) <= tol


def base_values_of(params: ParameterSet) -> dict[str, float]:
    return {k: float(v) for k, v in params.values.items()}
