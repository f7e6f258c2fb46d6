"""Model against measurement: error metrics, residual tests, FRFs, localisation, the compare report."""

from __future__ import annotations

from workbench.compare._comparison import CompareOptions, compare
from workbench.compare._frf_estimate import h1_estimate
from workbench.compare._frf_peaks import find_peaks
from workbench.compare._metrics import channel_metrics, fit_eq4, fit_percent, normalised_error
from workbench.compare._model_figures import (
    FRF_FIGURES,
    bode_figure,
    calibration_figure,
    time_response_figure,
)
from workbench.compare._report import report_json, write_report
from workbench.compare._residual_tests import ResidualTests, residual_tests

__all__ = [
    "FRF_FIGURES",
    "CompareOptions",
    "ResidualTests",
    "bode_figure",
    "calibration_figure",
    "channel_metrics",
    "compare",
    "find_peaks",
    "fit_eq4",
    "fit_percent",
    "h1_estimate",
    "normalised_error",
    "report_json",
    "residual_tests",
    "time_response_figure",
    "write_report",
]
