"""The prognosis challenge: simulated lives whose truth we know, scored with ProgPy's metrics, beside a
feature-only baseline.

A life (:class:`ChallengeLife`): degradation laws (:class:`board_config.scenario.LifeLaw`, the ``[life]`` terms),
a visit interval, a number of visits and a laser noise level. Each visit is simulated *directly* — no board ticking,
for speed: the visit's command sequence as the board plays it (settle, MBIT.a, settle, MBIT.b at 100 Hz) drives the
truth plant (one batched integration per life), white laser noise is added, and the joined visit record goes to the
same re-estimation as ``shm health`` (:func:`.estimate.estimate_visit`, the workbench fit). The truth's first FAULT
visit comes from the board monitor through the campaign machinery (:func:`.trip.fault_batch`).

Prognosis is sequential: from the 4th visit on, at every visit before the first FAULT, the trends and the forecast are
rebuilt from the visits so far (:mod:`.trend`, :mod:`.forecast`). Scores (:mod:`.metrics`):

* coverage — the true first FAULT visit inside the 90 % interval (in visits), over the predictions made once the
  trend is significant with at least four visits;
* α-λ (α = 20 %, λ = 0.5, β = 0.5; ProgPy's rule, as ``shm health --evaluate``: the first prediction at or after
  t_λ is judged, :func:`.metrics.alpha_lambda`) and the prognostic horizon, per life, on the trip time seen at
  visits;
* stable lives — "no significant trend" at the last visit;
* sudden damage — the change-point model chosen with its step between the two visits that bracket the truth's step.

The **baseline** is the classic feature-only practice: the first natural frequency f1 of each visit (a damped sine
fitted to MBIT.b's step response), trended with the same model choice and extrapolated to an alarm threshold
calibrated on the reference life (the f1 change at which the shipped ``aging`` life first FAULTs).
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor
from typing import TYPE_CHECKING

import numpy as np

from studies.health.challenge_lives import ChallengeLife, challenge_lives, reference_life
from studies.health.challenge_results import (
    ChallengeResult,
    LifeChallengeResult,
    StepVerdict,
    VisitPrediction,
    score_predictions,
    summarise,
)
from studies.health.estimate import DEFAULT_FREE, VisitEstimates
from studies.health.evaluate import seen_at_visits
from studies.health.follow import Followed, effect_limits, find_and_follow, series, trends_upto
from studies.health.forecast import forecast_trip, visit_of
from studies.health.trend import Trend, fit_trend
from studies.health.trip import HEALTH_PARAMS, fault_batch_values, trip_boundary

if TYPE_CHECKING:
    from workbench.records import Record

__all__ = ["ChallengeLife", "challenge_lives", "reference_life", "run_challenge", "run_life_challenge"]

RATE_HZ = 100.0
SETTLE_S = 2.0
MIN_VISITS = 4
#: diagnoses per life at most, and the growth of the held-out residual (the set in use) that calls for another
MAX_DIAGNOSES = 3
REDIAGNOSE_GROWTH = 1.5


# --- simulation of a life's visits ---------------------------------------------------------------------------
def visit_commands() -> np.ndarray:
    """(n, 2) channel commands (V) of one visit as the board plays it: settle, MBIT.a, settle, MBIT.b, 0."""
    from board_config import load_mbit_definitions
    from firmware_sim.mbit import generate_mbit

    defs = load_mbit_definitions()
    rows = []
    for key in ("a", "b"):
        seq = generate_mbit(defs[key], on_clamp="report")
        rows.append(np.zeros((round(SETTLE_S * RATE_HZ), 2)))
        rows.append(np.column_stack([seq.v_ch1, seq.v_ch2]))
    rows.append(np.zeros((1, 2)))
    return np.vstack([np.zeros((1, 2)), *rows])


def truth_columns(params: str, devs: Sequence[dict[str, float]], effect_values: Sequence[dict[str, float]]
                  ) -> dict[str, np.ndarray]:
    """SI parameter columns of the truth plants: the monitor's parameters from their deviations, the added
    effects' parameters as they are."""
    from plant import PlantModel

    model = PlantModel(params, terminal="amplifier")
    names = dict.fromkeys([*HEALTH_PARAMS, *sorted({k for d in devs for k in d})])  # a section stiffness too
    cols = {p: np.array([model.param_value(p) * (1 + d.get(p, 0.0)) for d in devs]) for p in names}
    for name in sorted({k for e in effect_values for k in e}):
        cols[name] = np.array([e.get(name, 0.0) for e in effect_values])
    return cols


