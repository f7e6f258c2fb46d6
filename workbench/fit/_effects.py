"""``shm fit``: add effects to the model, fit their parameters (and freed ones), score before/after.

:func:`fit_records` is the entry point (see :mod:`workbench.fit` for the method); :class:`FitReport` is what it
returns.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from board_config import ParameterSet, load_parameter_set
from board_config.parameter import Parameter
from plant import InputSignals, PhysicalEffect, PlantModel
from plant.effect import EffectError
from workbench.fit._bootstrap import MODEL_EXPLAINS_SIGMA, N_REPLICATES, apply_bootstrap
from workbench.fit._effect_library import (
    core_free_parameter,
    effect_free_parameters,
    guess_values,
    resolve_candidates,
)
from workbench.fit._objective import Objective, SimBatch, rms
from workbench.fit._optimiser import FitHistoryPoint, FitOutcome, optimise
from workbench.fit._parameter_set import fitted_parameter_set
from workbench.fit._scores import ChannelScore, channel_scores
from workbench.fit._targets import (
    DEFAULT_BLOCKS,
    DEFAULT_MAX_RATE_HZ,
    FitError,
    Target,
    model_factory,
    prepare_targets,
)
from workbench.records import Record


@dataclass
class FitReport:
    """What ``shm fit`` reports: before/after on training and held-out data, estimates, history, the new set."""

    added: list[str]
    free: list[Parameter]
    outcome: FitOutcome
    before: list[ChannelScore]
    after: list[ChannelScore]
    before_train_rms_sigma: float
    before_held_rms_sigma: float
    base_set: ParameterSet
    model: PlantModel
    save_name: str
    targets: list[Target]
    baseline_sim: SimBatch
    wall_s: float
    notes: list[str] = field(default_factory=list)
    #: how the estimates' intervals were found: "jacobian", or "block bootstrap" when the fitted model leaves more
    #: than the noise (held-out > MODEL_EXPLAINS_SIGMA; see workbench.fit._bootstrap)
    interval_method: str = "jacobian"
    #: the starting values of the free parameters (the effects' own guesses, else the set's values) — lmfit's init
    initial: dict[str, float] = field(default_factory=dict)

    @property
    def parameter_set(self) -> ParameterSet:
        """The fitted parameter set (``[[effects]]`` with every added effect); :class:`FitError` when an added
        effect cannot be referred to from a file (defined in a script or a function)."""
        return fitted_parameter_set(self.base_set, self.model, self.outcome.values, self.save_name, meta={
            "description": f"{self.base_set.name} + {', '.join(self.added) or 'refit'}, fitted by shm fit to "
                           f"{', '.join(tg.name for tg in self.targets)}",
            "fitted_from": self.base_set.name,
        })

    def summary(self) -> dict[str, Any]:
        o = self.outcome
        return {
            "added_effects": self.added,
            "free_parameters": [fp.describe() for fp in self.free],
            "estimates": [e.__dict__ for e in o.estimates],
            "correlation": o.correlation.tolist(),
            "train_rms_sigma": {"before": self.before_train_rms_sigma, "after": o.train_rms_sigma},
            "held_rms_sigma": {"before": self.before_held_rms_sigma, "after": o.held_rms_sigma},
            "channels_before": [s.__dict__ | {"rms_sigma": s.rms_sigma} for s in self.before],
            "channels_after": [s.__dict__ | {"rms_sigma": s.rms_sigma} for s in self.after],
            "history": [h.__dict__ for h in o.history],
            "optimiser": o.message,
            "simulations": o.n_sims,
            "wall_s": self.wall_s,
            "parameter_set": self.save_name,
            "notes": self.notes,
            "interval_method": self.interval_method,
            "model_explains_record": bool(o.held_rms_sigma <= MODEL_EXPLAINS_SIGMA),
        }


def check_effect_runs(model: PlantModel, cls: type[PhysicalEffect], target: Target) -> None:
    """Run the composed model once on a short stretch of a record; a user effect that produces NaN/Inf or
    writes outside its slots is reported by name."""
    n = min(target.inputs.n_samples, max(50, int(0.2 / target.inputs.dt)))
    short = InputSignals(target.inputs.t0, target.inputs.dt, target.inputs.values[:, :n])
    t_end = short.t[-1]
    try:
        res = model.simulate(short, t_end=t_end, dt_out=max(t_end / 20, short.dt))
    except (IndexError, ValueError) as exc:
        raise FitError(f"effect '{cls.name}': the composed model fails to run: {type(exc).__name__}: {exc} — "
                       "check that the hooks only index x[so + k], p[po + k] and y[yo + k] within what the effect "
                       "declares") from exc
    if not res.ok or not np.all(np.isfinite(res.y)):
        bad = [n for j, n in enumerate(res.output_names) if not np.all(np.isfinite(res.y[0, :, j]))]
        raise FitError(f"effect '{cls.name}': the model with this effect produces non-finite values at its starting "
                       f"parameters ({'; '.join(res.failures()) or 'outputs ' + ', '.join(bad[:5])}) — check the "
                       "effect's hooks (division by a zero parameter? NaN written to the bus or to y?)")


def fit_records(records: Sequence[Record], params: ParameterSet | str = "table2",
                add: Sequence[str | type[PhysicalEffect]] = (), free: Sequence[str] = (), *,
                save_name: str = "fitted", holdout: str = "blocks", n_blocks: int = DEFAULT_BLOCKS,
                max_rate_Hz: float = DEFAULT_MAX_RATE_HZ, max_nfev: int = 40, seed: int = 0,
                on_iteration: Callable[[FitHistoryPoint], None] | None = None,
                on_baseline: Callable[[float, float], None] | None = None,
                bootstrap_replicates: int = N_REPLICATES) -> FitReport:
    """Add ``add`` to the model, fit their parameters (and ``free`` ones: ``name`` or ``name:lower:upper``)
    on the training part of ``records``, and score before/after on training and held-out data.

    ``on_baseline(train_rms_sigma, held_rms_sigma)`` is called once the starting model has been scored,
    ``on_iteration(point)`` at every optimiser iteration (the live display of ``shm fit``). When the fitted model
    leaves more than the noise (held-out > 1.5 σ) the intervals come from a block bootstrap of
    ``bootstrap_replicates`` replicates (:mod:`workbench.fit._bootstrap`; 0: the Jacobian's, whatever the fit)."""
    t0 = time.perf_counter()
    base = load_parameter_set(params)
    try:
        classes = resolve_candidates(add)
    except EffectError as exc:
        raise FitError(str(exc)) from None
    base_build = model_factory(base, [])
    targets = prepare_targets(records, base_build, holdout=holdout, n_blocks=n_blocks, max_rate_Hz=max_rate_Hz)
    base_models = [tg.model for tg in targets]
    base_obj = Objective(targets, base_models, [])
    base_sim = base_obj.simulate(np.zeros((1, 0)), keep_full=True)
    if not base_sim.ok.all():
        raise FitError("the starting model fails to integrate on the records: "
                       + "; ".join(f"{tg.name}: status {int(s[0])}" for tg, s in zip(targets, base_sim.status)))
    # the effects' own starting guesses first (cheap; a malformed guess fails before anything compiles)
    free_params, guess = _effect_guesses(classes, guess_data(targets[0], base_sim, base_models[0]))
    models = _fit_models(base, classes, targets)
    free_params = _freed_core_parameters(models[0], free, free_params)
    before = channel_scores(targets, base_sim)
    before_train = rms(base_obj.residuals(base_sim, "train")[0])
    before_held = rms(base_obj.residuals(base_sim, "held")[0])
    if on_baseline is not None:
        on_baseline(before_train, before_held)
    for fp in free_params:
        if fp.name not in guess:
            guess[fp.name] = float(models[0].p_nominal[models[0].param_index(fp.name)])
    obj = Objective(targets, models, free_params)
    outcome = optimise(obj, guess, max_nfev=max_nfev, seed=seed, on_iteration=on_iteration)
    if not outcome.ok:
        raise FitError(f"the fitted model fails to integrate on the records ({outcome.message})")
    after = channel_scores(targets, outcome.sim)
    notes, interval_method = _interval_notes(obj, outcome, bootstrap_replicates, seed)
    return FitReport(
        added=[c.name for c in classes], free=free_params, outcome=outcome, before=before, after=after,
        before_train_rms_sigma=before_train, before_held_rms_sigma=before_held,
        base_set=base, model=models[0], save_name=save_name, targets=targets, baseline_sim=base_sim,
        wall_s=time.perf_counter() - t0, notes=notes, interval_method=interval_method,
        initial={fp.name: float(guess[fp.name]) for fp in free_params})


def _effect_guesses(classes: Sequence[type[PhysicalEffect]], data: dict[str, Any]
                    ) -> tuple[list[Parameter], dict[str, float]]:
    """The added effects' free parameters and their own starting guesses from ``data`` (see :func:`guess_data`)."""
    free_params: list[Parameter] = []
    guess: dict[str, float] = {}
    for cls in classes:
        try:
            own = effect_free_parameters(cls)
            guess.update(guess_values(cls, data, own))
        except EffectError as exc:
            raise FitError(str(exc)) from None
        free_params.extend(own)
    return free_params, guess


def _fit_models(base: ParameterSet, classes: Sequence[type[PhysicalEffect]], targets: list[Target]
                ) -> list[PlantModel]:
    """The model with the added effects, one per record; each effect run once on a short stretch first."""
    try:
        build = model_factory(base, classes)
        models = [build(tg.record) for tg in targets]
    except EffectError as exc:
        raise FitError(str(exc)) from None
    for cls in classes:
        check_effect_runs(models[0], cls, targets[0])
    return models


def _freed_core_parameters(model: PlantModel, free: Sequence[str], free_params: list[Parameter]
                           ) -> list[Parameter]:
    """``free_params`` with the freed core parameters (``name`` or ``name:lower:upper``) added or replacing an
    effect's of the same name; :class:`FitError` when nothing is left to fit."""
    for spec in free:
        try:
            fp = core_free_parameter(model, spec)
        except (EffectError, ValueError) as exc:
            raise FitError(str(exc)) from None
        free_params = [q for q in free_params if q.name != fp.name] + [fp]
    if not free_params:
        raise FitError("nothing to fit: add an effect (--add) or free a parameter (--free)")
    return free_params


def _interval_notes(obj: Objective, outcome: FitOutcome, bootstrap_replicates: int, seed: int
                    ) -> tuple[list[str], str]:
    """The notes on a fit and how its intervals were found: a block bootstrap (applied to ``outcome``) when the
    model leaves more than the noise, else the Jacobian's; a note per estimate that ended at a range bound."""
    notes = []
    interval_method = "jacobian"
    if outcome.held_rms_sigma > MODEL_EXPLAINS_SIGMA and bootstrap_replicates > 0 and outcome.estimates:
        boot = apply_bootstrap(obj, outcome, n_replicates=bootstrap_replicates, seed=seed)
        interval_method = "block bootstrap"
        notes.append(f"the model does not explain the record yet (held-out {outcome.held_rms_sigma:.3g} σ > "
                     f"{MODEL_EXPLAINS_SIGMA} σ): the intervals come from a {boot.describe()}, not from the "
                     "Jacobian, which assumes what is left is noise")
    for e in outcome.estimates:
        if e.at_bound:
            notes.append(f"{e.name} ended at a bound of its range [{e.lower:g}, {e.upper:g}] {e.unit}: widen it "
                         f"with --free {e.name}:LOWER:UPPER if the physics allows")
    return notes, interval_method


def guess_data(target: Target, base_sim: SimBatch, model: PlantModel) -> dict[str, Any]:
    """The mapping an effect's ``guess`` reads (see :mod:`plant.effects.library_support`)."""
    full = base_sim.full[0][0] if base_sim.full else None
    rec = target.record
    u = rec.input_matrix()[target.sample_idx]
    data: dict[str, Any] = {
        "t_s": target.t,
        "inputs": {"v_ch1": u[:, 0], "v_ch2": u[:, 1], "z0dd": u[:, 2]},
        "measured": {o: target.measured[j] for j, o in enumerate(target.outputs)},
        "params": dict(zip(model.param_names, map(float, model.p_nominal))),
    }
    if full is not None:
        data["predicted"] = {n: full[:, j] for j, n in enumerate(model.output_names)}
    return data
