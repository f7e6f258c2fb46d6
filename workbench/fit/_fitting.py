"""Fit added physical effects (and freed parameters) to measurement records, with held-out scoring.

The discipline is that of the nonlinear system-identification benchmarks: parameters are fitted on a
*training* part and judged on a *held-out* part they never saw.

* **Split.** Each record is cut into ``n_blocks`` contiguous blocks; even blocks train, odd blocks are held out
  (``holdout="blocks"``, the default — every test regime is seen by both parts). With several records,
  ``holdout="records"`` holds out every second record whole. The model always runs free from rest over the whole
  record (it never sees a measured output); the split only says which samples score what.
* **Residuals** are measured − simulated on every measured channel, divided by the channel's noise level σ
  (the record's ``noise_std`` metadata, else a robust estimate from the data), so errors read in units of the
  noise floor: a held-out RMS of 1.0 σ is as good as the data allow. Long records are sub-sampled to at most
  ``max_rate_Hz`` for fitting (pointwise residuals, no filtering).
* **Optimiser.** scipy ``least_squares`` (trust-region reflective) in the unit box of the free parameters
  (log-scaled where a parameter spans decades). The finite-difference Jacobian's columns are integrated as
  *one batch* (``PlantModel.simulate(params=...)`` with k parameter rows), and so are the multi-start screening
  points — the compiled integrator runs the batch members in parallel threads.
* **Uncertainty.** Standard errors from the Jacobian at the optimum, ``cov = s² (JᵀJ)⁻¹`` with
  s² = RSS/(N − k), inflated by (1 + ρ₁)/(1 − ρ₁) for the lag-1 autocorrelation ρ₁ of the training residual;
  the correlation matrix flags parameters the data cannot separate. When the fitted model leaves more than the
  noise (held-out > 1.5 σ) the intervals come from a moving-block bootstrap over the record instead
  (:mod:`workbench.fit._bootstrap`), and the report says the model does not explain the record yet.

:func:`fit_records` is the entry point used by ``shm fit``; :mod:`workbench.diagnose` builds on the same
:class:`Objective`.

This module is the fit's public face; the code lives in one module per stage:

* :mod:`workbench.fit._targets` — records cut into training/held-out parts, σ levels, the per-record model factory;
* :mod:`workbench.fit._objective` — the batched objective (weighted residuals of parameter rows);
* :mod:`workbench.fit._optimiser` — multi-start least squares, the batched Jacobian, estimates and uncertainty;
* :mod:`workbench.fit._bootstrap` — block-bootstrap intervals when the fitted model does not explain the record;
* :mod:`workbench.fit._scores` — per-channel scoreboards;
* :mod:`workbench.fit._parameter_set` — the fitted parameter set (``[[effects]]``);
* :mod:`workbench.fit._effects` — ``shm fit`` itself (:func:`fit_records`, :class:`FitReport`).
"""

from workbench.fit._effects import FitReport, check_effect_runs, fit_records, guess_data
from workbench.fit._objective import Objective, SimBatch, lag1_autocorrelation, part_mask, rms
from workbench.fit._optimiser import (
    FD_STEP,
    FitHistoryPoint,
    FitOutcome,
    ParameterEstimate,
    optimise,
    outcome_at,
    train_residual_and_jacobian,
)
from workbench.fit._parameter_set import effect_entry_name, fitted_parameter_set
from workbench.fit._scores import ChannelScore, channel_scores
from workbench.fit._targets import (
    DEFAULT_BLOCKS,
    DEFAULT_MAX_RATE_HZ,
    MIN_BLOCK_SAMPLES,
    FitError,
    Target,
    block_masks,
    model_factory,
    prepare_targets,
)

__all__ = [
    "DEFAULT_BLOCKS",
    "DEFAULT_MAX_RATE_HZ",
    "FD_STEP",
    "MIN_BLOCK_SAMPLES",
    "ChannelScore",
    "FitError",
    "FitHistoryPoint",
    "FitOutcome",
    "FitReport",
    "Objective",
    "ParameterEstimate",
    "SimBatch",
    "Target",
    "block_masks",
    "channel_scores",
    "check_effect_runs",
    "effect_entry_name",
    "fit_records",
    "fitted_parameter_set",
    "guess_data",
    "lag1_autocorrelation",
    "model_factory",
    "optimise",
    "outcome_at",
    "part_mask",
    "prepare_targets",
    "rms",
    "train_residual_and_jacobian",
]