def truth_faults(life: ChallengeLife, params: str, devs: Sequence[dict[str, float]],
                 effect_values: Sequence[dict[str, float]]) -> np.ndarray:
    """The board monitor's verdict on each visit's truth plant (campaign machinery)."""
    return fault_batch_values(params, truth_columns(params, devs, effect_values), life.effects)


def simulate_visit_records(life: ChallengeLife, params: str, devs: list[dict[str, float]],
                           effect_values: Sequence[dict[str, float]] | None = None) -> list[Record]:
    """One joined visit record per visit (truth deviations ``devs``, the added effects' parameter values), with
    the life's laser noise."""
    from plant import InputSignals, PlantModel
    from workbench.records import record_from_arrays

    effect_values = effect_values if effect_values is not None else [{} for _ in devs]
    model = PlantModel(params, terminal="amplifier", effects=list(life.effects))
    cmds = visit_commands()
    n = cmds.shape[0]
    t = np.arange(n) / RATE_HZ
    u = np.zeros((1, n, 3))
    u[0, :, 0:2] = cmds
    cols = truth_columns(params, devs, effect_values)
    res = model.simulate(InputSignals(0.0, 1.0 / RATE_HZ, u), t_out=t, params=model.param_batch(n=len(devs), **cols),
                         rtol=1e-6, h_max=5e-3, threads=1)
    res.raise_on_failure(f"{life.name}: truth simulation failed: ")
    rng = np.random.default_rng(np.random.SeedSequence([life.seed, 17]))
    recs = []
    for i, h in enumerate(life.hours()):
        z3 = np.asarray(res["z3_meas"][i], float) + rng.normal(0.0, life.noise_m, n)
        meta = {"test": "visit", "sample_rate_Hz": RATE_HZ, "terminal": "amplifier",
                "inputs": ["v_ch1_V", "v_ch2_V"], "params": params, "operating_hours": float(h),
                "channels": {"z3_m": {"noise_std": life.noise_m}},
                "provenance": {"generator": "health challenge", "life": life.name, "visit": i + 1}}
        recs.append(record_from_arrays(t, {"v_ch1_V": cmds[:, 0], "v_ch2_V": cmds[:, 1], "z3_m": z3}, meta,
                                       path=f"<{life.name} visit {i + 1}>"))
    return recs


def first_natural_frequency(record: Record) -> float:
    """f1 (Hz) from MBIT.b's step response in a joined visit record: a damped sine fitted to the first 0.6 s after
    the step (the feature-only baseline's feature)."""
    from scipy.optimize import curve_fit

    v = record["v_ch1"] - record["v_ch2"]
    z = record["z3"]
    t = record.t
    steps = np.flatnonzero(np.diff(v) > 100.0)
    k = int(steps[-1]) + 2 if steps.size else len(t) // 2
    win = slice(k, min(len(t), k + int(0.6 * RATE_HZ)))
    tt, zz = t[win] - t[k], z[win]
    zz = zz - np.mean(zz[-10:])
    spec = np.abs(np.fft.rfft(zz * np.hanning(zz.size), 4096))
    freqs = np.fft.rfftfreq(4096, 1 / RATE_HZ)
    f0 = float(freqs[1 + np.argmax(spec[1:])])

    def damped(x, a, zeta, f, ph, c):
        w = 2 * np.pi * f
        return a * np.exp(-zeta * w * x) * np.cos(w * np.sqrt(max(1 - zeta ** 2, 1e-6)) * x + ph) + c

    try:
        p, _ = curve_fit(damped, tt, zz, p0=[np.max(np.abs(zz)), 0.05, f0, 0.0, 0.0], maxfev=4000)
        return float(abs(p[2]))
    except (RuntimeError, ValueError):
        return f0


