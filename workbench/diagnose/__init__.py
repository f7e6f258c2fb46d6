"""Diagnosis: which physics is missing, by forward selection over the library and discovery beyond it."""

from __future__ import annotations

from workbench.diagnose._pipeline import diagnose
from workbench.diagnose._report import ProgressPlot, overlay_figure, ranking_figure, write_html

__all__ = [
    "ProgressPlot",
    "diagnose",
    "overlay_figure",
    "ranking_figure",
    "write_html",
]