# --- one life -------------------------------------------------------------------------------------------------
def run_life_challenge(life: ChallengeLife, params: str = "table2", f1_threshold: float | None = None,
                       n_paths: int = 400, n_grid: int = 500) -> LifeChallengeResult:
    """Simulate, estimate, predict sequentially and score one life (picklable)."""
    from studies.health.estimate import estimate_visit

    t0 = time.perf_counter()
    hours = life.hours()
    truth = [life.truth_at(float(h)) for h in hours]
    devs, eff_values = [d for d, _ in truth], [e for _, e in truth]
    faults = truth_faults(life, params, devs, eff_values)
    k_true = int(np.argmax(faults)) if faults.any() else None
    recs = simulate_visit_records(life, params, devs, eff_values)
    ests = [estimate_visit([r], params) for r in recs]
    f1 = np.array([first_natural_frequency(r) for r in recs])
    y, s = series(ests, DEFAULT_FREE)
    boundary = trip_boundary(params)
    followed = Followed()
    diagnoses = 0
    limits: dict[str, float] = {}
    preds: list[VisitPrediction] = []
    base_preds: list[VisitPrediction] = []
    last = life.visits if k_true is None else k_true  # predictions only before the first FAULT
    for j in range(MIN_VISITS - 1, last):
        hh = hours[: j + 1]
        if needs_diagnosis(followed, ests, j, diagnoses):
            f = find_and_follow(ests[: j + 1], lambda i: [recs[i]], params, lambda eff, free, base: [
                estimate_visit([r], params, free, eff, base) for r in recs])
            diagnoses += f.diagnosed_visit is not None
            if f.diagnosed_visit is not None and (f.switched or not followed.switched):
                followed = f
            if followed.switched:
                assert followed.estimates is not None
                y, s = series(followed.estimates, followed.free)
                limits = effect_limits(params, followed.free)
        trends = trends_upto(hours, y, s, j + 1)
        fc = forecast_trip(trends, boundary, float(hh[-1]), life.interval, seed=life.seed + j, n_paths=n_paths,
                           n_grid=n_grid, effect_limits=limits)
        seen = seen_at_visits(fc.trip_samples, hours[0], life.interval)
        preds.append(VisitPrediction(j, float(hh[-1]), fc.significant,
                                     _interval_visits(fc.trip_samples, hours[0], life.interval), seen))
        if f1_threshold is not None:
            base_preds.append(_baseline_prediction(hh, f1[: j + 1] / f1[0] - 1, f1_threshold, life, j))
    final = trends_upto(hours, y, s, len(hours))  # final-visit verdicts: stable and sudden lives
    return LifeChallengeResult(
        life.name, life.kind, life.group, tuple(life.effects), life.visits, life.interval, life.noise_m * 1e6,
        tuple(float(h) for h in hours), k_true, f1.tolist(), score_predictions(preds, k_true, hours),
        score_predictions(base_preds, k_true, hours) if f1_threshold is not None else None, followed,
        {p: t.significant for p, t in final.items()}, {p: t.model for p, t in final.items()},
        _step_verdict(life, hours, final), time.perf_counter() - t0)


def _step_verdict(life: ChallengeLife, hours: np.ndarray, final: Mapping[str, Trend]) -> StepVerdict | None:
    """A sudden damage's step parameter at the last visit: change point placed between the right visits?"""
    if life.kind != "sudden" or life.step_parameter is None or life.step_parameter not in final:
        return None
    t = final[life.step_parameter]
    ok = t.model == "change_point" and t.best.tau is not None and \
        _bracket(hours, life.step_hours) == _bracket(hours, t.best.tau)
    return StepVerdict(bool(ok), t.best.tau)


def needs_diagnosis(followed: Followed, ests: Sequence[VisitEstimates], j: int, done: int) -> bool:
    """As of visit ``j``: diagnose when no diagnosis ran yet, or — at most :data:`MAX_DIAGNOSES` times — when the
    set in use leaves :data:`REDIAGNOSE_GROWTH` × the held-out residual it left at the visit last diagnosed (a
    second cause growing, or the first one outgrowing what was named)."""
    if followed.diagnosed_visit is None:
        return True
    if done >= MAX_DIAGNOSES:
        return False
    in_use = followed.estimates if followed.estimates is not None else ests
    return bool(in_use[j].held_rms_sigma > REDIAGNOSE_GROWTH * in_use[followed.diagnosed_visit].held_rms_sigma)


def _bracket(hours: np.ndarray, t: float | None) -> int | None:
    if t is None:
        return None
    return int(np.searchsorted(hours, t, side="right"))


def _interval_visits(samples: np.ndarray, start: float, interval: float) -> list[int | None]:
    with np.errstate(invalid="ignore"):
        q05, q95 = np.quantile(samples, [0.05, 0.95])
    return [visit_of(float(q05), start, interval), visit_of(float(q95), start, interval)]


def _baseline_prediction(hh: np.ndarray, f1_rel: np.ndarray, thr: float, life: ChallengeLife, j: int
                         ) -> VisitPrediction:
    tr = fit_trend("f1", hh, f1_rel, np.full(hh.size, 1e-3))
    rng = np.random.default_rng(life.seed + 1000 + j)
    grid = np.linspace(hh[-1], hh[-1] + 20 * life.interval + 4 * hh[-1], 500)
    if tr.significant:
        paths = tr.sample_paths(grid, 400, rng)
    else:
        from studies.health.trend import paths_of

        paths = paths_of(tr.fits.get("linear") or tr.fits["none"], grid, 400, rng)
    cross = (paths <= thr) if thr < 0 else (paths >= thr)
    hit = cross.any(axis=1)
    trips = np.where(hit, grid[np.argmax(cross, axis=1)], np.inf)
    return VisitPrediction(j, float(hh[-1]), tr.significant, _interval_visits(trips, 0.0, life.interval),
                           seen_at_visits(trips, 0.0, life.interval))


# --- the whole challenge --------------------------------------------------------------------------------------
def f1_alarm_threshold(params: str = "table2") -> float:
    """The baseline's alarm: relative f1 change of the reference life at its first FAULT (truth, noise-free)."""
    life = reference_life()
    hours = life.hours()
    devs = [life.truth_at(float(h))[0] for h in hours]
    k = int(np.argmax(truth_faults(life, params, devs, [{} for _ in devs])))
    recs = simulate_visit_records(ChallengeLife("ref", life.laws, life.visits, life.interval, 0.0, seed=0), params,
                                  devs)
    return first_natural_frequency(recs[k]) / first_natural_frequency(recs[0]) - 1.0


def run_challenge(lives: Sequence[ChallengeLife], params: str = "table2", workers: int | None = None,
                  progress: Callable[[str], None] | None = None, scheduler: str | None = None) -> ChallengeResult:
    """Every life (process pool of ``workers``; with ``scheduler``, one task per life on the scale-out runner:
    ``local`` workers, ``tcp://host:port`` or ``synchronous``) and the summary scores."""
    t0 = time.perf_counter()
    trip_boundary(params)  # computed (or loaded) once before the workers start
    thr = f1_alarm_threshold(params)
    n = workers if workers is not None else min(len(lives), os.cpu_count() or 1)
    out: list[LifeChallengeResult] = []
    if scheduler is not None:
        from studies.batch.cases import run_cases

        def shown(x: LifeChallengeResult) -> None:  # each life in life order, as soon as the lives before it are in
            if progress:
                progress(_life_line(x))
        out = run_cases(run_life_challenge, [(life, params, thr) for life in lives], scheduler=scheduler,
                        workers=n, on_result=shown, what="health challenge")[0]
    elif n <= 1:
        for life in lives:
            out.append(run_life_challenge(life, params, thr))
            if progress:
                progress(_life_line(out[-1]))
    else:
        with ProcessPoolExecutor(max_workers=n) as pool:
            futs = [pool.submit(run_life_challenge, life, params, thr) for life in lives]
            for f in futs:
                out.append(f.result())
                if progress:
                    progress(_life_line(out[-1]))
    return ChallengeResult(out, summarise(out), time.perf_counter() - t0, thr)


def _life_line(x: LifeChallengeResult) -> str:
    ph = x.physics
    cov = "" if ph.coverage is None else f"coverage {ph.covered}/{ph.predictions}"
    al = "" if ph.alpha_lambda is None else f", alpha-lambda {'ok' if ph.alpha_lambda else 'missed'}"
    extra = ""
    if x.kind == "stable":
        extra = "no significant trend" if not any(x.final_significant.values()) else \
            f"FALSE TREND {x.final_models}"
    if x.kind == "sudden":
        placed, tau = (None, None) if x.step is None else (x.step.placed, x.step.tau_h)
        extra = f"step placed: {placed} (tau {tau})"
    fault = x.true_first_fault_visit  # 0-based index; printed as the visit number (1 = entry into service)
    d = x.followed.diagnosed_visit
    if x.followed.switched and d is not None:
        extra += f" [followed: {', '.join(x.followed.free)} from {x.hours[d]:g} h]"
    return (f"  {x.life:<34} first FAULT visit {fault + 1 if fault is not None else '-':>4}  {cov}{al} {extra}"
            f"  ({x.wall_s:.1f} s)")
